"""``tactex experiment ladder``: model ``auto`` (the ladder) against its rungs alone, on the same
real scenes.

Scenes: ``--scenes`` seeded 1 + C scenes of the test folder's classes (``experiment real``'s
``draw_scenes``); every setting runs every scene with the same seed (paired), without a stop rule
up to ``--budget`` touches after the baseline, and the belief after every decision is kept
(``experiment real``'s ``curve``), so every stop threshold of ``--thresholds`` is exact.
Class-disjoint: the representation file (``--representation``) must be prepared on another
library (e.g. octopi-objects when testing on octopi-dev); the CNN learns only within the trial.

Touches: the test presses' descriptors come from ``experiment unseen``'s cache (``--cache-dir``,
built once, never in the repository); a setting whose learner may need frames (a CNN, or the
ladder with a CNN rung) also gets the press's strongest-contact and no-contact frames (read once
per run; the CNN sees no further frames of a press). CPU seconds
per trial: the process time of the learner and engine (storing touches and deciding), without
reading the press files, up to each decision (``cpu`` in the curves), so the CPU at a stop
threshold is exact too.

Output: ``experiment real``'s (runs.json, summary.json, charts), plus per setting the CPU per
trial at every threshold, the share of scenes that climbed each rung, and why (``ladder``).
"""

from __future__ import annotations

import argparse
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

from tactex_ros.core.config import SHIPPED_STOP, preset, trial_preset
from tactex_ros.core.texture import DIM
from tactex_ros.core.errors import InputError
from tactex_ros.core.touch import Touch
from tactex_lab.analysis.stats import wilcoxon_paired
from tactex_lab.experiments import curves as real_curves
from tactex_lab.experiments import press_cache, protocol
from tactex_lab.experiments.common import results_dir

THRESHOLDS = (0.8, 0.9, 0.95, 1.01)


def default_settings(rep: str) -> list[str]:
    """Always-cheapest, always-prepared, always-CNN and the ladder (``parse_setting`` form)."""
    return ["descriptor=default", f"representation=default:learner.representation={rep}",
            "cnn=cnn", f"auto=default:learner.model=auto,learner.representation={rep}"]


#: Frames of presses already read in this process, {press file: (frame, no-contact frame)}: a
#: press file is decoded once per run, not once per touch and setting.
_FRAMES: dict[str, tuple[np.ndarray, np.ndarray | None]] = {}


class FramedPresses(press_cache.CachedPresses):
    """``experiment unseen``'s cached presses (each touch carries its cached descriptor), with
    ``frames`` also the real strongest-contact and no-contact frames (read from the press file
    once per process) instead of a placeholder."""

    def __init__(self, cache: dict[str, np.ndarray], frames: bool) -> None:
        super().__init__(cache["f0"], cache["cls"])
        self.paths = cache["path"]
        self.frames = frames
        self.load_s = 0.0          # process time spent reading press files

    def touch(self, row: int) -> Touch:
        if not self.frames:
            return super().touch(row)
        from tactex_ros.sources.replay import load_touch
        path = str(self.paths[row])
        if path not in _FRAMES:
            t0 = time.process_time()
            t = load_touch(path)[0]
            _FRAMES[path] = (t.frame, t.no_contact)
            self.load_s += time.process_time() - t0
        frame, nc = _FRAMES[path]
        return Touch(frame, nc, None, self.x[row])


def needs_frames(cfg) -> bool:
    """Whether a learner of ``cfg`` may look at frames (not only descriptors)."""
    if cfg.is_ladder:
        from tactex_ros.core.ladder import DESCRIPTOR_RUNGS, rungs_of
        return any(r not in DESCRIPTOR_RUNGS for r in rungs_of(cfg).names)
    return cfg.plugin


