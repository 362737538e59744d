"""``tactex experiment stability-real``: where each method breaks on replayed real presses.

Scenes (1 reference + ``--comparisons``) are drawn from the classes of a replay folder (``--source
replay:DIR``) with seeds ``--seed`` .. ; scene i runs with seed ``seed + i`` under every method,
perturbation and severity (paired: the same classes, the same press order, the same random draws
of the k-th touch). Every touch of a trial is perturbed by ``sources.perturb.Perturbation`` (one
kind at one severity; ``SEVERITIES``: lighting drift [% gain per touch], sensor noise [grey
levels], partial contact [share of the contact area lost], low force [share of the contact
difference lost], worn gel [blur px]).

Methods: ``default`` (the shipped method: descriptor, information-gain touches, stop at belief
0.9, at most ``--budget`` touches after the baseline) on ``--scenes`` scenes at every severity;
``cnn`` (the lab's CNN preset, variance strategy, ``--cnn-rounds`` touches after the baseline, no
stop) on the first ``--cnn-scenes`` scenes at the severities of ``--cnn-levels`` (indices into
each axis); ``seed_faithful`` likewise when listed (about 40 s of CPU per decision). ``--guard
KIND`` also runs the default with ``--guard-set`` overrides (a guard's settings) on KIND's axis.

Per method, perturbation and severity: accuracy with its Wilson 95 % interval, touches after the
baseline (mean), rejected touches, and the exact McNemar test against the same method on the
same scenes unperturbed; the method *breaks* at the first severity whose accuracy is below the
clean one with p < ``--alpha``. Guarded runs: the same, plus McNemar guarded vs unguarded per
severity. Outputs: ``summary.json``, ``runs.json``, ``severity.png`` (one panel per
perturbation, one line per method with its 95 % band and number of scenes).
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path
from typing import Any

import numpy as np

from tactex_ros.core.config import trial_preset
from tactex_ros.core.errors import InputError
from tactex_ros.sources.perturb import KINDS
from tactex_lab.analysis import charts
from tactex_lab.analysis.stats import mcnemar_exact, wilson
from tactex_lab.experiments.common import learner_set, results_dir, write_json
from tactex_lab.experiments.runner import (TrialJob, TrialResult, add_runner_args, backend_of,
                                           run_jobs)

SEVERITIES: dict[str, list[float]] = {
    "drift": [1.0, 2.0, 4.0, 8.0],          # % gain change per touch
    "noise": [2.0, 5.0, 10.0, 20.0],        # grey levels (std)
    "partial": [0.25, 0.5, 0.75, 0.9],      # share of the contact area lost
    "low_force": [0.5, 0.75, 0.9, 0.95],    # share of the contact difference lost
    "worn": [1.0, 2.0, 4.0, 8.0],           # blur px
}
UNITS = {"drift": "% gain per touch", "noise": "grey levels", "partial": "share of contact lost",
         "low_force": "share of contact difference lost", "worn": "gel blur [px]"}
METHODS = ("default", "cnn", "seed_faithful")      # presets; each runs its trial preset
GUARDED = "default+guard"


def scenes_of(source: str, n: int, comparisons: int, seed0: int) -> list[list[str]]:
    """``n`` scenes [reference, comparisons...] of the source's classes, seeds seed0 .."""
    from tactex_ros.sources import assign_platforms
    from tactex_lab.experiments.runner import cached_source
    classes = cached_source(source).classes
    if len(classes) < comparisons:
        raise InputError(f"{source}: {len(classes)} classes cannot fill {comparisons} "
                         "comparisons")
    return [assign_platforms(classes, comparisons, None, None, seed0 + i)[0] for i in range(n)]


def conditions(args: argparse.Namespace) -> list[tuple[str, str, float]]:
    """(method label, perturbation kind or 'clean', severity) of every condition run."""
    out: list[tuple[str, str, float]] = []
    for m in args.methods:
        out.append((m, "clean", 0.0))
        for kind in args.perturbations:
            levels = SEVERITIES[kind]
            pick = range(len(levels)) if m == "default" else args.cnn_levels
            out += [(m, kind, levels[i]) for i in pick]
    if args.guard:
        out.append((GUARDED, "clean", 0.0))
        out += [(GUARDED, args.guard, v) for v in SEVERITIES[args.guard]]
    return out


