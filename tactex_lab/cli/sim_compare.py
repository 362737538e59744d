"""``tactex sim compare``: the sim-to-real report (frame statistics per fabric family and the
ranking of learner settings on both sides), added to the product's ``sim`` group."""

from __future__ import annotations

import argparse

from tactex_ros.cli.options import builds, command_group
from tactex_ros.core.errors import InputError


def compare_with_real(real_dir: str, out_png: str, seed: int = 0, per_class: int = 2,
                      real_per_class: int = 3, ranking: dict | None = None,
                      fabrics: list[str] | None = None) -> dict:
    """The sim-to-real report (``analysis/sim_vs_real.py``): frame statistics per family, a
    picture (``analysis.charts.sim_vs_real``) and, with ``ranking`` (keyword arguments of
    ``experiments.ranking.run_ranking`` except the folder), the ranking agreement of learner
    settings. ``fabrics``: simulated fabrics of the statistics (default: the whole
    catalogue)."""
    from tactex_lab.analysis import charts
    from tactex_lab.analysis import sim_vs_real as compare
    from tactex_lab.experiments.ranking import run_ranking

    every = compare.real_presses(real_dir, 10 ** 6)
    real = compare.first_presses(every, real_per_class)
    sim = compare.sim_presses(per_class, seed, fabrics)
    result = compare.frame_report(real, sim, every)
    result["real_classes"] = sorted({p.name for p in real})
    result["sim_fabrics"] = sorted({p.name for p in sim})
    if ranking is not None:
        result["ranking"] = run_ranking(real_dir, seed=seed, **ranking)
    charts.sim_vs_real(out_png, real, sim, result.get("ranking"))
    return result


def _print_report(res: dict) -> None:
    print(f"{'group':<14} {'statistic':<20} {'real':>22} {'sim':>22} {'ratio':>18}  <=25%")
    for c in res["checks"]:
        def fmt(v):
            return (", ".join(f"{x:.2f}" for x in v) if isinstance(v, list) else f"{v:.3f}")
        print(f"{c['group']:<14} {c['statistic']:<20} {fmt(c['real']):>22} {fmt(c['sim']):>22} "
              f"{fmt(c['ratio']):>18}  {'yes' if c['within_25pct'] else 'no'}")
    print(f"{res['checks_passed']} of {len(res['checks'])} statistics within 25 % of real")
    rk = res.get("ranking")
    if rk:
        print(f"\n{'setting':<15} {'sim acc':>8} {'real acc':>9} {'gap':>7} {'sim mean':>9} "
              f"{'real mean':>10}   (accuracy after +{rk['budget']} touches; mean over "
              f"0..{rk['budget']})")
        for n, v in rk["settings"].items():
            print(f"{n:<15} {v['sim']['accuracy']:>8.3f} {v['real']['accuracy']:>9.3f} "
                  f"{v['gap_real_minus_sim']:>+7.3f} {v['sim']['accuracy_mean_over_budgets']:>9.3f} "
                  f"{v['real']['accuracy_mean_over_budgets']:>10.3f}")
        for key in ("accuracy_spearman", "mean_over_budgets_spearman"):
            sp = rk[key]
            print(f"{key}: rho {sp['rho']:.3f}, 95 % bootstrap interval "
                  f"[{sp['ci95'][0]:.3f}, {sp['ci95'][1]:.3f}] over {sp['settings']} settings")
        print(f"mean accuracy gap real - sim {rk['mean_gap_real_minus_sim']:+.3f} (mean |gap| "
              f"{rk['mean_abs_gap']:.3f}); {rk['scenes']} sim + {rk['scenes']} real scenes of "
              f"1 + {rk['comparisons']}; failed trials: sim {rk['sim_failed_trials']}, real "
              f"{rk['real_failed_trials']}")


def cmd_compare(args: argparse.Namespace) -> int:
    from tactex_lab.analysis.sim_vs_real import DEFAULT_SETTINGS
    ranking = None
    if args.presses < 1 or args.real_presses < 1:
        raise InputError("--presses and --real-presses must be >= 1")
    if args.scenes > 0:
        if not 2 <= args.comparisons <= 24:
            raise InputError(f"--comparisons must be in 2..24, got {args.comparisons}")
        if not 0 <= args.budget <= 100:
            raise InputError(f"--budget must be in 0..100, got {args.budget}")
        if args.workers < 1:
            raise InputError(f"--workers must be >= 1, got {args.workers}")
        from tactex_lab.experiments.curves import parse_setting
        for text in args.setting or []:
            parse_setting(text)          # a bad setting is refused before any work
        ranking = dict(settings=args.setting or list(DEFAULT_SETTINGS), scenes=args.scenes,
                       comparisons=args.comparisons, budget=args.budget, workers=args.workers,
                       sim_spec=args.sim_source, real_one_session=args.real_one_session)
    elif args.scenes < 0:
        raise InputError(f"--scenes must be >= 0, got {args.scenes}")
    fabrics = [f for f in args.fabrics.split(",") if f] if args.fabrics else None
    if fabrics:
        from tactex_ros.sim.fabrics import load_catalogue
        from tactex_ros.core.paths import config_dir
        known = load_catalogue(config_dir() / "fabrics.yaml")
        unknown = [f for f in fabrics if f not in known]
        if unknown:
            raise InputError(f"--fabrics: unknown {unknown}; `tactex sim fabrics` lists them")
    res = compare_with_real(args.real, args.out, args.seed, args.presses, args.real_presses,
                            ranking, fabrics)
    _print_report(res)
    if args.json:
        from tactex_ros.cli.options import write_json
        write_json(args.json, res)
    print(f"wrote {args.out}")
    return 0


def add_commands(sub: argparse._SubParsersAction, command: str | None = None) -> None:
    if not builds(command, "sim"):
        return
    c = command_group(sub, "sim", "fabric simulator").add_parser(
        "compare", help="sim-to-real report: frame statistics per family and the ranking of "
                        "learner settings on both sides")
    c.add_argument("--real", required=True, help="folder of real presses (<class>/<file>)")
    c.add_argument("--out", required=True, help="PNG: side-by-side frames (+ ranking)")
    c.add_argument("--seed", type=int, default=0)
    c.add_argument("--json")
    c.add_argument("--presses", type=int, default=2, help="simulated presses per fabric")
    c.add_argument("--real-presses", type=int, default=3, help="real presses per class")
    c.add_argument("--fabrics", help="comma-separated simulated fabrics for the statistics "
                                     "(default: the whole catalogue)")
    c.add_argument("--scenes", type=int, default=0,
                   help="scenes per side for the ranking of learner settings (0 = skip it)")
    c.add_argument("--setting", action="append",
                   help="label=preset[:PATH=value,...] as for `tactex experiment real` "
                        "(repeat; default: analysis/sim_vs_real.py DEFAULT_SETTINGS)")
    c.add_argument("--comparisons", type=int, default=4)
    c.add_argument("--budget", type=int, default=5,
                   help="touches after the baseline; accuracy is ranked at this budget")
    c.add_argument("--workers", type=int, default=1)
    c.add_argument("--sim-source", default="sim:recorded",
                   help="simulated side of the ranking (default sim:recorded: every fabric "
                        "in its own recording session, as the real folder's classes; sim: "
                        "one session per trial, as a live robot)")
    c.add_argument("--real-one-session", action="store_true",
                   help="rank on the real presses moved onto one background per trial "
                        "(replay:DIR:one-session), as a live robot sees them")
    c.set_defaults(func=cmd_compare)
