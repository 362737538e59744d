"""``tactex experiment stability``: where each method fails, how, and the guards before/after.

Scenes are drawn per seed by the simulator at difficulty q (``sim:<q>``, 4 comparisons, the
reference one of them; ``TrialJob.platform_classes=None``), so seed s is the same scene and the
same presses for every strategy, model and (unperturbed) condition: all comparisons are paired.

Axes (each swept from easy to hard; the others held at the base condition q = ``--base-q``):

- ``difficulty``: q in ``--difficulties``;
- ``noise``: extra Gaussian sensor noise [grey levels];
- ``drift``: lighting drift, a random per-channel offset per touch [grey levels];
- ``depth_spread``: press depth uniform in nominal +- this [mm] (shallow presses barely touch);
- ``blank``: probability that a touch is a flat no-contact frame;
- ``lr``: learning rate (training that diverges).

Every strategy of ``--strategies`` runs every condition with the default model; ``--models``
(default: ``auto`` (model ``cnn_auto``) and ``top``, the largest stage of its ladder) run with the variance
strategy on the difficulty axis and the base condition, to show the compute ``auto`` saves.
Conditions listed in ``GUARDED`` run a second time with ``guards=False`` (before/after).

Where a method fails: the first value on an axis where accuracy drops below ``--threshold``.
How (per wrong or failed trial, from its round records): ``error`` (the trial stopped: e.g.
non-finite loss without guards, baseline touches rejected), ``diverged`` (non-finite loss or
steps skipped/rolled back), ``degenerate`` (at least half the rounds had all scores equal: the
choice was a tie-break), ``stuck`` (one platform took >= 80 % of the revisits),
``confident_wrong`` (final max probability >= 0.8 on a wrong platform), ``unsure_wrong``
(the rest).

Outputs: ``summary.json`` (accuracy, CI, per-seed std, failure points, failure modes, guard
before/after, auto vs top compute), ``runs.json``, figures ``axis_<name>.png``,
``failure_modes.png``, ``guards.png``, ``auto_compute.png``.
"""

from __future__ import annotations

import argparse
import json
import math
import time
from pathlib import Path
from typing import Any

import numpy as np

from tactex_ros.core.config import TrialConfig
from tactex_ros.core.engine import training_of
from tactex_ros.core.errors import InputError
from tactex_lab.analysis import charts
from tactex_lab.experiments.common import learner_set, results_dir, write_json
from tactex_lab.experiments.runner import TrialJob, add_runner_args, backend_of, run_jobs
from tactex_lab.analysis.stats import mcnemar_exact as mcnemar
from tactex_lab.analysis.stats import wilson

AXES: dict[str, list[float]] = {
    "difficulty": [0.3, 0.5, 0.7, 0.8, 0.9, 0.95],
    "noise": [0.0, 5.0, 10.0, 20.0, 40.0],
    "drift": [0.0, 10.0, 20.0, 40.0],
    "depth_spread": [0.0, 0.2, 0.35, 0.45],
    "blank": [0.0, 0.1, 0.25, 0.5],
    "lr": [0.003, 0.1, 1.0],
}
# (axis, value) pairs that also run without guards
GUARDED = [("blank", 0.25), ("blank", 0.5), ("depth_spread", 0.35), ("depth_spread", 0.45),
           ("lr", 1.0), ("lr", 0.1)]
MODES = ["error", "diverged", "degenerate", "stuck", "confident_wrong", "unsure_wrong"]


def condition(axis: str, value: float, base_q: float) -> dict:
    """source, perturb and learner overrides of one condition."""
    q = value if axis == "difficulty" else base_q
    perturb: dict[str, Any] = {}
    over: dict[str, Any] = {}
    if axis in ("noise", "drift", "blank") and value:
        perturb[axis] = value
    if axis == "depth_spread" and value:
        perturb["depth_spread"] = value
    if axis == "lr":
        over["lr"] = value
    return {"source": f"sim:{q:g}", "perturb": perturb, "overrides": over}


def failure_mode(run: dict) -> str | None:
    """None for a correct trial, else one of MODES (see module docstring)."""
    if run.get("error"):
        return "error"
    if run["correct"]:
        return None
    rounds = run["rounds"] + ([run["final"]] if run.get("final") else [])
    trained = [t for t in map(training_of, rounds) if t]
    if any(t.get("train_loss") is None or not math.isfinite(t["train_loss"]) or
           t.get("skipped_steps", 0) or t.get("restored") for t in trained):
        return "diverged"
    scored = [r for r in run["rounds"] if r["scores"] is not None]
    if scored and np.mean([r.get("degenerate", False) for r in scored]) >= 0.5:
        return "degenerate"
    final = run["final"]
    t0, t1 = np.asarray(rounds[0]["touches"]), np.asarray(final["touches"])
    revisits = t1 - t0
    if revisits.sum() >= 3 and revisits.max() >= 0.8 * revisits.sum():
        return "stuck"
    if max(final["probs"]) >= 0.8:
        return "confident_wrong"
    return "unsure_wrong"


