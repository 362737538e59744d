"""``tactex experiment pareto``: speed against accuracy, on the same trials and seeds.

Parts (each can be switched off; all write into one results folder):

- **grid**: every setting of ``--grid`` (one factor at a time around the default: input size,
  training steps per round, Monte-Carlo passes, batch-norm recalibration, model variant, model
  ``cnn_auto``, and combinations) runs the trials of ``--trials-file`` on ``--source`` for every
  seed with the ``--strategy`` (variance), ``--rounds`` decisions after the baseline. Per setting:
  the median decision time per round (train + score + choose, one torch thread per worker
  process) and the trial accuracy at ``--budget`` total touches (the decision a run capped at that
  budget would have ended with); the mean compute per trial (sum of its decision times).
  Jobs are interleaved over settings so every setting sees the same machine load.
  Heavy settings (``seed_faithful``: 299 px, 10 epochs per round; the full Inception v3) run on the
  first ``--heavy-trials`` trials only, and their accuracy is compared with the default's on
  exactly those trials and seeds.
- **faithful**: seed-faithful against the default on ``--faithful-source`` (e.g. the replayed
  octopi-dev presses: ``replay:../shared/datasets/octopi-dev``; needed for this part), ``--faithful-trials`` scenes drawn from seeds 0..N-1, ``--faithful-rounds``
  rounds, variance strategy: accuracy and time, paired.
- **touches**: accuracy against the number of touches for every strategy of ``--strategies`` with
  the default setting, ``--touch-rounds`` rounds, read at every budget from one run per trial
  and seed; the wall time of this part is the "32 trials x 4 strategies x 20 rounds" speed target.

Figures: ``pareto.png`` (accuracy against median decision time, log scale, Pareto front, the
thesis's setting marked), ``pareto_heavy.png`` (the heavy subset), ``touches.png``,
``faithful.png``. JSON: ``grid.json``, ``faithful.json``, ``touches.json``, ``runs.json``.
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path
from typing import Any

import numpy as np

from tactex_ros.core.config import TrialConfig
from tactex_ros.core.engine import training_of
from tactex_ros.core.errors import InputError
from tactex_lab.analysis import charts
from tactex_lab.experiments.common import correct_at, learner_set, results_dir, write_json
from tactex_lab.experiments.runner import TrialJob, add_runner_args, backend_of, cached_source, run_jobs
from tactex_lab.analysis.stats import mcnemar_exact as mcnemar
from tactex_lab.analysis.stats import pareto_front, wilson

# The settings are spelled out in full around the pre-issue-5 default ("base": 64 px, 12 Adam
# steps of 32 per round, 20 MC passes, BN recalibration on 64 views) so the grid does not move
# when PRESETS["default"] changes; "default" is whatever the preset is now.
BASE = dict(model="small_inception", input_size=64, epochs=0, steps=12, batch_size=32, lr=3e-3,
            dropout=0.5, mc_passes=20, bn_recalibrate=64)


def _b(**kw: Any) -> dict:
    return {**BASE, **kw}


# label -> (preset, overrides, heavy). One factor at a time around the base, plus combinations.
GRIDS: dict[str, list[tuple[str, str, dict, bool]]] = {
    "full": [
        ("default", "cnn", {}, False),
        ("base", "cnn", _b(), False),
        ("32px", "cnn", _b(input_size=32), False),
        ("48px", "cnn", _b(input_size=48), False),
        ("96px", "cnn", _b(input_size=96), False),
        ("steps4", "cnn", _b(steps=4), False),
        ("steps8", "cnn", _b(steps=8), False),
        ("steps24", "cnn", _b(steps=24), False),
        ("mc5", "cnn", _b(mc_passes=5), False),
        ("mc50", "cnn", _b(mc_passes=50), False),
        ("bn0", "cnn", _b(bn_recalibrate=0), False),
        ("bn16", "cnn", _b(bn_recalibrate=16), False),
        # (48 px + 8 steps is the current "default" preset: not listed twice)
        ("32px+steps24", "cnn", _b(input_size=32, steps=24), False),
        ("32px+steps12+bs16", "cnn", _b(input_size=32, batch_size=16), False),
        ("auto", "cnn", _b(model="cnn_auto"), False),
        ("inception_v3_random@80", "cnn", _b(model="inception_v3_random", input_size=80),
         True),
        ("seed_faithful", "seed_faithful", {}, True),
    ],
    "quick": [
        ("default", "cnn", {}, False),
        ("32px", "cnn", _b(input_size=32), False),
        ("steps4", "cnn", _b(steps=4), False),
        ("auto", "cnn", _b(model="cnn_auto"), False),
    ],
}
THESIS_LABEL = "seed_faithful"


# ------------------------------------------------------------------------------ small helpers
def job_key(job: TrialJob) -> str:
    """Content hash of a job with its learner settings resolved (a preset change changes it)."""
    import hashlib
    import json

    from tactex_ros.core.config import preset
    cfg = preset(job.preset, **job.overrides).model_dump()   # a learner's own fields only
    d = job.to_dict()
    d.pop("tags")
    blob = json.dumps({"job": d, "cfg": cfg}, sort_keys=True, default=str)
    return hashlib.sha1(blob.encode()).hexdigest()[:20]


def run_cached(jobs: list[TrialJob], args, description: str) -> list[dict]:
    """``run_jobs`` with an optional per-job result cache (``--cache DIR``): a job whose content
    hash (``job_key``) has a stored result is not run again. Results carry the job's own tags."""
    import json
    cache = Path(args.cache) if getattr(args, "cache", None) else None
    out: list[dict | None] = [None] * len(jobs)
    todo = []
    for i, j in enumerate(jobs):
        f = cache / f"{job_key(j)}.json" if cache else None
        if f is not None and f.is_file():
            r = json.loads(f.read_text())
            r["job"]["tags"] = dict(j.tags)
            out[i] = r
        else:
            todo.append(i)
    # with a cache, run in chunks so finished jobs are stored as they come
    step = len(todo) if cache is None else max(16, 6 * args.workers)
    backend = backend_of(args)
    for c0 in range(0, len(todo), max(1, step)):
        chunk = todo[c0:c0 + step]
        res = run_jobs([jobs[i] for i in chunk], backend, threads=args.threads,
                       description=f"{description}: {c0 + len(chunk)}/{len(todo)} to run, "
                                   f"{len(jobs) - len(todo)} cached", quiet=args.quiet)
        for i, r in zip(chunk, res, strict=True):
            out[i] = r.to_dict()      # the cache's file form, as cached results are read
            if cache is not None:
                write_json(cache / f"{job_key(jobs[i])}.json", out[i])
    return out  # type: ignore[return-value]