def build_jobs(args: argparse.Namespace, scenes: list[list[str]]) -> list[TrialJob]:
    jobs = []
    guard_over = learner_set(args.guard_set, "--guard-set")
    for label, kind, sev in conditions(args):
        method = "default" if label == GUARDED else label
        n = args.scenes if method == "default" else args.cnn_scenes
        rounds = args.budget if method == "default" else args.cnn_rounds
        over: dict[str, Any] = dict(guard_over) if label == GUARDED else {}
        for i, classes in enumerate(scenes[:n]):
            jobs.append(TrialJob(
                source=args.source, seed=args.seed + i, trial=trial_preset(method, rounds=rounds),
                preset=method,
                overrides=over, platform_classes=classes, comparisons=len(classes) - 1,
                perturb={"touch": [kind, sev]} if kind != "clean" else {},
                catch_errors=True, no_contact_reference=False, trial_id=f"{label}/{kind}={sev:g}/"
                f"s{i}", tags={"method": label, "kind": kind, "severity": sev, "scene": i}))
    return jobs


def compact(res: TrialResult) -> dict:
    """One trial's result -> the fields the summary reads."""
    return {**res.job.tags, "correct": res.correct, "touches": res.touches - len(res.classes),
            "error": res.error, "rejected": len(res.failed_touches),
            "sure": None if res.outcome is None else res.outcome.sure,
            "classes": res.classes, "wall_s": res.wall_s}


SAME = ("source", "seed", "budget", "comparisons", "cnn_rounds")


def _key(tags: dict) -> tuple:
    return (tags["method"], tags["kind"], float(tags["severity"]), int(tags["scene"]))


def reused(folder: str, args: argparse.Namespace) -> dict[tuple, dict]:
    """The trials of an earlier run in ``folder`` (its ``runs.json``), by (method, kind,
    severity, scene); InputError unless it ran with the same ``SAME`` settings."""
    d = Path(folder)
    try:
        cfg = json.loads((d / "config.json").read_text())["config"]
        runs = json.loads((d / "runs.json").read_text())
    except (OSError, ValueError, KeyError) as exc:
        raise InputError(f"--reuse {folder}: not a finished stability-real results folder "
                         f"({exc})") from None
    diff = [k for k in SAME if cfg.get(k) != vars(args).get(k)]
    if diff:
        raise InputError(f"--reuse {folder}: ran with other {', '.join(diff)} "
                         f"({', '.join(f'{k}={cfg.get(k)!r}' for k in diff)})")
    same_guard = cfg.get("guard_set") == args.guard_set
    return {_key(r): r for r in runs if same_guard or r["method"] != GUARDED}


def block(runs: list[dict], clean: list[dict] | None) -> dict:
    """Accuracy, interval, touches and the McNemar test against ``clean`` (same scenes)."""
    runs = sorted(runs, key=lambda r: r["scene"])
    c = [r["correct"] for r in runs]
    out: dict[str, Any] = {"n": len(c), "accuracy": float(np.mean(c)),
                           "ci95": list(wilson(sum(c), len(c))),
                           "touches": float(np.mean([r["touches"] for r in runs])),
                           "rejected": int(sum(r["rejected"] for r in runs)),
                           "errors": sum(1 for r in runs if r["error"])}
    if clean is not None:
        ref = {r["scene"]: r["correct"] for r in clean}
        paired = [(r["correct"], ref[r["scene"]]) for r in runs if r["scene"] in ref]
        out["mcnemar_vs_clean"] = mcnemar_exact([a for a, _ in paired], [b for _, b in paired])
    return out