def compact(res: dict) -> dict:
    job = res["job"]

    def keep(r: dict, names: tuple[str, ...]) -> dict:
        return {**{k: r.get(k) for k in names}, "detail": r.get("detail", training_of(r) or None)}

    rounds = [keep(r, ("probs", "scores", "predictive_entropy", "touches", "model",
                       "degenerate", "decision_s", "cpu_s")) for r in res["rounds"]]
    f = res.get("final")
    final = None if f is None else keep(f, ("probs", "touches", "model", "decision_s", "cpu_s",
                                            "predictive_entropy"))
    out = {**job["tags"], "strategy": job["strategy"], "seed": job["seed"],
           "correct": bool(res["correct"]), "error": res.get("error"), "rounds": rounds,
           "final": final, "failed_touches": len(res["failed_touches"]),
           "cpu_s": float(sum(r.get("cpu_s") or 0.0 for r in res["rounds"]) +
                          ((f or {}).get("cpu_s") or 0.0)),
           "wall_s": res["wall_s"]}
    out["mode"] = failure_mode(out)
    return out


def acc_block(runs: list[dict]) -> dict:
    c = [r["correct"] for r in runs]
    lo, hi = wilson(sum(c), len(c))
    modes = {m: sum(1 for r in runs if r["mode"] == m) for m in MODES}
    return {"n": len(c), "accuracy": float(np.mean(c)) if c else float("nan"), "ci95": [lo, hi],
            "modes": modes, "cpu_per_trial_s": float(np.mean([r["cpu_s"] for r in runs]))
            if runs else float("nan"),
            "rejected_touches": int(sum(r["failed_touches"] for r in runs)),
            "escalated": sum(1 for r in runs
                             if any(training_of(x).get("escalation") for x in r["rounds"]))}


# ------------------------------------------------------------------------------ command
def build_jobs(args) -> list[TrialJob]:
    jobs = []
    models = {"default": {}, "auto": {"model": "cnn_auto"}, "top": {}}
    from tactex_ros.core.config import preset
    from tactex_ros.core.ladder import rungs_of
    top = rungs_of(preset("cnn", **{"model": "cnn_auto", **args.overrides})).names[-1]
    name, _, px = top.partition("@")
    models["top"] = {"model": name, "input_size": int(px)}
    axes = {a: AXES[a] for a in args.axes}
    if "difficulty" in axes and args.difficulties:
        axes["difficulty"] = args.difficulties

    def add(axis, value, strategy, model, guards=True):
        c = condition(axis, value, args.base_q)
        over = {**args.overrides, **c["overrides"], **models[model]}
        if not guards:
            over["guards"] = False
        for seed in args.seeds:
            jobs.append(TrialJob(source=c["source"], seed=seed,
                                 trial=TrialConfig(strategy=strategy, rounds=args.rounds,
                                                   stop_confidence=0.0),
                                 preset="cnn", overrides=over,
                                 platform_classes=None, comparisons=4,
                                 trial_id=f"{axis}={value:g}/s{seed}", perturb=c["perturb"],
                                 catch_errors=True,
                                 tags={"axis": axis, "value": value, "model": model,
                                       "guards": guards, "pseed": seed}))
    for axis, values in axes.items():
        for v in values:
            for s in args.strategies:
                add(axis, v, s, "default")
            if axis == "difficulty":
                for m in args.models:
                    add(axis, v, "variance", m)
            for (ga, gv) in GUARDED:
                if ga == axis and gv == v:
                    for s in args.guard_strategies:
                        add(axis, v, s, "default", guards=False)
    return jobs, models


def _select(runs: list[dict], **kw: Any) -> list[dict]:
    return [r for r in runs if all(r.get(k) == v for k, v in kw.items())]


def _sweep(runs: list[dict], axis: str, values: list[float], strategy: str, model: str,
           threshold: float) -> tuple[dict, dict]:
    """Accuracy blocks along one axis (guards on) and where accuracy first drops below
    ``threshold``, with the failure modes there."""
    blocks = [acc_block(_select(runs, axis=axis, value=v, strategy=strategy, model=model,
                                guards=True)) for v in values]
    fail = next((v for v, b in zip(values, blocks, strict=True) if b["accuracy"] < threshold), None)
    modes = (None if fail is None else
             {m: n for m, n in blocks[values.index(fail)]["modes"].items() if n})
    return dict(zip(map(str, values), blocks, strict=True)), {"fails_at": fail, "modes_there": modes}


