"""The class-disjoint protocol of ``tactex experiment real`` and ``unseen`` (``real``'s
module docstring): class folds, choosing a (setting, theta) pair on the other folds' scenes,
measuring it on the fold's report scenes, the summary, its charts and its printed table.
"""

from __future__ import annotations

import argparse
import json
import statistics
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np

from tactex_ros.core.config import SHIPPED_STOP
from tactex_ros.core.errors import InputError
from tactex_lab.analysis import charts
from tactex_lab.analysis.stats import mcnemar_exact, wilcoxon_paired, wilson
from tactex_lab.experiments.common import write_json
from tactex_lab.experiments.curves import (BeliefCurve, at_budget, at_stop, draw_scenes,
                                           paired_at_budgets, paired_at_thresholds)

DEFAULT_THRESHOLDS = (0.8, 0.9, 0.95, 0.98, 0.99, 0.995, 1.01)


def class_folds(classes: list[str], k: int, seed: int) -> list[list[str]]:
    """``classes`` shuffled (seeded) and split into ``k`` folds of near-equal size."""
    if k < 2:
        return [list(classes)]
    order = [classes[i] for i in np.random.default_rng([seed, 41]).permutation(len(classes))]
    return [sorted(order[i::k]) for i in range(k)]


def score_pairs(curves: dict[str, list[BeliefCurve]], thresholds: list[float]) -> list[dict]:
    """Every (setting, theta): accuracy at the stop, mean touches, wrong-stop rate, n."""
    rows = []
    for label, cs in curves.items():
        for th in thresholds:
            st = [at_stop(c, th) for c in cs]
            acc = float(np.mean([s[0] for s in st]))
            s = sum(x[0] for x in st)
            rows.append({"setting": label, "theta": th, "accuracy": acc,
                         "ci95": list(wilson(s, len(st))),
                         "touches": float(np.mean([s[1] for s in st])),
                         "wrong_stop": float(np.mean([s[2] and not s[0] for s in st])),
                         "n": len(st)})
    return rows


def per_class(cs: list[BeliefCurve], theta: float) -> list[dict]:
    """Per reference class of the scenes ``cs`` (their ``classes[0]``; curves without classes
    are left out), the outcome at the stop ``theta`` (``at_stop``): scenes, wrong (the stop's
    platform is not the match, sure or at the budget's end), wrong stops (sure and wrong), mean
    touches; sorted by wrong share, then scenes (most first), then class name."""
    by: dict[str, list] = {}
    for c in cs:
        if c.classes:
            by.setdefault(c.classes[0], []).append(at_stop(c, theta))
    rows = [{"class": k, "scenes": len(st), "wrong": sum(not s[0] for s in st),
             "wrong_stops": sum(s[2] and not s[0] for s in st),
             "touches": float(np.mean([s[1] for s in st]))} for k, st in by.items()]
    return sorted(rows, key=lambda r: (-r["wrong"] / r["scenes"], -r["scenes"], r["class"]))


def choose(rows: list[dict], target: float, settings: list[str] | None = None) -> dict:
    """Best (setting, theta) row: highest accuracy with mean touches <= target; ties fewer
    touches. If no row meets the target, the one with the fewest touches."""
    cand = [r for r in rows if settings is None or r["setting"] in settings]
    ok = [r for r in cand if r["touches"] <= target]
    if not ok:
        return min(cand, key=lambda r: (r["touches"], -r["accuracy"]))
    return max(ok, key=lambda r: (r["accuracy"], -r["touches"]))


def calibration(cs: list[BeliefCurve], bins: int = 10) -> dict:
    """How far the belief's top probability is from being right, over every decision of the
    curves ``cs``: expected calibration error (``bins`` equal-width bins of the confidence in
    [0, 1], weighted by decisions), mean confidence, accuracy, and the accuracy of decisions
    with confidence >= ``SHIPPED_STOP`` (``right_at_0.9``, None without such decisions)."""
    conf = np.array([x for c in cs for x in c.conf], dtype=np.float64)
    ok = np.array([x for c in cs for x in c.correct], dtype=np.float64)
    if conf.size == 0:
        return {"decisions": 0}
    idx = np.minimum((conf * bins).astype(int), bins - 1)
    ece = sum(abs(conf[idx == b].mean() - ok[idx == b].mean()) * np.sum(idx == b)
              for b in range(bins) if np.any(idx == b)) / conf.size
    hi = conf >= SHIPPED_STOP
    return {"decisions": int(conf.size), "ece": float(ece), "mean_confidence": float(conf.mean()),
            "accuracy": float(ok.mean()),
            f"right_at_{SHIPPED_STOP:g}": float(ok[hi].mean()) if hi.any() else None,
            f"share_at_{SHIPPED_STOP:g}": float(hi.mean())}


