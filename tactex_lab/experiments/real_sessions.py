"""``tactex experiment real-sessions``: does a setting use the recording session?

The same real scenes replayed as recorded and moved onto one background per trial (as a live
robot presses), paired per scene (``run_sessions``).
"""

from __future__ import annotations

import argparse
from typing import Any

import numpy as np

from tactex_ros.core.config import SHIPPED_STOP
from tactex_ros.core.errors import InputError
from tactex_lab.experiments.common import results_dir, write_json
from tactex_lab.experiments.curves import (at_budget, at_stop, belief_curves, draw_scenes,
                                           paired_at_budgets, paired_at_thresholds,
                                           parse_setting)
from tactex_lab.experiments.runner import Backend


def run_sessions(real_dir: str, settings: list[str], scenes: int, comparisons: int,
                 budget: int, seed: int, workers: int, out: str | None = None
                 ) -> dict[str, Any]:
    """Does a setting use the recording session? Every setting on the same ``scenes`` real
    scenes (same seeds) replayed as recorded (``replay:DIR``) and moved onto one background
    per trial (``replay:DIR:one-session``, as a live robot presses): accuracy after 0, 1, 3,
    ``budget`` touches and at the stop 0.9 on both, exact McNemar of one-session against
    recorded per setting (paired by scene), and the per-scene outcomes."""
    parsed = [parse_setting(t) for t in settings]
    labels = [q[0] for q in parsed]
    if len(set(labels)) != len(labels):
        raise InputError(f"setting labels must be unique, got {labels}")
    from tactex_ros.sources import open_source
    classes = sorted(open_source(f"replay:{real_dir}").classes)
    scene_list = draw_scenes(classes, scenes, comparisons, seed)
    d = results_dir(out, "real_sessions", {"real": real_dir, "settings": settings,
                                           "scenes": scenes, "comparisons": comparisons,
                                           "budget": budget, "seed": seed})
    curves = {side: belief_curves(scene_list, parsed, f"replay:{real_dir}{suffix}", seed,
                                  budget, f"{side}-", Backend("joblib", workers))
              for side, suffix in (("recorded", ""), ("one_session", ":one-session"))}
    points = sorted({0, 1, 3, budget})
    res: dict[str, Any] = {"scenes": scenes, "comparisons": comparisons, "budget": budget,
                           "seed": seed, "settings": {}}
    at = f"at_stop_{SHIPPED_STOP:g}"       # the shipped stop, in the summary's keys
    for lab in labels:
        both = {side: curves[side][lab] for side in curves}
        row: dict[str, Any] = {}
        for side, cs in both.items():
            row[side] = {"accuracy_at": {str(k): float(np.mean([at_budget(c, k) for c in cs]))
                                         for k in points},
                         f"accuracy_{at}": float(np.mean([at_stop(c, SHIPPED_STOP)[0]
                                                          for c in cs])),
                         f"touches_{at}": float(np.mean([at_stop(c, SHIPPED_STOP)[1]
                                                         for c in cs])),
                         "correct_at_budget": [at_budget(c, budget) for c in cs],
                         "failed_trials": sum(1 for c in cs if c.error)}
        row["paired_at_budgets"] = paired_at_budgets(both, "recorded",
                                                     tuple(points))["one_session"]
        row[f"paired_{at}"] = paired_at_thresholds(both, "recorded",
                                                   [SHIPPED_STOP])["one_session"]
        res["settings"][lab] = row
    write_json(d / "summary.json", res)
    for lab, row in res["settings"].items():
        r, o = row["recorded"], row["one_session"]
        pb = row["paired_at_budgets"][str(budget)]["p"]
        print(f"{lab:>16}: +{budget} recorded {r['accuracy_at'][str(budget)]:.3f} one-session "
              f"{o['accuracy_at'][str(budget)]:.3f} (McNemar p {pb:.3g}); stop {SHIPPED_STOP:g} "
              f"{r[f'accuracy_{at}']:.3f} / {o[f'accuracy_{at}']:.3f} with "
              f"{r[f'touches_{at}']:.2f} / {o[f'touches_{at}']:.2f} touches")
    print(f"wrote {d}")
    return res


def register(esub: argparse._SubParsersAction) -> None:
    q = esub.add_parser("real-sessions", help="real presses replayed as recorded and moved "
                                              "onto one session: does a setting use the "
                                              "recording session?")
    q.add_argument("--real", required=True, help="folder of recorded presses")
    q.add_argument("--setting", action="append", required=True,
                   help="label=preset[:PATH=value,...] (repeat)")
    q.add_argument("--scenes", type=int, default=30)
    q.add_argument("--comparisons", type=int, default=4)
    q.add_argument("--budget", type=int, default=5)
    q.add_argument("--seed", type=int, default=0)
    q.add_argument("--workers", type=int, default=1)
    q.add_argument("--out")

    def sessions(args: argparse.Namespace) -> int:
        if args.scenes < 2 or args.budget < 0 or args.workers < 1 or args.comparisons < 2:
            raise InputError("--scenes >= 2, --budget >= 0, --workers >= 1, "
                             "--comparisons >= 2")
        run_sessions(args.real, args.setting, args.scenes, args.comparisons, args.budget,
                     args.seed, args.workers, args.out)
        return 0

    q.set_defaults(func=sessions)