def _guards_before_after(runs: list[dict], axes: dict, strategies: list[str]) -> list[dict]:
    """Every guarded condition: the same seeds with guards on and off, exact McNemar."""
    out = []
    for (ga, gv) in GUARDED:
        if ga not in axes:
            continue
        for s in strategies:
            on = sorted(_select(runs, axis=ga, value=gv, strategy=s, model="default",
                                guards=True), key=lambda r: r["seed"])
            off = sorted(_select(runs, axis=ga, value=gv, strategy=s, model="default",
                                 guards=False), key=lambda r: r["seed"])
            if not on or not off:
                continue
            out.append({"axis": ga, "value": gv, "strategy": s, "with": acc_block(on),
                        "without": acc_block(off),
                        "mcnemar_with_vs_without": mcnemar([r["correct"] for r in on],
                                                           [r["correct"] for r in off])})
    return out


def _auto_vs_top(runs: list[dict], top_model: dict) -> dict:
    """Model ``auto`` against the largest ladder stage on the difficulty axis, paired by
    (difficulty, seed): accuracy, decision CPU, escalations."""
    a_runs = _select(runs, axis="difficulty", strategy="variance", model="cnn_auto", guards=True)
    t_runs = _select(runs, axis="difficulty", strategy="variance", model="top", guards=True)
    key = lambda r: (r["value"], r["seed"])  # noqa: E731
    ta = {key(r): r for r in t_runs}
    pairs = [(r, ta[key(r)]) for r in a_runs if key(r) in ta]
    auto = {"top_model": top_model, "pairs": len(pairs),
            "accuracy_auto": float(np.mean([a["correct"] for a, _ in pairs])),
            "accuracy_top": float(np.mean([t["correct"] for _, t in pairs])),
            "cpu_auto_s": float(sum(a["cpu_s"] for a, _ in pairs)),
            "cpu_top_s": float(sum(t["cpu_s"] for _, t in pairs)),
            "mcnemar_auto_vs_top": mcnemar([a["correct"] for a, _ in pairs],
                                           [t["correct"] for _, t in pairs]),
            "escalated_trials": sum(1 for a, _ in pairs
                                    if any(training_of(x).get("escalation") for x in a["rounds"])),
            "escalation_reasons": sorted({training_of(x)["escalation"].split(":")[0]
                                          for a, _ in pairs for x in a["rounds"]
                                          if training_of(x).get("escalation")})}
    auto["cpu_saved_share"] = (1 - auto["cpu_auto_s"] / auto["cpu_top_s"]
                               if auto["cpu_top_s"] else None)
    return auto


def summarise(runs: list[dict], args, models: dict) -> dict:
    """Accuracy tables per axis, failure points, the base condition, guards before/after and
    auto against the largest model."""
    axes = {a: (args.difficulties if a == "difficulty" and args.difficulties else AXES[a])
            for a in args.axes}
    table: dict = {}
    failure_points: dict = {}
    for axis, values in axes.items():
        table[axis], failure_points[axis] = {}, {}
        series = [(s, "default") for s in args.strategies]
        if axis == "difficulty":
            series += [("variance", m) for m in args.models]
        for strategy, model in series:
            key = f"{strategy}/{model}"
            table[axis][key], failure_points[axis][key] = _sweep(
                runs, axis, values, strategy, model, args.threshold)
    # per-seed spread at the base condition
    per_seed = {}
    for s in args.strategies:
        rr = _select(runs, axis="difficulty", value=args.base_q, strategy=s, model="default",
                     guards=True)
        per_seed[s] = {"accuracy": float(np.mean([r["correct"] for r in rr])) if rr else None,
                       "n_seeds": len(rr)}
    auto = ({} if "difficulty" not in axes or not {"auto", "top"} <= set(args.models)
            else _auto_vs_top(runs, models["top"]))
    return {"threshold": args.threshold, "base_q": args.base_q, "rounds": args.rounds,
            "seeds": args.seeds, "strategies": args.strategies, "models": args.models,
            "axes": axes, "table": table, "failure_points": failure_points,
            "base_condition": per_seed,
            "guards_before_after": _guards_before_after(runs, axes, args.guard_strategies),
            "auto_vs_top": auto}


