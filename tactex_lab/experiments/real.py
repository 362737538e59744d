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
import statistics
from pathlib import Path
from typing import Any

import numpy as np

from tactex_lab.analysis import charts
import time
from dataclasses import dataclass
from functools import partial

from tactex_ros.core import calibration as belief_calibration
from tactex_ros.core import representation
from tactex_ros.core.config import SHIPPED_STOP, TrialConfig, preset
from tactex_ros.core.engine import confident
from tactex_ros.core.errors import InputError
from tactex_ros.core.touch import Touch
from tactex_lab.experiments.common import budget_index, parse_set, results_dir, write_json
from tactex_lab.experiments.runner import Backend, TrialJob, add_runner_args, backend_of, run_jobs
from tactex_lab.analysis.stats import mcnemar_exact, spearman_interval, wilcoxon_paired, wilson

DEFAULT_SETTINGS = ("default=default", "random=default:trial.strategy=random",
                    "variance=default:trial.strategy=variance")
DEFAULT_THRESHOLDS = (0.8, 0.9, 0.95, 0.98, 0.99, 0.995, 1.01)


def parse_setting(text: str) -> tuple[str, str, str | None, dict[str, Any]]:
    """``label=preset[:PATH=val,PATH=val]`` -> (label, preset, strategy or None, overrides).

    Overrides are dotted schema paths (``tactex_ros.core.config.overrides``):
    ``learner.<field>`` and ``trial.strategy``."""
    from tactex_ros.core.config import PRESETS
    label, sep, rest = text.partition("=")
    if not sep or not label:
        raise InputError(f"--setting {text!r}: expected label=preset[:PATH=value,...]")
    pre, _, kv = rest.partition(":")
    if pre not in PRESETS:
        raise InputError(f"--setting {text!r}: unknown preset {pre!r}; one of "
                         f"{', '.join(PRESETS)}")
    over = parse_set([it for it in kv.split(",") if it], f"--setting {text!r}:", ("strategy",))
    return label, pre, over.get("trial", {}).get("strategy"), over.get("learner", {})


def class_folds(classes: list[str], k: int, seed: int) -> list[list[str]]:
    """``classes`` shuffled (seeded) and split into ``k`` folds of near-equal size."""
    if k < 2:
        return [list(classes)]
    order = [classes[i] for i in np.random.default_rng([seed, 41]).permutation(len(classes))]
    return [sorted(order[i::k]) for i in range(k)]


def draw_scenes(classes: list[str], n: int, comparisons: int, seed0: int) -> list[list[str]]:
    """``n`` scenes [reference, comparisons...] from ``classes`` (seeds seed0 ..)."""
    from tactex_ros.sources import assign_platforms
    if len(classes) < comparisons:
        raise InputError(f"{len(classes)} classes cannot fill {comparisons} comparisons")
    return [assign_platforms(classes, comparisons, None, None, seed0 + i)[0] for i in range(n)]


def curve(res: dict) -> dict:
    """A runner result -> the belief after every decision (touches after the baseline)."""
    recs = res["rounds"] + ([res["final"]] if res.get("final") else [])
    base = len(res["classes"])
    truth = res["truth_index"]
    out = {"extra": [], "correct": [], "conf": [], "decision_s": [], "believed": 0,
           "touched": 0, "error": res.get("error")}
    prev = None
    for r in recs:
        probs = np.asarray(r["probs"])
        out["extra"].append(int(sum(r["touches"]) + r.get("reference_touches", 1) - base))
        out["correct"].append(bool(int(np.argmax(probs)) + 1 == truth))
        out["conf"].append(float(probs.max()))
        out["decision_s"].append(float(r["decision_s"]))
        if prev is not None and prev["platform"] not in (None, "reference", 0):
            out["touched"] += 1
            chosen = prev["platform"]
            idx = int(chosen[1:]) if isinstance(chosen, str) else int(chosen)
            out["believed"] += int(idx == int(np.argmax(prev["probs"])) + 1)
        prev = r
    return out


def at_budget(c: dict, k: int) -> bool:
    """Correct after ``k`` touches after the baseline (``common.budget_index``)."""
    idx = budget_index(c["extra"], k)
    return bool(idx >= 0 and c["correct"][idx])


def at_stop(c: dict, theta: float) -> tuple[bool, int, bool]:
    """(correct, touches after the baseline, stopped confident) under stop threshold theta."""
    for i, conf in enumerate(c["conf"]):
        if confident(conf, theta):
            return c["correct"][i], c["extra"][i], True
    return c["correct"][-1], c["extra"][-1], False


def score_pairs(curves: dict[str, list[dict]], thresholds: list[float]) -> list[dict]:
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