def decisions_of(res: dict) -> list[dict]:
    """Every decision of a runner result: total touches when deciding, probs, time, model."""
    out = []
    for r in res["rounds"] + ([res["final"]] if res.get("final") else []):
        out.append({"total": int(sum(r["touches"])) + 1, "probs": r["probs"],
                    "decision_s": r["decision_s"], "cpu_s": r.get("cpu_s", float("nan")),
                    "entropy": r["predictive_entropy"],
                    "model": (f"{r['model']}@{training_of(r)['input_size']}"
                              if training_of(r) else r["model"]),
                    "escalation": training_of(r).get("escalation")})
    return out


def compact(res: dict) -> dict:
    job = res["job"]
    return {"setting": job["tags"].get("setting"), "trial": job["trial_id"],
            "seed": job["tags"].get("seed"), "job_seed": job["seed"],
            "strategy": job["strategy"], "truth": res["truth_index"],
            "correct": bool(res["correct"]), "error": res.get("error"),
            "decisions": decisions_of(res), "wall_s": res["wall_s"],
            "failed_touches": len(res["failed_touches"])}


def summarise_setting(runs: list[dict], budget: int) -> dict:
    times = [d["decision_s"] for r in runs for d in r["decisions"]]
    cpu = [d["cpu_s"] for r in runs for d in r["decisions"]]
    ok = [correct_at(r["decisions"], r["truth"], budget) for r in runs]
    final = [r["correct"] for r in runs]
    lo, hi = wilson(sum(ok), len(ok))
    per_seed = {}
    for r, c in zip(runs, ok, strict=True):
        per_seed.setdefault(r["seed"], []).append(c)
    seed_acc = [float(np.mean(v)) for v in per_seed.values()]
    escal = sum(1 for r in runs if any(d["escalation"] for d in r["decisions"]))
    return {"n": len(runs), "accuracy": float(np.mean(ok)) if ok else float("nan"),
            "ci95": [lo, hi], "accuracy_final": float(np.mean(final)) if final else float("nan"),
            "std_over_seeds": float(np.std(seed_acc, ddof=1)) if len(seed_acc) > 1 else 0.0,
            "median_decision_s": float(np.median(times)) if times else float("nan"),
            "p90_decision_s": float(np.percentile(times, 90)) if times else float("nan"),
            "median_cpu_s": float(np.median(cpu)) if cpu else float("nan"),
            "cpu_per_trial_s": float(np.mean([sum(d["cpu_s"] for d in r["decisions"])
                                              for r in runs])) if runs else float("nan"),
            "compute_per_trial_s": float(np.mean([sum(d["decision_s"] for d in r["decisions"])
                                                  for r in runs])) if runs else float("nan"),
            "trials_escalated": escal, "errors": sum(1 for r in runs if r["error"]),
            "models": sorted({d["model"] for r in runs for d in r["decisions"]})}


