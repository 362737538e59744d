"""``tactex experiment stop-rules`` (first cut): the threshold stop against the e-value stop,
or (``--strategies A B``) one next-touch strategy against another under the threshold stop,
paired (the same scenes, seeds and touches' source), on one source's random or hard scenes
(``--scene-protocol``, ``scenes.py``).

Per arm: accuracy (Wilson 95 %), touches after the baseline, the share of sure-and-wrong
scenes and of not-sure ones; an exact McNemar test of correctness between the two arms and a
paired Wilcoxon test of their touches. Each trial runs with the shipped default settings and
only ``trial.stop_rule`` (and ``trial.stop_confidence`` / ``trial.stop_alpha``) or
``trial.strategy`` differs. Not yet: class-disjoint choosing, calibration error
(docs/research/sequential_stop.md, "Left").
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np

from tactex_ros.core.errors import InputError


def run(source: str, scenes: int, comparisons: int, rounds: int, seed: int, theta: float,
        alpha: float, strategies: list[str] | None = None, scene_protocol: str = "random",
        metric_library: str | None = None, representation: str = "",
        stop_null: str = "library") -> dict:
    """Run every scene under both arms (the two rules, or the two ``strategies`` under the
    threshold rule); returns the summary (per arm and the paired tests). ``representation``:
    a ``tactex prepare`` file both arms run with (its evidence model for the e-value rule);
    ``stop_null``: the e-value rule's ``trial.stop_null``."""
    from tactex_ros.core.config import preset, trial_preset
    from tactex_ros.core.engine import TrialSpec, run_trial
    from tactex_ros.sources import open_source
    from tactex_ros.core.stats import wilson
    from tactex_lab.analysis.stats import mcnemar_exact, wilcoxon_paired
    from tactex_ros.core.calibration import ece_of
    from tactex_lab.experiments.scenes import SceneDraw

    src = open_source(source)
    learner = preset("default", representation=representation)
    if strategies:
        rules = {st: dict(stop_rule="threshold", stop_confidence=theta, strategy=st)
                 for st in strategies}
    else:
        rules = {"threshold": dict(stop_rule="threshold", stop_confidence=theta),
                 "evalue": dict(stop_rule="evalue", stop_alpha=alpha, stop_null=stop_null)}
    scene = SceneDraw(scene_protocol, src, comparisons, preset("default"), metric_library,
                      source)
    rows: dict[str, list[dict]] = {k: [] for k in rules}
    drawn = []
    for i in range(scenes):
        classes, truth = scene.draw(seed + i)
        drawn.append(classes)
        for name, over in rules.items():
            res = run_trial(TrialSpec(comparisons, learner,
                                      trial_preset("default", rounds=rounds, **over),
                                      seed=seed + i), src.trial(classes, seed + i), truth=truth)
            rows[name].append({"correct": bool(res.correct), "sure": bool(res.sure),
                               "extra": res.touches - (comparisons + 1),
                               "confidence": res.confidence})
    out: dict = {"source": source, "scenes": scenes, "comparisons": comparisons,
                 "rounds": rounds, "seed": seed, "theta": theta, "alpha": alpha,
                 "stop_null": None if strategies else stop_null,
                 "scene_protocol": scene_protocol, "representation": representation or None,
                 "metric_library": metric_library if scene_protocol == "hard" else None,
                 "arms": {}, "scene_classes": drawn}
    for name, rs in rows.items():
        k = sum(r["correct"] for r in rs)
        lo, hi = wilson(k, len(rs))
        out["arms"][name] = {
            "accuracy": k / len(rs), "wilson95": [lo, hi],
            "touches": float(np.mean([r["extra"] for r in rs])),
            "ece": ece_of(np.array([r["confidence"] for r in rs]),
                          np.array([r["correct"] for r in rs])),
            "sure_and_wrong": float(np.mean([r["sure"] and not r["correct"] for r in rs])),
            "not_sure": float(np.mean([not r["sure"] for r in rs]))}
    a, b = list(rules)
    out["mcnemar_p"] = mcnemar_exact([r["correct"] for r in rows[a]],
                                     [r["correct"] for r in rows[b]])["p"]
    out["wilcoxon_touches"] = wilcoxon_paired([r["extra"] for r in rows[a]],
                                              [r["extra"] for r in rows[b]])
    out["rows"] = rows
    return out


def register(esub: argparse._SubParsersAction) -> None:
    p = esub.add_parser("stop-rules", help="threshold stop vs e-value stop (or two "
                                           "strategies), paired scenes")
    p.add_argument("--source", required=True, help="replay:DIR or sim")
    p.add_argument("--scenes", type=int, default=20)
    p.add_argument("--comparisons", type=int, default=4)
    p.add_argument("--rounds", type=int, default=10, help="touch budget after the baseline")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--theta", type=float, default=0.9, help="threshold rule's stop belief")
    p.add_argument("--alpha", type=float, default=0.03, help="e-value rule's bound")
    p.add_argument("--strategies", nargs=2, metavar=("A", "B"), default=None,
                   help="compare these two next-touch strategies under the threshold stop "
                        "instead of the two stop rules")
    p.add_argument("--scene-protocol", choices=("random", "hard"), default="random",
                   help="random classes, or hard: the reference's nearest classes by a metric "
                        "fitted on --metric-library")
    p.add_argument("--metric-library", default=None,
                   help="replay:DIR whose classes are not the source's: fits the hard scenes' "
                        "metric")
    p.add_argument("--representation", default="",
                   help="a tactex prepare file both arms run with (prepare it on another "
                        "library: class-disjoint)")
    p.add_argument("--stop-null", choices=("library", "scene"), default="library",
                   help="the e-value rule's trial.stop_null: the evidence model's null, or "
                        "also the scene's own pairs of comparisons")
    p.add_argument("--file", required=True, help="summary JSON to write")

    def func(args: argparse.Namespace) -> int:
        if args.scenes < 1 or args.comparisons < 2 or args.rounds < 1:
            raise InputError("--scenes >= 1, --comparisons >= 2 and --rounds >= 1 needed, got "
                             f"{args.scenes}, {args.comparisons}, {args.rounds}")
        if args.strategies:
            from tactex_ros.core.config import STRATEGY_NAMES
            bad = [st for st in args.strategies if st not in STRATEGY_NAMES]
            if bad or args.strategies[0] == args.strategies[1]:
                raise InputError(f"--strategies {' '.join(args.strategies)}: two different "
                                 f"ones of {', '.join(STRATEGY_NAMES)}")
        out = run(args.source, args.scenes, args.comparisons, args.rounds, args.seed,
                  args.theta, args.alpha, args.strategies, args.scene_protocol,
                  args.metric_library, args.representation, args.stop_null)
        Path(args.file).parent.mkdir(parents=True, exist_ok=True)
        Path(args.file).write_text(json.dumps(out, indent=1) + "\n")
        for name, r in out["arms"].items():
            print(f"{name}: accuracy {r['accuracy']:.3f} [{r['wilson95'][0]:.3f}, "
                  f"{r['wilson95'][1]:.3f}], touches {r['touches']:.2f}, sure and wrong "
                  f"{r['sure_and_wrong']:.1%}, not sure {r['not_sure']:.1%}, final-belief "
                  f"ECE {r['ece']:.3f}")
        print(f"McNemar p = {out['mcnemar_p']:.3g}, touches Wilcoxon p = "
              f"{out['wilcoxon_touches']['p']:.3g}")
        return 0

    p.set_defaults(func=func)