def choose(rows: list[dict], target: float, settings: list[str] | None = None) -> dict:
    """Best (setting, theta) row: highest accuracy with mean touches <= target; ties fewer
    touches. If no row meets the target, the one with the fewest touches."""
    cand = [r for r in rows if settings is None or r["setting"] in settings]
    ok = [r for r in cand if r["touches"] <= target]
    if not ok:
        return min(cand, key=lambda r: (r["touches"], -r["accuracy"]))
    return max(ok, key=lambda r: (r["accuracy"], -r["touches"]))


def belief_curves(scenes: list[list[str]], settings: list[tuple], source: str, seed: int,
                  budget: int, tag: str, backend: Backend = Backend(), threads: int = 1,
                  quiet: bool = False) -> dict[str, list[dict]]:
    """Run every scene (``[reference, comparisons...]`` classes) with every setting of
    ``parse_setting`` on ``source``, no stop rule, ``budget`` touches after the baseline; scene
    i has seed ``seed + i`` for every setting (paired). Returns {label: [curve per scene]}
    (see ``curve``, plus the scene's ``classes``)."""
    from tactex_ros.core.engine import trial_preset
    jobs = []
    for i, classes in enumerate(scenes):
        for label, pre, strategy, over in settings:
            st = strategy or trial_preset(pre).strategy
            jobs.append(TrialJob(source=source, seed=seed + i, strategy=st,
                                 rounds=budget, stop_confidence=0.0, preset=pre,
                                 overrides=over, platform_classes=classes,
                                 comparisons=len(classes) - 1, catch_errors=True,
                                 no_contact_reference=False,
                                 trial_id=f"{tag}{i}", tags={"setting": label, "set": tag}))
    res = run_jobs(jobs, backend, threads=threads, description=f"{tag} scenes x settings",
                   quiet=quiet)
    out: dict[str, list[dict]] = {s[0]: [] for s in settings}
    for r in res:
        c = curve(r)
        c["classes"] = r["classes"]
        out[r["job"]["tags"]["setting"]].append(c)
    return out


def _run(scenes, settings, args, tag) -> dict[str, list[dict]]:
    return belief_curves(scenes, settings, args.source, args.seed, args.budget, tag,
                         backend_of(args), args.threads, args.quiet)


def calibration(cs: list[dict], bins: int = 10) -> dict:
    """How far the belief's top probability is from being right, over every decision of the
    curves ``cs``: expected calibration error (``bins`` equal-width bins of the confidence in
    [0, 1], weighted by decisions), mean confidence, accuracy, and the accuracy of decisions
    with confidence >= 0.9 (``right_at_0.9``, None without such decisions)."""
    conf = np.array([x for c in cs for x in c["conf"]], dtype=np.float64)
    ok = np.array([x for c in cs for x in c["correct"]], dtype=np.float64)
    if conf.size == 0:
        return {"decisions": 0}
    idx = np.minimum((conf * bins).astype(int), bins - 1)
    ece = sum(abs(conf[idx == b].mean() - ok[idx == b].mean()) * np.sum(idx == b)
              for b in range(bins) if np.any(idx == b)) / conf.size
    hi = conf >= SHIPPED_STOP
    return {"decisions": int(conf.size), "ece": float(ece), "mean_confidence": float(conf.mean()),
            "accuracy": float(ok.mean()),
            "right_at_0.9": float(ok[hi].mean()) if hi.any() else None,
            "share_at_0.9": float(hi.mean())}


def summarise(curves: dict[str, list[dict]], budget: int) -> dict:
    """Per setting: accuracy after k touches with intervals, decision time, believed share."""
    out = {}
    for label, cs in curves.items():
        n = len(cs)
        acc = []
        for k in range(budget + 1):
            s = sum(at_budget(c, k) for c in cs)
            lo, hi = wilson(s, n)
            acc.append({"touches": k, "accuracy": s / n, "ci95": [lo, hi]})
        dec = [d for c in cs for d in c["decision_s"]]
        touched = sum(c["touched"] for c in cs)
        out[label] = {"scenes": n, "accuracy_vs_touches": acc,
                      "decision_s_median": statistics.median(dec) if dec else None,
                      "believed_share": (sum(c["believed"] for c in cs) / touched
                                         if touched else None),
                      "errors": sum(1 for c in cs if c["error"]),
                      "calibration": calibration(cs)}
    return out