def summarise(curves: dict[str, list[BeliefCurve]], budget: int) -> dict:
    """Per setting: accuracy after k touches with intervals, decision time, believed share."""
    out = {}
    for label, cs in curves.items():
        n = len(cs)
        acc = []
        for k in range(budget + 1):
            s = sum(at_budget(c, k) for c in cs)
            lo, hi = wilson(s, n)
            acc.append({"touches": k, "accuracy": s / n, "ci95": [lo, hi]})
        dec = [d for c in cs for d in c.decision_s]
        touched = sum(c.touched for c in cs)
        out[label] = {"scenes": n, "accuracy_vs_touches": acc,
                      "decision_s_median": statistics.median(dec) if dec else None,
                      "believed_share": (sum(c.believed for c in cs) / touched
                                         if touched else None),
                      "errors": sum(1 for c in cs if c.error),
                      "calibration": calibration(cs)}
    return out


def protocol(classes: list[str], labels: list[str], runner, args: argparse.Namespace) -> dict:
    """The class-disjoint protocol (module docstring) over ``classes``: ``runner(scenes, tag)``
    gives {label: [belief curve per scene]} for a list of scenes; ``args`` carries folds,
    scenes, comparisons, seed, budget, thresholds, target_touches, report_only,
    paired_against. Returns the summary (with ``report_curves``)."""
    thresholds = sorted(args.thresholds or DEFAULT_THRESHOLDS)
    folds = class_folds(classes, args.folds, args.seed)
    report_only = bool(getattr(args, "report_only", False))
    against = list(getattr(args, "paired_against", None) or [labels[0]])
    unknown = [a for a in against if a not in labels]
    if unknown:
        raise InputError(f"--paired-against {unknown}: not a --setting label; one of {labels}")
    report_curves: dict[str, list[BeliefCurve]] = {lab: [] for lab in labels}
    fold_info = []
    for k, fold in enumerate(folds):
        if args.folds >= 2 and not report_only:
            rest = sorted(set(classes) - set(fold))
            choose_curves = runner(draw_scenes(rest, args.scenes, args.comparisons,
                                               args.seed + 1000 * (k + 1)), f"choose{k}-")
            rows = score_pairs(choose_curves, thresholds)
            best = choose(rows, args.target_touches)
            per_setting = {lab: choose(rows, args.target_touches, [lab]) for lab in labels}
        else:
            rest, rows, best, per_setting = [], [], None, {}
        rep = runner(draw_scenes(fold, args.scenes, args.comparisons, args.seed + 100000 * k),
                     f"report{k}-")
        for lab, cs in rep.items():
            report_curves[lab].extend(cs)
        fold_info.append({"fold": k, "report_classes": fold, "choose_classes": rest,
                          "chosen": best, "chosen_per_setting": per_setting,
                          "choose_rows": rows, "report_rows": score_pairs(rep, thresholds),
                          "report_chosen": _report(rep, best, per_setting)})
    budgets = tuple(k for k in (0, 1, 3, 5, 10) if k <= args.budget)
    summary = {"comparisons": args.comparisons, "budget": args.budget,
               "folds": fold_info,
               "per_setting": summarise(report_curves, args.budget),
               "report_rows": score_pairs(report_curves, thresholds),
               "paired_at_budgets": paired_at_budgets(report_curves, labels[0], budgets),
               "paired": {ref: {"budgets": paired_at_budgets(report_curves, ref, budgets),
                                "thresholds": paired_at_thresholds(report_curves, ref,
                                                                   thresholds)}
                          for ref in against},
               "report_curves": report_curves}
    if args.folds >= 2 and not report_only:
        summary["held_out"] = _pool_chosen(fold_info, labels)
    return summary


def write_outputs(out: Path, summary: dict, labels: list[str], args: argparse.Namespace
                  ) -> None:
    """runs.json (the report curves), summary.json, the charts and the printed table."""
    curves = summary.pop("report_curves")
    write_json(out / "runs.json", {lab: [c.to_json() for c in cs] for lab, cs in curves.items()})
    press = PressTime(**args.press) if getattr(args, "press", None) else press_time()
    summary["press_time"] = asdict(press)
    write_json(out / "summary.json", summary)
    _charts(out, summary, curves, labels, args.budget, press)
    _print(summary, labels, args)


