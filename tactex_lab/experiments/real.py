"""``tactex experiment real``: accuracy against touches on real presses, class-disjoint.

Every default of tactex is justified by this command on recorded real presses (a replay folder,
e.g. ``../shared/datasets/octopi-dev``); the simulator is a second opinion.

Scenes: 1 reference + C comparisons drawn from a set of classes with ``sources.assign_platforms``
(the same draw as ``tactex trial --seed S``), the same scenes for every setting (paired).
Each setting runs every scene *without* a stop rule up to ``--budget`` touches after the
baseline and records the belief after every touch. From that one run:

- accuracy after k touches (k = 0 .. budget) with Wilson 95 % intervals;
- for every stop threshold theta in ``--thresholds``: the trial stops at the first decision
  whose belief reaches theta (or at the budget); accuracy at the stop, touches after the
  baseline until the stop (mean), wrong-stop rate (stopped confident and wrong);
- decision time (median over all decisions) and the share of touches spent on the platform the
  belief favoured at that moment ("believed").

The policy's choices do not depend on theta, so the sweep over theta is exact, not re-run.

Class-disjoint protocol (``--folds K``, K >= 2): the classes are split into K folds (seeded). For
fold k, ``--scenes`` scenes are drawn from the other folds' classes (*choose* scenes) and as many
from fold k's classes (*report* scenes). On the choose scenes, every (setting, theta) pair is
scored; the pair with the highest accuracy at the stop whose mean touches after the baseline are
<= ``--target-touches`` wins (ties: fewer touches). That pair is then measured on the report
scenes. The figure to trust pools the report scenes of all folds: classes never used for
choosing. Each setting is also reported at its own chosen theta, with exact McNemar tests paired
with the chosen setting on the same report scenes.

``--report-only`` skips the choose scenes (no choosing): every setting is measured on the same
report scenes of every fold at every theta of ``--thresholds`` (for settings too slow to run
twice, e.g. the CNN's uncertainty variants). ``--paired-against A B`` adds exact McNemar tests
(correct per scene, at fixed budgets and at every theta) and Wilcoxon tests (touches until the
stop) of every setting against each of A, B on the pooled report scenes (``paired``).

Output folder: ``config.json``, ``runs.json`` (per scene and setting: classes, the belief curve),
``summary.json``, ``accuracy_vs_touches.png``, ``pareto.png`` (accuracy at the stop against
touches, every setting x threshold).
"""

from __future__ import annotations

import argparse

from tactex_ros.core.errors import InputError
from tactex_lab.experiments.common import results_dir
from tactex_lab.experiments.curves import BeliefCurve, belief_curves, parse_setting
from tactex_lab.experiments.protocol import (PRESS_TIME_HELP, THRESHOLD_HELP, check_options,
                                             protocol, write_outputs)
from tactex_lab.experiments.runner import add_runner_args, backend_of

DEFAULT_SETTINGS = ("default=default", "random=default:trial.strategy=random",
                    "variance=default:trial.strategy=variance")


def _run(scenes, settings, args, tag) -> dict[str, list[BeliefCurve]]:
    return belief_curves(scenes, settings, args.source, args.seed, args.budget, tag,
                         backend_of(args), args.threads, args.quiet,
                         contact_guard=args.contact_guard == "on")


def run(args: argparse.Namespace) -> dict:
    from tactex_ros.sources import open_source
    settings = [parse_setting(s) for s in args.setting or DEFAULT_SETTINGS]
    labels = [s[0] for s in settings]
    if len(set(labels)) != len(labels):
        raise InputError(f"--setting labels must be unique, got {labels}")
    src = open_source(args.source)
    classes = sorted(src.classes)
    out = results_dir(args.out, "real", {k: v for k, v in vars(args).items() if k != "func"})
    summary = protocol(classes, labels, lambda scenes, tag: _run(scenes, settings, args, tag),
                       args)
    summary.update(source=args.source, settings={s[0]: {"preset": s[1], "strategy": s[2],
                                                        "overrides": s[3]} for s in settings})
    write_outputs(out, summary, labels, args)
    return summary


def register(esub: argparse._SubParsersAction) -> None:
    p = esub.add_parser("real", help="accuracy against touches on real presses "
                                     "(class-disjoint folds)")
    p.add_argument("--source", required=True, help="replay:DIR of recorded presses")
    p.add_argument("--comparisons", type=int, default=4)
    p.add_argument("--contact-guard", choices=("on", "off"), default="on",
                   help="on: a press the contact guard rejects against its own no-contact frame "
                        "is refused and pressed again, as on the robot; off: every press counts "
                        "(the figures before this option)")
    p.add_argument("--scenes", type=int, default=40, help="scenes per fold and set")
    p.add_argument("--budget", type=int, default=15, help="touches after the baseline")
    p.add_argument("--folds", type=int, default=3, help="class folds (1 = no choosing)")
    p.add_argument("--setting", action="append",
                   help="label=preset[:PATH=value,...] (repeat); default: "
                        + " ".join(DEFAULT_SETTINGS))
    p.add_argument("--thresholds", type=float, nargs="+", help=THRESHOLD_HELP)
    p.add_argument("--target-touches", type=float, default=5.0,
                   help="choose the most accurate (setting, theta) with at most this many "
                        "touches after the baseline on average")
    p.add_argument("--report-only", action="store_true",
                   help="no choose scenes: measure every setting on the report scenes of each "
                        "fold at every threshold (no choosing)")
    p.add_argument("--paired-against", nargs="+", metavar="LABEL",
                   help="paired tests of every setting against these settings (default: the "
                        "first --setting)")
    p.add_argument("--press-time", metavar="FILE|DIR", help=PRESS_TIME_HELP)
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--out")
    add_runner_args(p)

    def func(args: argparse.Namespace) -> int:
        check_options(args)
        for name in ("comparisons", "scenes", "budget", "folds"):
            if getattr(args, name) < (2 if name == "comparisons" else 1):
                raise InputError(f"--{name} too small: {getattr(args, name)}")
        run(args)
        return 0

    p.set_defaults(func=func)