# ------------------------------------------------------------------------------ parts
def _trial_scenes(trials_file: str, source: str) -> list[tuple[str, list[str]]]:
    from tactex_lab.experiments.trials import find_trial_file, load_trials, platform_classes
    doc = load_trials(find_trial_file(trials_file))
    src = cached_source(source)
    return [(t["id"], platform_classes(src, t)) for t in doc["trials"]]


def _grid_jobs(args, grid: list[tuple], scenes: list[tuple], heavy_n: int,
               heavy_seeds: list[int]) -> list[TrialJob]:
    """Every (seed, scene, setting) of the grid; heavy settings only on the first ``heavy_n``
    scenes and ``heavy_seeds``; heavy jobs first so the long ones do not trail at the end."""
    jobs = []
    for seed in args.seeds:
        for pos, (tid, classes) in enumerate(scenes):
            for label, pre, over, heavy in grid:
                if heavy and (pos >= heavy_n or seed not in heavy_seeds):
                    continue
                jobs.append(TrialJob(source=args.source, seed=1000 * seed + pos,
                                     trial=TrialConfig(strategy=args.strategy,
                                                       rounds=args.rounds, stop_confidence=0.0),
                                     preset=pre,
                                     overrides={**over, **args.overrides},
                                     platform_classes=classes,
                                     trial_id=tid, catch_errors=True,
                                     tags={"setting": label, "seed": seed, "pos": pos}))
    jobs.sort(key=lambda j: 0 if any(g[0] == j.tags["setting"] and g[3] for g in grid) else 1)
    return jobs


