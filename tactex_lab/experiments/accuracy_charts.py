"""``tactex experiment accuracy-charts``: accuracy against touches and against trial time,
redrawn from the run JSONs of ``experiment real`` / ``experiment unseen`` (no trial is re-run).

Each ``--runs`` folder holds ``runs.json`` (per setting, the belief curve of every report scene)
and ``summary.json`` (budget, comparisons). Folders of the same protocol with other seeds (other
folds and scenes) are pooled per setting: a setting's line counts the scenes of every folder
that ran it, and the legend says how many. Each line has its 95 % Wilson band
(``charts.touches_and_time``). A folder without ``runs.json`` is redrawn from the counts its
``summary.json`` (``per_setting``) or ``pooled.json`` (``right_after``) keeps: the charts only,
as every point is a count of scenes right after k touches (no paired tests then).

The time axis counts a measured press time per press (``--press-time``:
``protocol.press_time``, a press benchmark's result or recorded trials; the baseline's presses
included) and the setting's median decision time per decision.
"""

from __future__ import annotations

import argparse
import json
from dataclasses import asdict
from pathlib import Path

import numpy as np

from tactex_ros.core.errors import InputError
from tactex_lab.analysis import charts
from tactex_lab.experiments.common import write_json
from tactex_lab.experiments.curves import BeliefCurve, paired_at_budgets, paired_at_thresholds
from tactex_lab.experiments.protocol import (DEFAULT_THRESHOLDS, PRESS_TIME_HELP, band_rows,
                                             per_class, press_time, score_pairs)


def load_runs(folders: list[str | Path], settings: list[str] | None = None
              ) -> tuple[dict[str, list[BeliefCurve]], int, int]:
    """Pool the report scenes of ``folders`` per setting (in first-seen order, or
    ``settings``): ({label: [belief curve per scene]}, budget, comparisons). The folders must
    share budget and comparisons."""
    pooled: dict[str, list[BeliefCurve]] = {}
    budget = comparisons = None
    for f in folders:
        f = Path(f)
        try:
            runs = json.loads((f / "runs.json").read_text())
            summary = json.loads((f / "summary.json").read_text())
        except (OSError, ValueError) as exc:
            raise InputError(f"--runs {f}: not a results folder with runs.json and "
                             f"summary.json ({exc})") from None
        b, c = int(summary["budget"]), int(summary["comparisons"])
        if budget is not None and (b, c) != (budget, comparisons):
            raise InputError(f"--runs {f}: budget {b} / comparisons {c} differ from the first "
                             f"folder's {budget} / {comparisons}")
        budget, comparisons = b, c
        for lab, cs in runs.items():
            try:
                pooled.setdefault(lab, []).extend(BeliefCurve.from_json(c) for c in cs)
            except InputError as exc:
                raise InputError(f"--runs {f}: runs.json, setting {lab!r}: {exc}") from None
    if budget is None:
        raise InputError("--runs: no folder given")
    labels = settings or list(pooled)
    missing = [s for s in labels if s not in pooled]
    if missing:
        raise InputError(f"--settings {missing}: not in the runs; they hold {list(pooled)}")
    return {lab: pooled[lab] for lab in labels}, budget, comparisons


def pooled_figures(curves: dict[str, list[BeliefCurve]], thresholds: list[float],
                   against: list[str], class_theta: float | None = None) -> dict:
    """The pooled scenes' figures: every (setting, theta) at the stop (``score_pairs``) and the
    paired tests against each setting of ``against`` at fixed budgets and thresholds; with
    ``class_theta``, each setting's outcome per reference class at that stop (``per_class``)."""
    budgets = (0, 1, 3, 5, 10)
    out = {"scenes": {lab: len(cs) for lab, cs in curves.items()},
           "report_rows": score_pairs(curves, thresholds),
           "paired": {ref: {"budgets": paired_at_budgets(curves, ref, budgets),
                            "thresholds": paired_at_thresholds(curves, ref, thresholds)}
                      for ref in against}}
    if class_theta is not None:
        out["per_class"] = {"theta": class_theta,
                            "rows": {lab: per_class(cs, class_theta)
                                     for lab, cs in curves.items()}}
    return out


def _counts_of(folder: Path) -> dict | None:
    """{label: {"n", "right" (per k = 0..K), "decision_s_median"}}, budget and comparisons of a
    folder without runs.json, from its summary.json's ``per_setting`` or its pooled.json's
    ``right_after``; None when neither holds them."""
    for name in ("summary.json", "pooled.json"):
        f = folder / name
        if not f.is_file():
            continue
        try:
            d = json.loads(f.read_text())
        except (OSError, ValueError) as exc:
            raise InputError(f"--runs {folder}: {name} not readable ({exc})") from None
        if "right_after" in d:
            return d
        if "per_setting" in d and "budget" in d and "comparisons" in d:
            rows = {}
            for lab, ps in d["per_setting"].items():
                n = int(ps["scenes"])
                rows[lab] = {"n": n, "decision_s_median": ps.get("decision_s_median") or 0.0,
                             "right": [round(a["accuracy"] * n)
                                       for a in ps["accuracy_vs_touches"]]}
            return {"budget": int(d["budget"]), "comparisons": int(d["comparisons"]),
                    "right_after": rows}
    return None