def _report(curves: dict[str, list[BeliefCurve]], best: dict | None,
            per_setting: dict[str, dict]) -> dict:
    """Report-scene outcomes (per scene) of each setting at its chosen theta."""
    out = {}
    for lab, cs in curves.items():
        th = per_setting.get(lab, {}).get("theta", 1.01)
        out[lab] = {"theta": th, "outcomes": [at_stop(c, th) for c in cs]}
    if best is not None:
        out["__chosen__"] = {"setting": best["setting"], "theta": best["theta"],
                             "outcomes": [at_stop(c, best["theta"])
                                          for c in curves[best["setting"]]]}
    return out


def _pool_chosen(fold_info: list[dict], labels: list[str]) -> dict:
    """Pool the report scenes of every fold: the chosen pair and each setting at its theta."""
    def pooled(key: str) -> dict:
        oc = [o for f in fold_info for o in f["report_chosen"][key]["outcomes"]]
        s = sum(o[0] for o in oc)
        return {"accuracy": s / len(oc), "ci95": list(wilson(s, len(oc))), "n": len(oc),
                "touches_mean": float(np.mean([o[1] for o in oc])),
                "wrong_stop": float(np.mean([o[2] and not o[0] for o in oc])),
                "correct": [bool(o[0]) for o in oc], "touches": [int(o[1]) for o in oc]}
    out = {"chosen": pooled("__chosen__"),
           "chosen_pairs": [(f["chosen"]["setting"], f["chosen"]["theta"]) for f in fold_info],
           "settings": {lab: pooled(lab) for lab in labels}}
    base = out["chosen"]
    for lab in labels:
        st = out["settings"][lab]
        st["mcnemar_vs_chosen"] = mcnemar_exact(base["correct"], st["correct"])
        st["wilcoxon_touches_vs_chosen"] = wilcoxon_paired(base["touches"], st["touches"])
    return out


def band_rows(curves: dict[str, list[BeliefCurve]], budget: int
              ) -> dict[str, tuple[np.ndarray, float]]:
    """{label: (right after k = 0..budget touches (scenes, budget + 1), median decision time
    [s] over every decision)}: the input of ``charts.touches_and_time``."""
    rows = {}
    for lab, cs in curves.items():
        dec = [d for c in cs for d in c.decision_s]
        rows[lab] = (np.array([[at_budget(c, k) for k in range(budget + 1)] for c in cs],
                              dtype=bool).reshape(-1, budget + 1),
                     statistics.median(dec) if dec else 0.0)
    return rows


#: Where the time axis takes its seconds per press when no --press-time is given: the press
#: benchmark's result on the lab scene as shipped (`tactex bench press --scene
#: config/scene.yaml --worlds 1000 --json docs/results/press_bench/scene.json`)
DEFAULT_PRESS_TIME = Path(__file__).resolve().parents[2] / "docs/results/press_bench/scene.json"

THRESHOLD_HELP = "stop thresholds on the leading belief, 0..1.01 (above 1: never stops)"
PRESS_TIME_HELP = ("where the time axis's seconds per press come from: a `tactex bench press "
                   "--json` file (its press_s_median) or a trial record, a session or a folder "
                   "of them (the median of every recorded press time); default: "
                   "the benchmark on the lab scene, docs/results/press_bench/scene.json")


@dataclass(frozen=True)
class PressTime:
    """Seconds per press for a time axis [s], measured, and where they were measured
    (``source``: the file or folder; ``note``: a short label for the axis)."""

    seconds: float
    source: str
    note: str


def press_time(source: str | Path | None = None) -> PressTime:
    """The measured press time of ``source`` (``PRESS_TIME_HELP``; None: the default bench
    file). InputError (exit status 2) naming the source when it holds no press time or one
    outside 0.1..3600 s."""
    from tactex_ros.trial.record import press_durations, read_record
    p = Path(source) if source is not None else DEFAULT_PRESS_TIME
    if p.is_file():
        try:
            d = json.loads(p.read_text())
            s = float(d["press_s_median"])
        except (OSError, ValueError, TypeError, KeyError) as exc:
            raise InputError(f"--press-time {str(p)!r}: not a `tactex bench press --json` "
                             f"result with press_s_median ({exc!r})") from None
        note = f"bench press, {Path(str(d.get('scene', '?'))).name}"
    elif p.is_dir():
        folders = sorted({f.parent for f in p.rglob("touches.jsonl")})
        times = [t for f in folders for t in press_durations(read_record(f, False)["touches"])]
        if not times:
            raise InputError(f"--press-time {str(p)!r}: no recorded press (no touches.jsonl "
                             "with request and capture times below it)")
        s = statistics.median(times)
        note = f"{len(times)} recorded presses"
    else:
        raise InputError(f"--press-time {str(p)!r}: not found ({PRESS_TIME_HELP})")
    if not 0.1 <= s <= 3600.0:
        raise InputError(f"--press-time {str(p)!r}: {s:g} s a press, outside 0.1..3600")
    shown = "docs/results/press_bench/scene.json" if source is None else str(p)
    return PressTime(s, shown, note)