def _paired(curves: dict[str, list[dict]], reference: str, points, outcome) -> dict:
    """Every setting against ``reference`` on the same scenes at each point (a budget or a
    threshold): ``outcome(curve, point)`` gives (correct, touches after the baseline or None).
    {setting: {str(point): {"reference", "setting" (accuracies), "p" (exact McNemar)[,
    "touches_p" (Wilcoxon on touches, where outcomes carry touches)]}}}."""
    out = {}
    for lab, cs in curves.items():
        if lab == reference:
            continue
        row = {}
        for pt in points:
            a = [outcome(c, pt) for c in curves[reference]]
            b = [outcome(c, pt) for c in cs]
            ok_a, ok_b = [x[0] for x in a], [x[0] for x in b]
            row[str(pt)] = {"reference": float(np.mean(ok_a)), "setting": float(np.mean(ok_b)),
                            "p": mcnemar_exact(ok_a, ok_b)["p"]}
            if a and a[0][1] is not None:
                row[str(pt)]["touches_p"] = wilcoxon_paired([x[1] for x in a],
                                                            [x[1] for x in b])["p"]
        out[lab] = row
    return out


def paired_at_budgets(curves: dict[str, list[dict]], reference: str,
                      budgets: tuple[int, ...] = (0, 1, 3, 5, 10)) -> dict:
    """Exact McNemar of every setting against ``reference`` at fixed touch budgets (no stop
    rule), on the same scenes: {setting: {str(k): {"reference", "setting", "p"}}}."""
    return _paired(curves, reference, budgets, lambda c, k: (at_budget(c, k), None))


def paired_at_thresholds(curves: dict[str, list[dict]], reference: str,
                         thresholds: list[float]) -> dict:
    """Every setting against ``reference`` under each stop threshold, on the same scenes:
    {setting: {str(theta): {"reference", "setting" (accuracies), "p" (exact McNemar),
    "touches_p" (Wilcoxon on touches after the baseline)}}}."""
    return _paired(curves, reference, thresholds, at_stop)


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
    report_curves: dict[str, list[dict]] = {lab: [] for lab in labels}
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
    write_json(out / "runs.json", summary.pop("report_curves"))
    write_json(out / "summary.json", summary)
    _charts(out, summary, labels, args.budget, getattr(args, "press_s", PRESS_S))
    _print(summary, labels, args)