def run_grid(args, out: Path) -> dict:
    grid = GRIDS[args.grid]
    if args.settings:
        keep = set(args.settings)
        grid = [g for g in grid if g[0] in keep]
    if args.drawn:   # scenes drawn by the source from each job's seed (e.g. replay sources)
        scenes = [(f"d{i}", None) for i in range(args.drawn)]
    else:
        scenes = _trial_scenes(args.trials_file, args.source)
    if args.max_trials:
        scenes = scenes[:args.max_trials]
    heavy_n = min(args.heavy_trials, len(scenes))
    heavy_seeds = args.seeds[:args.heavy_seeds]
    jobs = _grid_jobs(args, grid, scenes, heavy_n, heavy_seeds)
    t0 = time.perf_counter()
    res = run_cached(jobs, args, f"pareto grid ({len(grid)} settings)")
    wall = time.perf_counter() - t0
    runs = [dict(compact(r), pos=r["job"]["tags"]["pos"]) for r in res]
    rows = {label: summarise_setting([r for r in runs if r["setting"] == label], args.budget)
            for label, *_ in grid}
    heavy_labels = [g[0] for g in grid if g[3]]
    # on the heavy subset: every setting, same trials and seeds
    sub = [r for r in runs if r["pos"] < heavy_n and r["seed"] in heavy_seeds]
    rows_heavy = {label: summarise_setting([r for r in sub if r["setting"] == label],
                                           args.budget) for label, *_ in grid}
    # paired tests against the default (full set; heavy ones on their subset)
    tests = {}
    for label, *_ in grid:
        if label == "default":
            continue
        src = sub if label in heavy_labels else runs
        key = {(r["trial"], r["seed"]): correct_at(r["decisions"], r["truth"], args.budget)
               for r in src if r["setting"] == "default"}
        mine = {(r["trial"], r["seed"]): correct_at(r["decisions"], r["truth"], args.budget)
                for r in src if r["setting"] == label}
        common = sorted(set(key) & set(mine))
        tests[label] = mcnemar([mine[k] for k in common], [key[k] for k in common])
        tests[label]["pairs"] = len(common)
    summary = {"budget": args.budget, "rounds": args.rounds, "strategy": args.strategy,
               "source": args.source, "trials": len(scenes), "seeds": args.seeds,
               "heavy_trials": heavy_n, "heavy_seeds": heavy_seeds, "settings": {g[0]: {"preset": g[1], "overrides": g[2],
                                                             "heavy": g[3]} for g in grid},
               "all_trials": rows, "heavy_subset": rows_heavy, "vs_default_mcnemar": tests,
               "pareto_front": [list(rows)[i] for i in pareto_front(
                   [(v["median_cpu_s"], v["accuracy"]) for v in rows.values()])],
               "wall_s": wall, "workers": args.workers, "threads": args.threads}
    write_json(out / "grid.json", summary)
    write_json(out / "grid_runs.json", runs)
    light = {k: v for k, v in rows.items() if k not in heavy_labels}
    charts.pareto(out / "pareto.png", {**light, **{k: rows_heavy[k] for k in heavy_labels}},
                  f"{args.source}, {len(scenes)} trials x {len(args.seeds)} seeds, "
                  f"{args.strategy}, accuracy at {args.budget} touches "
                  f"(heavy settings: first {heavy_n} trials, seeds {heavy_seeds})",
                  mark=THESIS_LABEL)
    if heavy_labels:
        charts.pareto(out / "pareto_heavy.png", rows_heavy,
                      f"same {heavy_n} trials x seeds {heavy_seeds} for every setting, "
                      f"accuracy at {args.budget} touches", mark=THESIS_LABEL)
    return summary


