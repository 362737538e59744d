"""``tactex experiment stop-rules`` (first cut): the threshold stop against the e-value stop,
paired (the same scenes, seeds and touches' source), on one source's random scenes.

Per rule: accuracy (Wilson 95 %), touches after the baseline, the share of sure-and-wrong
scenes and of not-sure ones; an exact McNemar test of correctness between the rules. Each
trial runs with the shipped default settings and only ``trial.stop_rule`` differs (and
``trial.stop_confidence`` / ``trial.stop_alpha``). Not yet: class-disjoint choosing, hard
scenes, calibration error (docs/research/sequential_stop.md, "Left").
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np

from tactex_ros.core.errors import InputError


def run(source: str, scenes: int, comparisons: int, rounds: int, seed: int, theta: float,
        alpha: float) -> dict:
    """Run every scene under both rules; returns the summary (per rule and the paired test)."""
    from tactex_ros.core.config import preset, trial_preset
    from tactex_ros.core.engine import TrialSpec, run_trial
    from tactex_ros.sources import open_source, trial_scene
    from tactex_ros.core.stats import wilson
    from tactex_lab.analysis.stats import mcnemar_exact

    src = open_source(source)
    rules = {"threshold": dict(stop_rule="threshold", stop_confidence=theta),
             "evalue": dict(stop_rule="evalue", stop_alpha=alpha)}
    rows: dict[str, list[dict]] = {k: [] for k in rules}
    for i in range(scenes):
        classes, truth = trial_scene(src, comparisons, seed + i)
        for name, over in rules.items():
            res = run_trial(TrialSpec(comparisons, preset("default"),
                                      trial_preset("default", rounds=rounds, **over),
                                      seed=seed + i), src.trial(classes, seed + i), truth=truth)
            rows[name].append({"correct": bool(res.correct), "sure": bool(res.sure),
                               "extra": res.touches - (comparisons + 1)})
    out: dict = {"source": source, "scenes": scenes, "comparisons": comparisons,
                 "rounds": rounds, "seed": seed, "theta": theta, "alpha": alpha, "rules": {}}
    for name, rs in rows.items():
        k = sum(r["correct"] for r in rs)
        lo, hi = wilson(k, len(rs))
        out["rules"][name] = {
            "accuracy": k / len(rs), "wilson95": [lo, hi],
            "touches": float(np.mean([r["extra"] for r in rs])),
            "sure_and_wrong": float(np.mean([r["sure"] and not r["correct"] for r in rs])),
            "not_sure": float(np.mean([not r["sure"] for r in rs]))}
    out["mcnemar_p"] = mcnemar_exact([r["correct"] for r in rows["threshold"]],
                                     [r["correct"] for r in rows["evalue"]])["p"]
    out["rows"] = rows
    return out


def register(esub: argparse._SubParsersAction) -> None:
    p = esub.add_parser("stop-rules", help="threshold stop vs e-value stop, paired scenes")
    p.add_argument("--source", required=True, help="replay:DIR or sim")
    p.add_argument("--scenes", type=int, default=20)
    p.add_argument("--comparisons", type=int, default=4)
    p.add_argument("--rounds", type=int, default=10, help="touch budget after the baseline")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--theta", type=float, default=0.9, help="threshold rule's stop belief")
    p.add_argument("--alpha", type=float, default=0.03, help="e-value rule's bound")
    p.add_argument("--file", required=True, help="summary JSON to write")

    def func(args: argparse.Namespace) -> int:
        if args.scenes < 1 or args.comparisons < 2 or args.rounds < 1:
            raise InputError("--scenes >= 1, --comparisons >= 2 and --rounds >= 1 needed, got "
                             f"{args.scenes}, {args.comparisons}, {args.rounds}")
        out = run(args.source, args.scenes, args.comparisons, args.rounds, args.seed,
                  args.theta, args.alpha)
        Path(args.file).parent.mkdir(parents=True, exist_ok=True)
        Path(args.file).write_text(json.dumps(out, indent=1) + "\n")
        for name, r in out["rules"].items():
            print(f"{name}: accuracy {r['accuracy']:.3f} [{r['wilson95'][0]:.3f}, "
                  f"{r['wilson95'][1]:.3f}], touches {r['touches']:.2f}, sure and wrong "
                  f"{r['sure_and_wrong']:.1%}, not sure {r['not_sure']:.1%}")
        print(f"McNemar p = {out['mcnemar_p']:.3g}")
        return 0

    p.set_defaults(func=func)