def breaks_at(levels: list[float], blocks: dict[str, dict], clean: dict,
              alpha: float) -> float | None:
    """First severity whose accuracy is below the clean one with McNemar p < ``alpha``."""
    for v in levels:
        b = blocks.get(f"{v:g}")
        if b and b["accuracy"] < clean["accuracy"] and b["mcnemar_vs_clean"]["p"] < alpha:
            return v
    return None


def summarise(runs: list[dict], args: argparse.Namespace) -> dict:
    methods = list(args.methods) + ([GUARDED] if args.guard else [])
    table: dict = {}
    for m in methods:
        clean_runs = [r for r in runs if r["method"] == m and r["kind"] == "clean"]
        t: dict[str, Any] = {"clean": block(clean_runs, None)}
        for kind in (args.perturbations if m != GUARDED else [args.guard]):
            levels = sorted({r["severity"] for r in runs
                             if r["method"] == m and r["kind"] == kind})
            blocks = {f"{v:g}": block([r for r in runs if r["method"] == m and
                                       r["kind"] == kind and r["severity"] == v], clean_runs)
                      for v in levels}
            t[kind] = {"levels": blocks,
                       "breaks_at": breaks_at(levels, blocks, t["clean"], args.alpha)}
        table[m] = t
    out: dict[str, Any] = {"methods": methods, "severities": SEVERITIES, "units": UNITS,
                           "alpha": args.alpha, "table": table}
    if args.guard:
        g = args.guard
        rows = []
        for v in SEVERITIES[g]:
            on = sorted([r for r in runs if r["method"] == GUARDED and r["kind"] == g and
                         r["severity"] == v], key=lambda r: r["scene"])
            off = {r["scene"]: r for r in runs if r["method"] == "default" and r["kind"] == g
                   and r["severity"] == v}
            pairs = [(r, off[r["scene"]]) for r in on if r["scene"] in off]
            if not pairs:       # the unguarded runs are elsewhere (a later --reuse joins them)
                continue
            rows.append({"severity": v, "n": len(pairs),
                         "with": float(np.mean([a["correct"] for a, _ in pairs])),
                         "without": float(np.mean([b["correct"] for _, b in pairs])),
                         "mcnemar_with_vs_without": mcnemar_exact(
                             [a["correct"] for a, _ in pairs], [b["correct"] for _, b in pairs])})
        out["guard"] = {"perturbation": g, "set": learner_set(args.guard_set, "--guard-set"),
                        "per_severity": rows}
    return out


def figure(out: Path, summary: dict) -> Path:
    panels = {}
    for kind in SEVERITIES:
        series = {}
        for m in summary["methods"]:
            t = summary["table"][m]
            if kind not in t:
                continue
            pts = [(0.0, t["clean"])] + [(float(v), b) for v, b in t[kind]["levels"].items()]
            ns = sorted({b["n"] for _, b in pts})
            series[m] = {"x": [p[0] for p in pts], "accuracy": [p[1]["accuracy"] for p in pts],
                         "lo": [p[1]["ci95"][0] for p in pts],
                         "hi": [p[1]["ci95"][1] for p in pts],
                         "n": ns[0] if len(ns) == 1 else "-".join(map(str, ns))}
        if series:
            panels[f"{kind} ({UNITS[kind]})"] = series
    return charts.accuracy_panels(out / "severity.png", panels,
                                  "accuracy against severity on replayed real presses")