def run_faithful(args, out: Path) -> dict:
    settings = [(THESIS_LABEL, "seed_faithful", dict(args.overrides)),
                ("default", "cnn", dict(args.overrides))]
    jobs = [TrialJob(source=args.faithful_source, seed=s,
                     trial=TrialConfig(strategy="variance", rounds=args.faithful_rounds,
                                       stop_confidence=0.0), preset=pre, overrides=over,
                     comparisons=4, trial_id=f"s{s}", catch_errors=True,
                     tags={"setting": label, "seed": s})
            for s in range(args.faithful_trials) for label, pre, over in settings]
    jobs.sort(key=lambda j: j.tags["setting"] != THESIS_LABEL)
    res = run_cached(jobs, args, "seed-faithful vs default")
    runs = [compact(r) for r in res]
    for r, x in zip(runs, res, strict=True):
        r["classes"] = x["classes"]
    summary = {}
    for label, *_ in settings:
        rr = [r for r in runs if r["setting"] == label]
        times = [d["decision_s"] for r in rr for d in r["decisions"]]
        summary[label] = {"correct": sum(r["correct"] for r in rr), "n": len(rr),
                          "accuracy_final": float(np.mean([r["correct"] for r in rr])),
                          "ci95": list(wilson(sum(r["correct"] for r in rr), len(rr))),
                          "median_decision_s": float(np.median(times)),
                          "median_cpu_s": float(np.median([d["cpu_s"] for r in rr
                                                           for d in r["decisions"]])),
                          "decision_s_by_touches": {
                              str(k): float(np.median([d["decision_s"] for r in rr
                                                       for d in r["decisions"]
                                                       if d["total"] == k]))
                              for k in sorted({d["total"] for r in rr for d in r["decisions"]})},
                          "per_trial": {r["trial"]: r["correct"] for r in rr}}
    a = [summary[THESIS_LABEL]["per_trial"][f"s{s}"] for s in range(args.faithful_trials)]
    b = [summary["default"]["per_trial"][f"s{s}"] for s in range(args.faithful_trials)]
    doc = {"source": args.faithful_source, "trials": args.faithful_trials,
           "seeds": list(range(args.faithful_trials)), "rounds": args.faithful_rounds,
           "strategy": "variance", "comparisons": 4,
           "scenes": {r["trial"]: r["classes"] for r in runs if r["setting"] == "default"},
           "summary": summary, "mcnemar_faithful_vs_default": mcnemar(a, b),
           "threads": args.threads, "workers": args.workers}
    write_json(out / "faithful.json", doc)
    write_json(out / "faithful_runs.json", runs)
    charts.faithful(out / "faithful.png", summary,
                    f"seed_faithful vs default: {Path(args.faithful_source).name}, "
                    f"{args.faithful_trials} trials (seeds 0-{args.faithful_trials - 1}), "
                    f"{args.faithful_rounds} rounds, variance", mark=THESIS_LABEL)
    return doc


def run_touches(args, out: Path) -> dict:
    scenes = _trial_scenes(args.trials_file, args.source)
    if args.max_trials:
        scenes = scenes[:args.max_trials]
    jobs = [TrialJob(source=args.source, seed=1000 * seed + pos,
                     trial=TrialConfig(strategy=s, rounds=args.touch_rounds, stop_confidence=0.0),
                     preset="cnn", overrides=dict(args.overrides),
                     platform_classes=classes, trial_id=tid, catch_errors=True,
                     tags={"setting": "default", "seed": seed})
            for seed in args.touch_seeds for pos, (tid, classes) in enumerate(scenes)
            for s in args.strategies]
    t0 = time.perf_counter()
    res = run_cached(jobs, args, f"touch curves ({len(args.strategies)} strategies)")
    wall = time.perf_counter() - t0
    runs = [compact(r) for r in res]
    budgets = list(range(len(scenes[0][1]), len(scenes[0][1]) + args.touch_rounds + 1))
    curves = {}
    for s in args.strategies:
        rr = [r for r in runs if r["strategy"] == s]
        acc = [float(np.mean([correct_at(r["decisions"], r["truth"], k) for r in rr]))
               for k in budgets]
        curves[s] = {"touches": budgets, "accuracy": acc, "n": len(rr),
                     "accuracy_final": float(np.mean([r["correct"] for r in rr])),
                     "median_decision_s": float(np.median([d["decision_s"] for r in rr
                                                           for d in r["decisions"]]))}
    doc = {"source": args.source, "trials": len(scenes), "seeds": args.touch_seeds,
           "rounds": args.touch_rounds, "strategies": args.strategies, "curves": curves,
           "wall_s": wall, "jobs": len(jobs), "workers": args.workers, "threads": args.threads,
           "decisions": sum(len(r["decisions"]) for r in runs),
           "cpu_total_s": float(sum(d["cpu_s"] for r in runs for d in r["decisions"])),
           "trial_wall_total_s": float(sum(r["wall_s"] for r in runs))}
    write_json(out / "touches.json", doc)
    charts.touch_curves(out / "touches.png", curves,
                        f"default setting, {args.source}, {len(scenes)} trials x "
                        f"{len(args.touch_seeds)} seed(s); wall {wall:.0f} s with {args.workers} "
                        f"workers")
    return doc