def rows_from_counts(counts: dict) -> dict[str, tuple[np.ndarray, float]]:
    """``band_rows``' form from counts (``_counts_of``): per setting a (n, K + 1) bool array
    whose column k has ``right[k]`` scenes right (the charts read column sums only) and the
    median decision time [s]."""
    rows = {}
    for lab, r in counts["right_after"].items():
        n, right = int(r["n"]), [int(v) for v in r["right"]]
        if n < 1 or any(not 0 <= v <= n for v in right):
            raise InputError(f"setting {lab!r}: counts {right} of {n} scenes")
        m = np.zeros((n, len(right)), dtype=bool)
        for k, v in enumerate(right):
            m[:v, k] = True
        rows[lab] = (m, float(r["decision_s_median"]))
    return rows


def register(esub: argparse._SubParsersAction) -> None:
    p = esub.add_parser("accuracy-charts", help="accuracy against touches and trial time from "
                                                "run JSONs, Wilson bands, seeds pooled")
    p.add_argument("--runs", nargs="+", required=True,
                   help="results folders with runs.json and summary.json (pooled per setting); "
                        "one folder without runs.json: the charts from its counts")
    p.add_argument("--settings", nargs="+", help="labels to draw, in order (default: all)")
    p.add_argument("--press-time", metavar="FILE|DIR", help=PRESS_TIME_HELP)
    p.add_argument("--title", default="real presses, report scenes, no stop rule")
    p.add_argument("--thresholds", type=float, nargs="+",
                   help="stop thresholds of pooled.json (default: experiment real's)")
    p.add_argument("--paired-against", nargs="+", metavar="LABEL",
                   help="paired tests in pooled.json against these settings (default: the "
                        "first)")
    p.add_argument("--per-class", type=float, metavar="THETA",
                   help="also each setting's outcome per reference class at this stop "
                        "threshold (pooled.json; the 5 most often wrong printed)")
    p.add_argument("--out", required=True,
                   help="folder for the two PNG files and pooled.json (the pooled scenes' "
                        "figures at the stop and paired tests)")

    def func(args: argparse.Namespace) -> int:
        if args.per_class is not None and not 0.0 < args.per_class <= 1.0:
            raise InputError(f"--per-class must be in (0, 1], got {args.per_class}")
        press = press_time(args.press_time)
        folders = [Path(f) for f in args.runs]
        counts = (_counts_of(folders[0]) if len(folders) == 1
                  and not (folders[0] / "runs.json").is_file() else None)
        if counts is not None:
            rows = rows_from_counts(counts)
            if args.settings:
                missing = [s for s in args.settings if s not in rows]
                if missing:
                    raise InputError(f"--settings {missing}: not in {list(rows)}")
                rows = {lab: rows[lab] for lab in args.settings}
            budget, comparisons, figures = counts["budget"], counts["comparisons"], None
        else:
            curves, budget, comparisons = load_runs(folders, args.settings)
            against = args.paired_against or [next(iter(curves))]
            unknown = [a for a in against if a not in curves]
            if unknown:
                raise InputError(f"--paired-against {unknown}: not in the runs {list(curves)}")
            rows = band_rows(curves, budget)
            figures = pooled_figures(curves, sorted(args.thresholds or DEFAULT_THRESHOLDS),
                                     against, args.per_class)
        for path in charts.touches_and_time(Path(args.out), rows, comparisons + 1,
                                            press.seconds, args.title, press.note):
            print(path)
        if figures is not None:
            figures.update(budget=budget, comparisons=comparisons,
                           press_time=asdict(press),
                           right_after={lab: {"n": len(r), "right": r.sum(axis=0).tolist(),
                                              "decision_s_median": dec}
                                        for lab, (r, dec) in rows.items()})
            print(write_json(Path(args.out) / "pooled.json", figures))
        print(f"  press time {press.seconds:.2f} s ({press.note}: {press.source})")
        for lab, (right, dec) in rows.items():
            print(f"  {lab:>14}: n = {len(right)}, +0 {right[:, 0].mean():.3f}, "
                  f"+{budget} {right[:, -1].mean():.3f}, decision {dec:.4f} s")
            for r in (figures or {}).get("per_class", {}).get("rows", {}).get(lab, [])[:5]:
                print(f"  {'':>14}  {r['class']}: wrong {r['wrong']} / {r['scenes']} "
                      f"({r['wrong_stops']} sure), {r['touches']:.2f} touches")
        return 0

    p.set_defaults(func=func)
