"""``tactex experiment accuracy-charts``: accuracy against touches and against trial time,
redrawn from the run JSONs of ``experiment real`` / ``experiment unseen`` (no trial is re-run).

Each ``--runs`` folder holds ``runs.json`` (per setting, the belief curve of every report scene)
and ``summary.json`` (budget, comparisons). Folders of the same protocol with other seeds (other
folds and scenes) are pooled per setting: a setting's line counts the scenes of every folder
that ran it, and the legend says how many. Each line has its 95 % Wilson band
(``charts.touches_and_time``). The time axis counts ``--press-s`` seconds per press (the
baseline's presses included) and the setting's median decision time per decision: give it the
press time of the robot the figure speaks for (``tactex graph summary RECORD``'s
``press_s_median``) and say where it comes from with ``--press-note``.
"""

from __future__ import annotations

import argparse
import json
import statistics
from pathlib import Path

import numpy as np

from tactex_ros.core.errors import InputError
from tactex_lab.analysis import charts
from tactex_lab.experiments.curves import at_budget


def load_runs(folders: list[str | Path], settings: list[str] | None = None
              ) -> tuple[dict[str, tuple[np.ndarray, float]], int, int]:
    """Pool the report scenes of ``folders`` per setting (in first-seen order, or
    ``settings``): ({label: (right after k touches (scenes, budget + 1), median decision time
    [s] over every decision)}, budget, comparisons). The folders must share budget and
    comparisons."""
    pooled: dict[str, list[dict]] = {}
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
            pooled.setdefault(lab, []).extend(cs)
    if budget is None:
        raise InputError("--runs: no folder given")
    labels = settings or list(pooled)
    missing = [s for s in labels if s not in pooled]
    if missing:
        raise InputError(f"--settings {missing}: not in the runs; they hold {list(pooled)}")
    rows = {}
    for lab in labels:
        dec = [d for c in pooled[lab] for d in c["decision_s"]]
        rows[lab] = (np.array([[at_budget(c, k) for k in range(budget + 1)]
                               for c in pooled[lab]], dtype=bool).reshape(-1, budget + 1),
                     statistics.median(dec) if dec else 0.0)
    return rows, budget, comparisons


def register(esub: argparse._SubParsersAction) -> None:
    p = esub.add_parser("accuracy-charts", help="accuracy against touches and trial time from "
                                                "run JSONs, Wilson bands, seeds pooled")
    p.add_argument("--runs", nargs="+", required=True,
                   help="results folders with runs.json and summary.json (pooled per setting)")
    p.add_argument("--settings", nargs="+", help="labels to draw, in order (default: all)")
    p.add_argument("--press-s", type=float, required=True,
                   help="seconds per press (tactex graph summary's press_s_median)")
    p.add_argument("--press-note", default="",
                   help="where the press time comes from (shown on the time axis)")
    p.add_argument("--title", default="real presses, report scenes, no stop rule")
    p.add_argument("--out", required=True, help="folder for the two PNG files")

    def func(args: argparse.Namespace) -> int:
        if not args.press_s > 0:
            raise InputError(f"--press-s must be > 0, got {args.press_s}")
        rows, budget, comparisons = load_runs(args.runs, args.settings)
        for path in charts.touches_and_time(Path(args.out), rows, comparisons + 1,
                                            args.press_s, args.title, args.press_note):
            print(path)
        for lab, (right, dec) in rows.items():
            print(f"  {lab:>14}: n = {len(right)}, +0 {right[:, 0].mean():.3f}, "
                  f"+{budget} {right[:, -1].mean():.3f}, decision {dec:.4f} s")
        return 0

    p.set_defaults(func=func)