def _report(curves: dict[str, list[dict]], best: dict | None,
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


#: Seconds per touch for the time axis when no --press-s is given: a press of the simulated
#: graph (impedance-control press, 10 mm/s descent) takes about 3 s (README, "make demo").
PRESS_S = 3.0


def _charts(out: Path, summary: dict, labels: list[str], budget: int,
            press_s: float = PRESS_S) -> None:
    """accuracy_vs_touches.png and accuracy_vs_time.png (trial time after the baseline:
    touches x (``press_s`` + the setting's median decision time)), 95 % Wilson bands and the
    number of scenes per line; pareto.png (the stop-threshold sweep)."""
    for axis in ("touches", "time"):
        series = {}
        for lab in labels:
            p = summary["per_setting"][lab]
            acc = p["accuracy_vs_touches"]
            step = 1.0 if axis == "touches" else press_s + (p["decision_s_median"] or 0.0)
            series[lab] = {"x": [a["touches"] * step for a in acc],
                           "accuracy": [a["accuracy"] for a in acc],
                           "lo": [a["ci95"][0] for a in acc], "hi": [a["ci95"][1] for a in acc],
                           "n": p["scenes"]}
        xlabel = ("touches after the baseline" if axis == "touches" else
                  f"trial time after the baseline [s] ({press_s:g} s per press + decision)")
        charts.accuracy_bands(out / f"accuracy_vs_{axis}.png", series, xlabel,
                              f"real presses, report scenes, no stop rule (budget {budget})")
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
    for lab in labels:
        both = {side: curves[side][lab] for side in curves}
        row: dict[str, Any] = {}
        for side, cs in both.items():
            row[side] = {"accuracy_at": {str(k): float(np.mean([at_budget(c, k) for c in cs]))
                                         for k in points},
                         "accuracy_at_stop_0.9": float(np.mean([at_stop(c, SHIPPED_STOP)[0]
                                                                for c in cs])),
                         "touches_at_stop_0.9": float(np.mean([at_stop(c, SHIPPED_STOP)[1]
                                                               for c in cs])),
                         "correct_at_budget": [at_budget(c, budget) for c in cs],
                         "failed_trials": sum(1 for c in cs if c["error"])}
        row["paired_at_budgets"] = paired_at_budgets(both, "recorded",
                                                     tuple(points))["one_session"]
        row["paired_at_stop_0.9"] = paired_at_thresholds(both, "recorded",
                                                         [SHIPPED_STOP])["one_session"]
        res["settings"][lab] = row
    write_json(d / "summary.json", res)
    for lab, row in res["settings"].items():
        r, o = row["recorded"], row["one_session"]
        pb = row["paired_at_budgets"][str(budget)]["p"]
        print(f"{lab:>16}: +{budget} recorded {r['accuracy_at'][str(budget)]:.3f} one-session "
              f"{o['accuracy_at'][str(budget)]:.3f} (McNemar p {pb:.3g}); stop 0.9 "
              f"{r['accuracy_at_stop_0.9']:.3f} / {o['accuracy_at_stop_0.9']:.3f} with "
              f"{r['touches_at_stop_0.9']:.2f} / {o['touches_at_stop_0.9']:.2f} touches")
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
    register_unseen(esub)
    p = esub.add_parser("real", help="accuracy against touches on real presses "
                                     "(class-disjoint folds)")
    p.add_argument("--source", required=True, help="replay:DIR of recorded presses")
    p.add_argument("--comparisons", type=int, default=4)
    p.add_argument("--scenes", type=int, default=40, help="scenes per fold and set")
    p.add_argument("--budget", type=int, default=15, help="touches after the baseline")
    p.add_argument("--folds", type=int, default=3, help="class folds (1 = no choosing)")
    p.add_argument("--setting", action="append",
                   help="label=preset[:PATH=value,...] (repeat); default: "
                        + " ".join(DEFAULT_SETTINGS))
    p.add_argument("--thresholds", type=float, nargs="+")
    p.add_argument("--target-touches", type=float, default=5.0,
                   help="choose the most accurate (setting, theta) with at most this many "
                        "touches after the baseline on average")
    p.add_argument("--report-only", action="store_true",
                   help="no choose scenes: measure every setting on the report scenes of each "
                        "fold at every threshold (no choosing)")
    p.add_argument("--paired-against", nargs="+", metavar="LABEL",
                   help="paired tests of every setting against these settings (default: the "
                        "first --setting)")
    p.add_argument("--press-s", type=float, default=PRESS_S,
                   help="seconds per touch for the time axis of accuracy_vs_time.png")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--out")
    add_runner_args(p)

    def func(args: argparse.Namespace) -> int:
        for name in ("comparisons", "scenes", "budget", "folds"):
            if getattr(args, name) < (2 if name == "comparisons" else 1):
                raise InputError(f"--{name} too small: {getattr(args, name)}")
        run(args)
        return 0

    p.set_defaults(func=func)


def run_ranking(real_dir: str, settings: list[str] | tuple[str, ...], scenes: int,
                comparisons: int, budget: int, seed: int, workers: int,
                sim_spec: str = "sim:recorded", real_one_session: bool = False
                ) -> dict[str, Any]:
    """The ranking part of the sim-to-real report (``tactex sim compare``,
    ``analysis/sim_vs_real.py``): every setting on the same ``scenes`` simulated and real
    scenes (1 + ``comparisons`` distinct classes: catalogue fabrics / the folder's classes),
    through this module's scene draw, runner and belief curves.

    Per setting and side: accuracy after ``budget`` touches after the baseline (Wilson
    interval), accuracy averaged over 0..budget touches, accuracy at the default's stop rule
    (belief 0.9) and the touches it took. Then Spearman rho of the two sides' rankings with
    a bootstrap interval, and the gaps real - sim. ``sim_spec``: the simulated source
    (``sim[:difficulty][:recorded]``; recorded sessions as the real folder's);
    ``real_one_session``: the real presses moved onto one background per trial
    (``replay:DIR:one-session``, to rank against the live simulator ``sim``)."""
    from tactex_ros.sources import open_source
    if not (sim_spec == "sim" or sim_spec.startswith("sim:")):
        raise InputError(f"--sim-source {sim_spec!r}: use sim[:difficulty][:recorded]")
    open_source(sim_spec)            # a bad spec is refused before any work
    if scenes < 2:
        raise InputError(f"--scenes must be >= 2 for a ranking, got {scenes}")
    if budget < 0:
        raise InputError(f"--budget must be >= 0, got {budget}")
    parsed = [parse_setting(s) for s in settings]
    labels = [p[0] for p in parsed]
    if len(labels) < 2 or len(set(labels)) != len(labels):
        raise InputError(f"the ranking needs >= 2 settings with unique labels, got {labels}")
    theta = SHIPPED_STOP
    out: dict[str, Any] = {"settings": {}, "scenes": scenes, "comparisons": comparisons,
                           "budget": budget, "stop_theta": theta, "seed": seed,
                           "setting_specs": list(settings), "sim_source": sim_spec,
                           "real_one_session": real_one_session}
    real_spec = f"replay:{real_dir}" + (":one-session" if real_one_session else "")
    scores: dict[str, dict[str, np.ndarray]] = {}
    for side, spec in (("sim", sim_spec), ("real", real_spec)):
        classes = sorted(open_source(spec).classes)
        curves = belief_curves(draw_scenes(classes, scenes, comparisons, seed),
                               parsed, spec, seed, budget, f"{side}-",
                               Backend("joblib", workers))
        errors = sum(1 for cs in curves.values() for c in cs if c["error"])
        at_b = np.array([[at_budget(c, budget) for c in curves[lab]] for lab in labels], float)
        mean_b = np.array([[np.mean([at_budget(c, k) for k in range(budget + 1)])
                            for c in curves[lab]] for lab in labels], float)
        stops = [[at_stop(c, theta) for c in curves[lab]] for lab in labels]
        scores[side] = {"at_budget": at_b, "mean_over_budgets": mean_b}
        for i, lab in enumerate(labels):
            k = int(at_b[i].sum())
            out["settings"].setdefault(lab, {})[side] = {
                "accuracy": k / scenes, "ci95": list(wilson(k, scenes)),
                "accuracy_mean_over_budgets": float(mean_b[i].mean()),
                "accuracy_at_stop": float(np.mean([st[0] for st in stops[i]])),
                "touches_at_stop": float(np.mean([st[1] for st in stops[i]]))}
        out[f"{side}_failed_trials"] = errors
    for lab in labels:
        v = out["settings"][lab]
        v["gap_real_minus_sim"] = v["real"]["accuracy"] - v["sim"]["accuracy"]
    gaps = [out["settings"][lab]["gap_real_minus_sim"] for lab in labels]
    out["accuracy_spearman"] = spearman_interval(scores["sim"]["at_budget"],
                                                 scores["real"]["at_budget"], seed=seed)
    out["mean_over_budgets_spearman"] = spearman_interval(
        scores["sim"]["mean_over_budgets"], scores["real"]["mean_over_budgets"], seed=seed)
    out["mean_gap_real_minus_sim"] = float(np.mean(gaps))
    out["mean_abs_gap"] = float(np.mean(np.abs(gaps)))
    return out


# ---------------------------------------------------------------------- experiment unseen
"""``tactex experiment unseen``: prepared representations on classes no part of the pipeline saw,
class-disjoint in both directions (issue 23, docs/unseen_materials.md).

Two libraries of recorded presses, A and B (``../shared``'s octopi-dev and octopi-objects). For
each direction (test on A with B as the lab's library, and the reverse) every setting:

- prepares on the *library* only: the representation (``core/representation.py``) and the
  belief's temperature calibrated on the library with classes left out
  (``core/calibration.py``), exactly what ``tactex prepare`` does;
- runs the trials of the test side through the trial engine (``core/engine.py``, infogain, no
  stop rule, ``--budget`` touches after the baseline), each press given by its descriptor
  computed once (``build_cache``; the draw of presses is ``ReplayTrial``'s, the scenes are
  ``experiment real``'s, so the scenes and presses are the same as ``tactex experiment real
  --source replay:A`` with the same seed);
- is scored with ``experiment real``'s protocol: 3 class folds of the test side; on each fold's
  *choose* scenes (other folds' classes) the best (setting, theta) with at most
  ``--target-touches`` touches is chosen and measured on the fold's *report* scenes; Wilson
  intervals, exact McNemar and Wilcoxon against the first setting (today's default) on the
  pooled report scenes.

Per-press features (``FEATURES``) tried on top of the shipped 106-number descriptor: several
frames of the press (the strongest + 3 more in contact; the frame at half the strongest contact,
the contact growing), and 2 x 2 regions of the strongest frame (mean and spread over regions).

The cache holds descriptors of ``../shared`` presses: write it under /tmp, never into the
repository.
"""

#: Per-press features: cache arrays -> (n, D') vectors.
FEATURES = {
    "frame": lambda c: c["f0"],
    "frames4": lambda c: np.mean(np.concatenate([c["f0"][:, None], c["extra"]], axis=1), 1),
    "growth": lambda c: np.concatenate([c["f0"], c["early"] - c["f0"]], axis=1),
    "regions": lambda c: np.concatenate([c["reg"].mean(1), c["reg"].std(1)], axis=1),
    "frame_regstd": lambda c: np.concatenate([c["f0"], c["reg"].std(1)], axis=1),
}


def build_cache(root: str | Path, out: str | Path) -> Path:
    """Describe every press of the replay folder ``root`` once: the strongest frame (``f0``),
    the 3 other in-contact frames of the touch (``extra``), the first frame with half the
    strongest contact score (``early``), the 2 x 2 regions of the strongest frame's contact
    difference (``reg``); with the class and file of each press. Written as ``out`` (.npz)."""
    from tactex_ros.core import texture
    from tactex_ros.core.contact import strongest_contact
    from tactex_ros.sources.replay import ReplaySource, read_video
    src = ReplaySource(root)
    rows: dict[str, list] = {k: [] for k in ("cls", "path", "f0", "extra", "early", "reg")}
    for cls in src.classes:
        for path in src.presses(cls):
            arr = read_video(path)
            touch = src.touch(path)
            nc = touch.no_contact
            idx, scores = strongest_contact(arr)
            f0 = texture.describe(touch.frame, nc)
            ex = [texture.describe(x, nc) for x in (touch.extra if touch.extra is not None
                                                    else [])]
            ex += [f0] * (3 - len(ex))
            rise = np.flatnonzero(scores[:idx + 1] >= 0.5 * scores[idx])
            early = texture.describe(np.ascontiguousarray(arr[rise[0] if len(rise) else idx,
                                                              ..., ::-1]), nc)
            d = texture.contact_difference(touch.frame, nc)
            h, w = d.shape[0] // 2, d.shape[1] // 2
            reg = [texture.describe_difference(d[i * h:(i + 1) * h, j * w:(j + 1) * w])
                   for i in range(2) for j in range(2)]
            for k, v in (("cls", cls), ("path", str(path)), ("f0", f0),
                         ("extra", np.stack(ex[:3])), ("early", early), ("reg", np.stack(reg))):
                rows[k].append(v)
    out = Path(out)
    np.savez(out, **{k: np.array(v) for k, v in rows.items()})
    return out


def load_cache(path: str | Path) -> dict[str, np.ndarray]:
    """The arrays ``build_cache`` wrote."""
    p = Path(path)
    if not p.is_file():
        raise InputError(f"feature cache not found: {p} (build it with --build-cache)")
    with np.load(p, allow_pickle=False) as z:
        return {k: z[k] for k in z.files}


def by_class(cache: dict[str, np.ndarray], feature: str) -> dict[str, np.ndarray]:
    """{class: (n_c, D') feature vectors}."""
    x = FEATURES[feature](cache)
    return {c: x[cache["cls"] == c] for c in sorted(set(cache["cls"].tolist()))}


@dataclass
class Setting:
    """One way to prepare: per-press feature, representation kind (``none`` = the descriptor as
    is), output dims (lda), calibration method (``off`` = the config's temperature)."""
    label: str
    feature: str = "frame"
    kind: str = "none"
    dims: int = 0
    calibration: str = "off"
    shrink: float = 1.0

    @staticmethod
    def parse(text: str) -> "Setting":
        """``label=key:value,...`` (keys feature, kind, dims, calibration, shrink)."""
        label, sep, rest = text.partition("=")
        if not sep or not label:
            raise InputError(f"--setting {text!r}: expected label=key:value,...")
        kw: dict[str, Any] = {}
        for item in filter(None, rest.split(",")):
            k, _, v = item.partition(":")
            if k not in ("feature", "kind", "dims", "calibration", "shrink"):
                raise InputError(f"--setting {text!r}: unknown key {k!r}")
            kw[k] = int(v) if k == "dims" else float(v) if k == "shrink" else v
        s = Setting(label, **kw)
        if s.feature not in FEATURES:
            raise InputError(f"--setting {text!r}: feature one of {', '.join(FEATURES)}")
        return s


def prepare_setting(setting: Setting, library: dict[str, np.ndarray], seed: int = 0
            ) -> representation.Representation | None:
    """What ``tactex prepare`` builds from ``library`` for ``setting`` (None: nothing)."""
    if setting.kind == "none" and setting.calibration == "off":
        return None
    fit = partial(representation.fit, shrink=setting.shrink, kind=setting.kind,
                  dims=setting.dims)
    rep = fit(library)
    if setting.calibration != "off":
        trajs = belief_calibration.trajectories(library, fit, preset("default"), seed=seed)
        rep.temperature = belief_calibration.fit_temperature(
            trajs, setting.calibration, *(((0.9,), 0.03) if setting.calibration == "target"
                                          else ()))
        rep.calibration = belief_calibration.report(trajs, rep.temperature)
    return rep


class _CachedPresses:
    """A ReplaySource look-alike whose touches carry their cached feature vector."""

    one_session = False

    def __init__(self, x: np.ndarray, cls: np.ndarray) -> None:
        self.x = x
        self.rows = {c: list(np.flatnonzero(cls == c)) for c in set(cls.tolist())}

    def check_class(self, c: str) -> None:
        if c not in self.rows:
            raise InputError(f"class {c!r} not in the cache")

    def presses(self, c: str) -> list[int]:
        return self.rows[c]

    def touch(self, row: int) -> Touch:
        return Touch(belief_calibration.PLACEHOLDER_FRAME, None, None, self.x[row])


def scene_curves(setting: Setting, rep: representation.Representation | None,
                 cache: dict[str, np.ndarray], scenes: list[list[str]], seed: int,
                 budget: int) -> list[dict]:
    """Belief curves (``experiment real``'s ``curve``) of ``scenes`` on the cached test presses;
    scene i runs with seed ``seed + i``, as ``experiment real``."""
    from tactex_ros.core.engine import TrialSpec, run_trial
    from tactex_ros.sources.replay import ReplayTrial
    src = _CachedPresses(FEATURES[setting.feature](cache), cache["cls"])
    cfg = preset("default", guards=False)
    tcfg = TrialConfig(strategy="infogain", rounds=budget, stop_confidence=0.0)
    out = []
    for i, plat in enumerate(scenes):
        truth = plat[1:].index(plat[0]) + 1
        spec = TrialSpec(len(plat) - 1, cfg, tcfg, seed=seed + i)
        eng = spec.engine()
        if rep is not None:
            eng.learner.representation = rep
            if np.isfinite(rep.temperature):
                eng.learner.match.beta = rep.temperature
        t0 = time.perf_counter()
        res = run_trial(spec, ReplayTrial(src, plat, seed + i), truth=truth,
                        engine=eng).to_dict()
        res.update(classes=plat, truth_index=truth, wall_s=time.perf_counter() - t0)
        c = curve(res)
        c["classes"] = plat
        out.append(c)
    return out


def nearest_mean_accuracy(x: np.ndarray, cls: np.ndarray,
                          rep: representation.Representation | None, per: int = 1,
                          scenes: int = 3000, seed: int = 0) -> float:
    """Screening proxy (no trial): share of random 1 + 4 scenes of the classes ``cls`` in which
    the comparison whose mean of ``per`` presses lies nearest to the mean of ``per`` reference
    presses, in the belief's scene units (``core/match.py``), is the match. ``per`` = 1 is the
    belief after the baseline."""
    rng = np.random.default_rng(seed)
    classes = sorted(set(cls.tolist()))
    rows = {c: np.flatnonzero(cls == c) for c in classes}
    z = x if rep is None else rep.apply(x)
    ok = 0
    for _ in range(scenes):
        comps = rng.choice(len(classes), 4, replace=False)
        t = int(rng.integers(4))
        ref_rows = rng.permutation(rows[classes[comps[t]]])
        means = [z[ref_rows[:per]].mean(0)]
        for i, c in enumerate(comps):
            r = rows[classes[c]]
            if i == t and len(ref_rows) > per:
                r = ref_rows[per:]
            means.append(z[rng.choice(r, min(per, len(r)), replace=False)].mean(0))
        m = np.vstack(means)
        spread = m.std(0)
        scale = np.sqrt(spread ** 2 + (0.05 * np.median(spread)) ** 2) + 1e-12
        ok += int(np.argmin((((m[1:] - m[0]) / scale) ** 2).sum(1)) == t)
    return ok / scenes


SCREEN = ([("frame", "none", 0, 1.0)] + [("frame", "whiten", 0, s) for s in (0.3, 1.0, 3.0)]
          + [("frame", "lda", k, s) for k in (8, 16, 24, 32, 48) for s in (0.3, 1.0, 3.0)]
          + [(f, kind, k, 1.0) for f in ("frames4", "growth", "regions", "frame_regstd")
             for kind, k in (("none", 0), ("whiten", 0), ("lda", 24))])


def screen(a: dict[str, np.ndarray], b: dict[str, np.ndarray]) -> list[dict]:
    """Every (feature, kind, dims, shrink) of ``SCREEN`` fitted on one cache and scored with
    ``nearest_mean_accuracy`` (1 and 2 presses per platform) on the other, both directions."""
    rows = []
    for name, test, lib in (("a_with_b", a, b), ("b_with_a", b, a)):
        for f, kind, k, shrink in SCREEN:
            x = FEATURES[f](test)
            rep = (None if kind == "none" else
                   representation.fit(by_class(lib, f), shrink=shrink, kind=kind, dims=k))
            rows.append({"direction": name, "feature": f, "kind": kind, "dims": k,
                         "shrink": shrink,
                         "acc_1": nearest_mean_accuracy(x, test["cls"], rep, 1),
                         "acc_2": nearest_mean_accuracy(x, test["cls"], rep, 2)})
            print("  ".join(f"{v}" if not isinstance(v, float) else f"{v:.3f}"
                            for v in rows[-1].values()), flush=True)
    return rows


UNSEEN_SETTINGS = ("default=feature:frame", "whiten=feature:frame,kind:whiten",
                   "whiten_cal=feature:frame,kind:whiten,calibration:stop",
                   "whiten_cal_f4=feature:frames4,kind:whiten,calibration:stop")


def run_direction(settings: list[Setting], test: dict[str, np.ndarray],
                  library: dict[str, np.ndarray], args: argparse.Namespace) -> dict:
    """One direction: prepare every setting on ``library``, then ``experiment real``'s
    protocol on the ``test`` presses. Returns the summary (``prepared``: what each setting's
    preparation measured and took)."""
    reps, prepared = {}, {}
    for s in settings:
        t0 = time.perf_counter()
        reps[s.label] = prepare_setting(s, by_class(library, s.feature), seed=args.seed)
        r = reps[s.label]
        prepared[s.label] = {"seconds": time.perf_counter() - t0, "setting": vars(s),
                             "dims": None if r is None else r.dims,
                             "temperature": None if r is None else r.temperature,
                             "calibration": None if r is None else r.calibration}

    def runner(scenes: list[list[str]], tag: str) -> dict[str, list[dict]]:
        return {s.label: scene_curves(s, reps[s.label], test, scenes, args.seed, args.budget)
                for s in settings}

    classes = sorted(set(test["cls"].tolist()))
    summary = protocol(classes, [s.label for s in settings], runner, args)
    summary["prepared"] = prepared
    return summary


def run_unseen(args: argparse.Namespace) -> dict:
    """Both directions (A tested with B as the library, and B with A)."""
    settings = [Setting.parse(t) for t in args.setting or UNSEEN_SETTINGS]
    labels = [s.label for s in settings]
    if len(set(labels)) != len(labels):
        raise InputError(f"--setting labels must be unique, got {labels}")
    caches = {}
    for name, root in (("a", args.a), ("b", args.b)):
        path = Path(args.cache_dir) / f"{Path(root).name}.npz"
        if args.build_cache or not path.is_file():
            print(f"describing every press of {root} -> {path}")
            build_cache(root, path)
        caches[name] = load_cache(path)
    out = results_dir(args.out, "unseen", {k: v for k, v in vars(args).items() if k != "func"})
    if args.screen:
        rows = screen(caches["a"], caches["b"])
        write_json(out / "screen.json", rows)
        return {"screen": rows}
    both = {}
    for test, lib in (("a", "b"), ("b", "a")):
        name = f"{Path(getattr(args, test)).name}_with_{Path(getattr(args, lib)).name}"
        d = out / name
        d.mkdir(parents=True, exist_ok=True)
        summary = run_direction(settings, caches[test], caches[lib], args)
        summary.update(test=getattr(args, test), library=getattr(args, lib),
                       settings={s.label: vars(s) for s in settings})
        print(f"== test {getattr(args, test)}, library {getattr(args, lib)}")
        write_outputs(d, summary, labels, args)
        both[name] = summary
    return both


def register_unseen(esub: argparse._SubParsersAction) -> None:
    p = esub.add_parser("unseen", help="prepared representations on unseen classes, "
                                       "class-disjoint in both directions")
    p.add_argument("--a", required=True, help="replay folder A (tested with B as the library)")
    p.add_argument("--b", required=True, help="replay folder B (tested with A as the library)")
    p.add_argument("--cache-dir", required=True,
                   help="where the per-press descriptors are cached, e.g. under /tmp (never the "
                        "repository: they are descriptors of ../shared's presses)")
    p.add_argument("--build-cache", action="store_true", help="re-describe every press")
    p.add_argument("--screen", action="store_true",
                   help="only the screening proxy (nearest mean, no trials) of every feature x "
                        "metric of SCREEN, both directions; writes screen.json")
    p.add_argument("--setting", action="append",
                   help="label=feature:F,kind:K,dims:N,calibration:C (repeat); default: "
                        + " ".join(UNSEEN_SETTINGS))
    p.add_argument("--comparisons", type=int, default=4)
    p.add_argument("--scenes", type=int, default=40, help="scenes per fold and set")
    p.add_argument("--budget", type=int, default=15, help="touches after the baseline")
    p.add_argument("--folds", type=int, default=3)
    p.add_argument("--thresholds", type=float, nargs="+")
    p.add_argument("--target-touches", type=float, default=3.0)
    p.add_argument("--report-only", action="store_true")
    p.add_argument("--paired-against", nargs="+", metavar="LABEL")
    p.add_argument("--press-s", type=float, default=3.0,
                   help="seconds per touch for the time axis (experiment real's PRESS_S)")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--out")

    def func(args: argparse.Namespace) -> int:
        for name in ("comparisons", "scenes", "budget", "folds"):
            if getattr(args, name) < (2 if name in ("comparisons", "folds") else 1):
                raise InputError(f"--{name} too small: {getattr(args, name)}")
        Path(args.cache_dir).mkdir(parents=True, exist_ok=True)
        run_unseen(args)
        return 0

    p.set_defaults(func=func)