def scene_run(setting: tuple, cache: dict[str, np.ndarray], plat: list[str], seed: int,
              budget: int) -> real_curves.BeliefCurve:
    """One scene under one ``parse_setting`` tuple: the belief curve (``curves.curve``) with
    ``cpu`` (cumulative learner CPU seconds at each decision), ``escalations``, ``notes`` and
    ``models``."""
    from tactex_ros.core.engine import TrialSpec, run_trial
    from tactex_ros.sources.replay import ReplayTrial
    label, pre, strategy, over = setting
    cfg = preset(pre, **{"guards": False, **over})
    if hasattr(cfg, "descriptor_height_map") and "descriptor_height_map" not in over:
        # the cache's descriptors: 106 numbers (the study's) or with the height map
        cfg = cfg.replace(descriptor_height_map=cache["f0"].shape[1] != DIM)
    tcfg = trial_preset(pre, strategy=strategy, rounds=budget, stop_confidence=0.0)
    src = FramedPresses(cache, needs_frames(cfg))
    truth = plat[1:].index(plat[0]) + 1
    spec = TrialSpec(len(plat) - 1, cfg, tcfg, seed=seed)
    cpu: list[float] = []
    t0 = time.process_time()

    def on_round(rec) -> None:
        cpu.append(time.process_time() - t0 - src.load_s)

    out = run_trial(spec, ReplayTrial(src, plat, seed), truth=truth, on_round=on_round)
    decisions = out.rounds + [out.final]
    d = out.to_dict()
    return replace(real_curves.curve(decisions, truth, classes=plat), cpu=tuple(cpu),
                   escalations=tuple(d["escalations"]), notes=tuple(d["notes"]),
                   models=tuple(r.model for r in decisions))


def cpu_at_stop(c: real_curves.BeliefCurve, theta: float) -> float:
    """Learner CPU seconds of the trial until it stops at ``theta`` (``curves.stop_index``)."""
    i = real_curves.stop_index(c, theta)
    return c.cpu[-1 if i is None else i]


def rungs_at_stop(c: real_curves.BeliefCurve, theta: float) -> list[str]:
    """The models a trial used until it stops at ``theta``."""
    i = real_curves.stop_index(c, theta)
    return list(c.models if i is None else c.models[:i + 1])


def ladder_summary(curves: dict[str, list[real_curves.BeliefCurve]], thresholds: list[float],
                   reference: str) -> dict:
    """Per setting and threshold: CPU seconds per trial (mean, median), paired Wilcoxon on CPU
    against ``reference``, the share of scenes whose trial reached each model, and the
    escalation reasons (first words) over all scenes."""
    out = {}
    for lab, cs in curves.items():
        row = {}
        for th in thresholds:
            cpu = [cpu_at_stop(c, th) for c in cs]
            reached: dict[str, int] = {}
            for c in cs:
                for m in set(rungs_at_stop(c, th)):
                    reached[m] = reached.get(m, 0) + 1
            row[str(th)] = {"cpu_mean_s": float(np.mean(cpu)),
                            "cpu_median_s": float(np.median(cpu)),
                            "cpu_p": (None if lab == reference else wilcoxon_paired(
                                [cpu_at_stop(c, th) for c in curves[reference]], cpu)["p"]),
                            "reached": {m: n / len(cs) for m, n in sorted(reached.items())}}
        reasons: dict[str, int] = {}
        for c in cs:
            for e in c.escalations:
                key = e["reason"].split(":")[1].strip() if ":" in e["reason"] else e["reason"]
                reasons[f"{e['model']}: {key}"] = reasons.get(f"{e['model']}: {key}", 0) + 1
        out[lab] = {"thresholds": row, "escalation_reasons": reasons,
                    "notes": sorted({n for c in cs for n in c.notes})}
    return out