def run(args: argparse.Namespace) -> int:
    for k in args.perturbations:
        if k not in SEVERITIES:
            raise InputError(f"--perturbations: unknown {k!r}; choose from {', '.join(KINDS)}")
    for m in args.methods:
        if m not in METHODS:
            raise InputError(f"--methods: unknown {m!r}; choose from {', '.join(METHODS)}")
    if not args.methods and not args.guard:
        raise InputError("--methods: none given and no --guard: nothing to run")
    if args.guard and args.guard not in SEVERITIES:
        raise InputError(f"--guard {args.guard!r}: choose a perturbation of {', '.join(KINDS)}")
    if not args.source.startswith("replay:"):
        raise InputError(f"--source {args.source!r}: this study replays real presses "
                         "(replay:DIR)")
    for i in args.cnn_levels:
        if not 0 <= i < 4:
            raise InputError(f"--cnn-levels {i}: an index 0..3 into each severity axis")
    if args.scenes < 1 or args.cnn_scenes < 0:
        raise InputError("--scenes must be >= 1 and --cnn-scenes >= 0")
    backend = backend_of(args).resolved()
    cfg = {k: v for k, v in vars(args).items() if k != "func"}
    out = results_dir(args.out, "stability_real", cfg)
    scenes = scenes_of(args.source, max(args.scenes, args.cnn_scenes), args.comparisons,
                       args.seed)
    jobs = build_jobs(args, scenes)
    done = {k: r for d in (args.reuse or []) for k, r in reused(d, args).items()}
    todo = [j for j in jobs if _key(j.tags) not in done]
    t0 = time.perf_counter()
    res = iter(run_jobs(todo, backend, threads=args.threads,
                        description=f"stability on real presses ({len(todo)} trials)",
                        quiet=args.quiet))
    runs = [done[_key(j.tags)] if _key(j.tags) in done else compact(next(res)) for j in jobs]
    summary = summarise(runs, args)
    summary.update(wall_s=time.perf_counter() - t0, trials=len(jobs), run_here=len(todo),
                   source=args.source, reused_from=args.reuse)
    write_json(out / "summary.json", summary)
    write_json(out / "runs.json", runs)
    figure(out, summary)
    for m in summary["methods"]:
        t = summary["table"][m]
        print(f"{m}: clean {t['clean']['accuracy']:.3f} (n = {t['clean']['n']}); breaks at "
              + ", ".join(f"{k} {t[k]['breaks_at']}" for k in t if k != "clean"))
    for r in summary.get("guard", {}).get("per_severity", []):
        print(f"  guard {summary['guard']['perturbation']}={r['severity']:g}: without "
              f"{r['without']:.3f} -> with {r['with']:.3f} "
              f"(p = {r['mcnemar_with_vs_without']['p']:.3g})")
    print(f"results in {out}")
    return 0


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("stability-real", help="perturbations of replayed real presses: where "
                                              "each method breaks; a guard before/after")
    p.add_argument("--source", required=True, help="replay:DIR of recorded presses")
    p.add_argument("--methods", nargs="*", default=["default", "cnn"],
                   help=f"of {', '.join(METHODS)} (none: only the guarded runs of --guard)")
    p.add_argument("--perturbations", nargs="+", default=list(SEVERITIES),
                   help=f"of {', '.join(SEVERITIES)}")
    p.add_argument("--scenes", type=int, default=40, help="scenes of the default method")
    p.add_argument("--cnn-scenes", type=int, default=12,
                   help="scenes of the CNN methods (the first of the default's)")
    p.add_argument("--cnn-levels", type=int, nargs="+", default=[1, 3],
                   help="severity indices (0..3) the CNN methods run")
    p.add_argument("--cnn-rounds", type=int, default=5,
                   help="touches after the baseline of the CNN methods")
    p.add_argument("--budget", type=int, default=15,
                   help="most touches after the baseline of the default method")
    p.add_argument("--comparisons", type=int, default=4)
    p.add_argument("--seed", type=int, default=0, help="scene i has seed seed + i")
    p.add_argument("--alpha", type=float, default=0.05,
                   help="significance of a break (exact McNemar against clean)")
    p.add_argument("--guard", help="perturbation on which the default also runs with "
                                   "--guard-set")
    p.add_argument("--guard-set", action="append", metavar="KEY=VALUE",
                   help="learner settings of the guarded run "
                        "(e.g. learner.contact_region_min=0.6)")
    p.add_argument("--reuse", metavar="DIR", nargs="+", help="take the trials earlier runs in "
                   "these folders already made (same source, seed, budget, comparisons) "
                   "instead of running them again")
    p.add_argument("--out", help="results folder (default results/stability_real)")
    add_runner_args(p)
    p.set_defaults(func=run)