def figures(out: Path, summary: dict, args) -> None:
    for axis, values in summary["axes"].items():
        series = {k: [v[str(x)]["accuracy"] for x in values]
                  for k, v in summary["table"][axis].items()}
        charts.accuracy_axis(out / f"axis_{axis}.png", axis, values, series, args.threshold,
                             f"{axis} (others at q={args.base_q:g}); {len(args.seeds)} seeds, "
                             f"{args.rounds} rounds")
    rows = []
    for axis, values in summary["axes"].items():
        for x in values:
            for k in ("variance/default", "yoto/default"):
                if k in summary["table"][axis]:
                    rows.append((f"{axis}={x:g} {k.split('/')[0]}",
                                 summary["table"][axis][k][str(x)]))
    if rows:
        charts.failure_modes(out / "failure_modes.png", rows,
                             "how trials fail (share of all trials at each condition)")
    if summary["guards_before_after"]:
        charts.guards(out / "guards.png", summary["guards_before_after"],
                      f"guards off vs on, same seeds ({len(args.seeds)})")
    if "difficulty" in summary["table"]:
        blocks = {k.split("/")[1]: [v[str(x)] for x in summary["axes"]["difficulty"]]
                  for k, v in summary["table"]["difficulty"].items() if k.startswith("variance/")}
        charts.auto_compute(out / "auto_compute.png", summary["axes"]["difficulty"], blocks,
                            "variance strategy: model auto vs default vs the largest ladder stage")


def run(args) -> int:
    for a in args.axes:
        if a not in AXES:
            raise InputError(f"unknown axis {a!r}; choose from {', '.join(AXES)}")
    if len(args.seeds) < 1:
        raise InputError("need at least one seed")
    backend = backend_of(args).resolved()
    args.workers = backend.workers
    args.overrides = learner_set(args.set)
    cfg = {k: v for k, v in vars(args).items() if k != "func"}
    out = results_dir(args.out, "stability", cfg)
    jobs, models = build_jobs(args)
    # identical trials (e.g. noise=0 and drift=0 are both the base condition) run once
    unique: dict[str, int] = {}
    todo: list[TrialJob] = []
    for j in jobs:
        k = json.dumps([j.source, j.perturb, j.overrides, j.trial.strategy, j.seed], sort_keys=True)
        if k not in unique:
            unique[k] = len(todo)
            todo.append(j)
    t0 = time.perf_counter()
    res = run_jobs(todo, backend, threads=args.threads,
                   description=f"stability ({len(todo)} trials)", quiet=args.quiet)
    runs = []
    for j in jobs:
        k = json.dumps([j.source, j.perturb, j.overrides, j.trial.strategy, j.seed], sort_keys=True)
        d = res[unique[k]].to_dict()      # runs.json's form
        r = dict(d, job=dict(d["job"], tags=j.tags))
        runs.append(compact(r))
    summary = summarise(runs, args, models)
    summary["wall_s"] = time.perf_counter() - t0
    summary["trials"] = len(todo)
    summary["conditions_x_seeds"] = len(jobs)
    write_json(out / "summary.json", summary)
    write_json(out / "runs.json", runs)
    figures(out, summary, args)
    print(f"threshold {args.threshold:g}; first failing value per axis:")
    for axis, d in summary["failure_points"].items():
        for k, v in d.items():
            print(f"  {axis:<13}{k:<20}{str(v['fails_at']):>7}  {v['modes_there'] or ''}")
    for g in summary["guards_before_after"]:
        print(f"  guards {g['axis']}={g['value']:g} {g['strategy']}: off "
              f"{g['without']['accuracy']:.2f} -> on {g['with']['accuracy']:.2f}")
    if summary["auto_vs_top"]:
        a = summary["auto_vs_top"]
        print(f"  auto vs top: accuracy {a['accuracy_auto']:.3f} vs {a['accuracy_top']:.3f}, "
              f"CPU {a['cpu_auto_s']:.0f} s vs {a['cpu_top_s']:.0f} s "
              f"(saved {100 * (a['cpu_saved_share'] or 0):.0f} %)")
    print(f"results in {out}")
    return 0


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("stability", help="accuracy over seeds, difficulty and perturbations; "
                                         "failure points and modes; guards before/after")
    p.add_argument("--axes", nargs="+", default=list(AXES), help=f"of {', '.join(AXES)}")
    p.add_argument("--difficulties", type=float, nargs="+",
                   help=f"difficulty values (default {AXES['difficulty']})")
    p.add_argument("--base-q", type=float, default=0.5, help="difficulty of the other axes")
    p.add_argument("--strategies", nargs="+",
                   default=["variance", "entropy", "bald", "random", "yoto"])
    p.add_argument("--models", nargs="*", default=["auto", "top"],
                   help="extra models on the difficulty axis (variance): auto, top")
    p.add_argument("--guard-strategies", nargs="*", default=["variance", "yoto"])
    p.add_argument("--set", action="append", metavar="PATH=VALUE",
                   help="learner override for every job (e.g. learner.input_size=48)")
    p.add_argument("--seeds", type=int, nargs="+", default=list(range(10)))
    p.add_argument("--rounds", type=int, default=5)
    p.add_argument("--threshold", type=float, default=0.6,
                   help="a method fails where its accuracy drops below this")
    p.add_argument("--out", help="results folder (default results/stability)")
    add_runner_args(p)
    p.set_defaults(func=run)