def run_ladder(args: argparse.Namespace) -> dict:
    settings = [real_curves.parse_setting(s) for s in args.setting or
                default_settings(args.representation)]
    labels = [s[0] for s in settings]
    if len(set(labels)) != len(labels):
        raise InputError(f"--setting labels must be unique, got {labels}")
    if args.representation and not Path(args.representation).is_file():
        raise InputError(f"--representation {args.representation}: no such file (make it with "
                         "`tactex prepare` on another library)")
    path = Path(args.cache_dir) / f"{Path(args.test).name}.npz"
    cache = press_cache.load_cache(path)
    classes = sorted(set(cache["cls"].tolist()))
    scenes = real_curves.draw_scenes(classes, args.scenes, args.comparisons, args.seed)
    thresholds = sorted(args.thresholds or THRESHOLDS)
    out = results_dir(args.out, "ladder", {k: v for k, v in vars(args).items() if k != "func"})
    curves: dict[str, list[real_curves.BeliefCurve]] = {lab: [] for lab in labels}
    for i, plat in enumerate(scenes):
        for s in settings:
            curves[s[0]].append(scene_run(s, cache, plat, args.seed + i, args.budget))
        if not args.quiet:
            print(f"scene {i + 1}/{len(scenes)}: " + "  ".join(
                f"{lab} "
                f"{'ok' if real_curves.at_stop(curves[lab][-1], SHIPPED_STOP)[0] else 'x'} "
                f"{curves[lab][-1].cpu[-1]:.1f}s" for lab in labels), flush=True)
    budgets = tuple(k for k in (0, 1, 3, 5, 10) if k <= args.budget)
    ref = labels[0]
    summary = {"test": args.test, "representation": args.representation,
               "comparisons": args.comparisons, "budget": args.budget, "scenes": len(scenes),
               "settings": {s[0]: {"preset": s[1], "strategy": s[2], "overrides": s[3]}
                            for s in settings},
               "per_setting": protocol.summarise(curves, args.budget),
               "report_rows": protocol.score_pairs(curves, thresholds),
               "paired": {ref: {"budgets": real_curves.paired_at_budgets(curves, ref, budgets),
                                "thresholds": real_curves.paired_at_thresholds(curves, ref,
                                                                        thresholds)}},
               "ladder": ladder_summary(curves, thresholds, ref),
               "report_curves": curves}
    args.report_only = True
    protocol.write_outputs(out, summary, labels, args)
    for lab, row in summary["ladder"].items():
        for th, v in row["thresholds"].items():
            print(f"    {lab:>14} at theta {th}: CPU per trial {v['cpu_mean_s']:.2f} s mean "
                  f"(Wilcoxon vs {ref} p={v['cpu_p']}) reached {v['reached']}")
        for note in row["notes"]:
            print(f"    {lab:>14}: {note}")
    return summary


def register(esub: argparse._SubParsersAction) -> None:
    p = esub.add_parser("ladder", help="model auto (the ladder) against always-cheapest and "
                                       "always-richest on the same real scenes")
    p.add_argument("--test", required=True, help="replay folder of the test presses")
    p.add_argument("--cache-dir", required=True,
                   help="experiment unseen's descriptor cache folder (holds <test name>.npz)")
    p.add_argument("--representation", default="",
                   help="tactex prepare file made on ANOTHER library (class-disjoint)")
    p.add_argument("--setting", action="append",
                   help="label=preset[:key=value,...] (repeat; the first is the paired "
                        "reference); default: descriptor, representation, cnn, auto")
    p.add_argument("--comparisons", type=int, default=4)
    p.add_argument("--scenes", type=int, default=40)
    p.add_argument("--budget", type=int, default=10, help="touches after the baseline")
    p.add_argument("--thresholds", type=float, nargs="+",
                   help=protocol.THRESHOLD_HELP)
    p.add_argument("--press-time", metavar="FILE|DIR", help=protocol.PRESS_TIME_HELP)
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--quiet", action="store_true")
    p.add_argument("--out")

    def func(args: argparse.Namespace) -> int:
        protocol.check_options(args)
        for name in ("comparisons", "scenes", "budget"):
            if getattr(args, name) < (2 if name == "comparisons" else 1):
                raise InputError(f"--{name} too small: {getattr(args, name)}")
        run_ladder(args)
        return 0

    p.set_defaults(func=func)