def check_options(args: argparse.Namespace) -> None:
    """Before any work: ``--thresholds`` are stop thresholds on the leading belief, 0..1 (up
    to 1.01: above 1 never stops, the whole budget, as the default sweep's last);
    ``--press-time`` a measured press time (``press_time``, kept as ``args.press``, a dict).
    InputError (exit status 2) naming the option,
    the value and the range otherwise (NaN included)."""
    for th in getattr(args, "thresholds", None) or []:
        if not 0.0 <= th <= 1.01:
            raise InputError(f"--thresholds {th:g}: outside 0..1.01 ({THRESHOLD_HELP})")
    if hasattr(args, "press_time"):           # kept as a dict: config.json records it
        args.press = asdict(press_time(args.press_time))


def _charts(out: Path, summary: dict, curves: dict[str, list[BeliefCurve]], labels: list[str],
            budget: int, press: PressTime) -> None:
    """accuracy_vs_touches.png and accuracy_vs_time.png (``charts.touches_and_time``: Wilson
    bands, scenes per line; ``press``: the measured press time) from the report ``curves``;
    pareto.png (the stop-threshold sweep)."""
    rows = band_rows({lab: curves[lab] for lab in labels}, budget)
    charts.touches_and_time(out, rows, summary["comparisons"] + 1, press.seconds,
                            f"real presses, report scenes, no stop rule (budget {budget})",
                            press.note)
    charts.stop_sweep(out / "pareto.png", summary["report_rows"], labels)


def _print(summary: dict, labels: list[str], args) -> None:
    print(f"real presses: {summary.get('source', summary.get('test'))}, {args.comparisons} "
          f"comparisons, budget {args.budget}")
    for lab in labels:
        p = summary["per_setting"][lab]
        acc = p["accuracy_vs_touches"]
        ks = [k for k in (0, 1, 3, 5, 10, args.budget) if k <= args.budget]
        print(f"  {lab:>14}: " + "  ".join(f"+{k}: {acc[k]['accuracy']:.3f}" for k in ks) +
              f"  decision {p['decision_s_median']:.4f} s  believed-share "
              f"{p['believed_share'] if p['believed_share'] is None else round(p['believed_share'], 2)}")
    if "held_out" in summary:
        h = summary["held_out"]["chosen"]
        print(f"  held-out classes, chosen per fold {summary['held_out']['chosen_pairs']}: "
              f"accuracy {h['accuracy']:.3f} [{h['ci95'][0]:.3f}, {h['ci95'][1]:.3f}] "
              f"n={h['n']}, touches after baseline {h['touches_mean']:.2f}, wrong stops "
              f"{h['wrong_stop']:.3f}")
        for lab, s in summary["held_out"]["settings"].items():
            print(f"    {lab:>14} at its theta: {s['accuracy']:.3f} "
                  f"[{s['ci95'][0]:.3f}, {s['ci95'][1]:.3f}] touches {s['touches_mean']:.2f}"
                  f"  McNemar vs chosen p={s['mcnemar_vs_chosen']['p']:.3g}")
    if getattr(args, "report_only", False):
        for r in summary["report_rows"]:
            print(f"    {r['setting']:>14} at theta {r['theta']:g}: {r['accuracy']:.3f} "
                  f"[{r['ci95'][0]:.3f}, {r['ci95'][1]:.3f}] touches {r['touches']:.2f} "
                  f"wrong stops {r['wrong_stop']:.3f}")
    for ref, pr in summary["paired"].items():
        for lab, row in pr["thresholds"].items():
            print(f"    {lab:>14} vs {ref}: McNemar p at theta " +
                  "  ".join(f"{th}: {v['p']:.3g}" for th, v in row.items()))