# ------------------------------------------------------------------------------ command
def run(args) -> int:
    if args.grid not in GRIDS:
        raise InputError(f"unknown grid {args.grid!r}; choose one of {', '.join(GRIDS)}")
    parts = set(args.parts)
    if "faithful" in parts and not args.faithful_source:
        raise InputError("part faithful needs --faithful-source (e.g. replay:DIR of recorded "
                         "presses)")
    args.workers = backend_of(args).resolved().workers
    args.overrides = learner_set(args.set)
    cfg = {k: v for k, v in vars(args).items() if k != "func"}
    out = results_dir(args.out, "pareto", cfg)
    done = {}
    if "grid" in parts:
        done["grid"] = run_grid(args, out)
    if "faithful" in parts:
        done["faithful"] = run_faithful(args, out)
    if "touches" in parts:
        done["touches"] = run_touches(args, out)
    if "grid" in done:
        rows = done["grid"]["all_trials"]
        print(f"{'setting':<24}{'accuracy':>9}{'median s':>10}{'median cpu s':>14}"
              f"{'cpu/trial s':>13}")
        for k, v in rows.items():
            print(f"{k:<24}{v['accuracy']:>9.3f}{v['median_decision_s']:>10.3f}"
                  f"{v['median_cpu_s']:>14.3f}{v['cpu_per_trial_s']:>13.2f}")
        print("Pareto front:", ", ".join(done["grid"]["pareto_front"]))
    if "faithful" in done:
        for k, v in done["faithful"]["summary"].items():
            print(f"{k}: {v['correct']}/{v['n']} correct, median decision "
                  f"{v['median_decision_s']:.2f} s")
    if "touches" in done:
        t = done["touches"]
        print(f"touch curves: {t['jobs']} trials, {t['decisions']} decisions, wall "
              f"{t['wall_s']:.0f} s; decision CPU total {t['cpu_total_s']:.0f} s")
    print(f"results in {out}")
    return 0


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("pareto", help="speed against accuracy: decision time vs trial accuracy")
    p.add_argument("--parts", nargs="+", default=["grid", "faithful", "touches"],
                   choices=["grid", "faithful", "touches"])
    p.add_argument("--grid", default="full", help=f"settings grid: {', '.join(GRIDS)}")
    p.add_argument("--settings", nargs="+", help="run only these settings of the grid")
    p.add_argument("--trials-file", default="human_study")
    p.add_argument("--source", default="sim")
    p.add_argument("--max-trials", type=int, default=0, help="first N trials only (0 = all)")
    p.add_argument("--drawn", type=int, default=0,
                   help="grid: N scenes of 4 comparisons drawn by the source from the job seeds "
                        "(1000 * seed + 0..N-1) instead of --trials-file")
    p.add_argument("--seeds", type=int, nargs="+", default=[0, 1])
    p.add_argument("--strategy", default="variance")
    p.add_argument("--rounds", type=int, default=3, help="decisions after the baseline (grid)")
    p.add_argument("--budget", type=int, default=8, help="touches at which accuracy is read")
    p.add_argument("--heavy-trials", type=int, default=8,
                   help="trials for the heavy settings (seed_faithful, inception_v3_random)")
    p.add_argument("--heavy-seeds", type=int, default=1,
                   help="the heavy settings run the first N of --seeds")
    p.add_argument("--faithful-source",
                   help="touch source of the faithful part (needed for it), e.g. replay:DIR")
    p.add_argument("--faithful-trials", type=int, default=8)
    p.add_argument("--faithful-rounds", type=int, default=3)
    p.add_argument("--strategies", nargs="+", default=["variance", "entropy", "random", "yoto"])
    p.add_argument("--touch-rounds", type=int, default=20)
    p.add_argument("--touch-seeds", type=int, nargs="+", default=[0])
    p.add_argument("--set", action="append", metavar="PATH=VALUE",
                   help="learner override for every job (after the setting's own), e.g. "
                        "learner.steps=4")
    p.add_argument("--out", help="results folder (default results/pareto)")
    p.add_argument("--cache", help="per-job result cache folder (re-runs skip finished jobs; "
                                   "the touches part's wall time then counts only new jobs)")
    add_runner_args(p)
    p.set_defaults(func=run)
