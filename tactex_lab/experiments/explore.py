"""``tactex experiment explore``: active exploration on fixed trials (thesis Table 5.2, Fig 5.4-5.7).

Every trial of a trial file (default ``config/trials/human_study.yaml``, the thesis's 32 trials)
runs once per strategy x model x seed, ``--rounds`` decisions after the baseline (thesis: 20).
Jobs run on the job runner (``runner.run_jobs``: ``--workers``, ``--backend joblib|ray``), one
torch thread each.

Seeds: a job's seed is ``1000 * seed + trial position`` — the same for every strategy and model,
so strategies are compared on the same presses and initial weights (paired), and different trials
get independent draws.

Touch budgets without re-running: a decision is recorded with the comparison touches it saw
(``touches``) and its mean softmax (``probs``); the reference is touched once. A trial capped at
``TrialConfig.max_touches = k`` is, touch for touch, the same run up to its final decision, which
is the first decision with total touches ``>= k`` (or the last one, when the rounds run out
first: ``yoto`` never touches again, so its decision at any k > 5 is the one after all rounds).
The accuracy at budget k is read from that record of the full run (``decision_at_budget``); the
test suite checks it against a capped run.

Outputs (``--out``, default ``results/explore``): ``config.json``, ``runs.json`` (one compact
record per job), ``summary.json`` and figures (see ``docs/research/experiments.md``).
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path
from typing import Any

import numpy as np

from tactex_ros.core.config import TrialConfig
from tactex_ros.core.errors import InputError
from tactex_lab.analysis import charts, stats
from tactex_lab.experiments.common import correct_at, learner_set, results_dir, write_json
from tactex_lab.experiments.runner import (TrialJob, TrialResult, add_runner_args, backend_of,
                                           cached_source, run_jobs)
from tactex_lab.experiments.trials import find_trial_file, load_trials, platform_classes

STRATEGIES_DEFAULT = ["variance", "entropy", "random", "yoto"]
BUDGETS_DEFAULT = [5, 6, 7, 8, 9]
# thesis Table 5.2: accuracy with a touch budget matched to the humans (5-9 touches per trial)
THESIS_MATCHED = {"humans": 0.6688, "variance": 0.9000, "entropy": 0.8813, "random": 0.8938,
                  "yoto": 0.8063}


# ---------------------------------------------------------------------------------- helpers
def compact(res: TrialResult) -> dict:
    """A runner result -> the record kept in runs.json (platforms by name)."""
    job, out = res.job, res.outcome
    if out is None:
        raise RuntimeError(f"trial {job.trial_id!r} failed: {res.error}")
    decisions = []
    for r in res.decisions:
        decisions.append({"probs": [round(p, 5) for p in r.probs],
                          "touches": list(r.touches), "total": int(sum(r.touches)) + 1,
                          "entropy": round(r.predictive_entropy, 5),
                          "next": None if r.platform is None else out.platform_ids[r.platform],
                          "decision_s": round(r.decision_s, 4)})
    return {"trial": job.tags["trial"], "strategy": job.trial.strategy,
            "model": job.tags["model"], "seed": job.tags["seed"], "job_seed": job.seed,
            "classes": res.classes, "truth": res.truth,
            "prediction": res.prediction, "correct": res.correct,
            "touches": res.touches, "final_touches": list(out.final.touches),
            "decisions": decisions, "wall_s": round(res.wall_s, 3),
            "failed_touches": res.failed_touches}


def build_jobs(trials: list[dict], source: str, strategies: list[str], models: list[str],
               seeds: list[int], rounds: int, preset_name: str, overrides: dict[str, Any],
               weights: str | None) -> list[TrialJob]:
    from tactex_ros.core.config import preset
    src = cached_source(source)
    jobs = []
    for model in models:
        over = dict(overrides, model=model)
        if model == "inception_v3":
            if not weights:
                raise InputError("model inception_v3 needs --weights (a torchvision checkpoint);"
                                 " use inception_v3_random for random weights")
            over["weights"] = str(weights)
        preset(preset_name, **over)  # validate once, here, with a readable error
        for seed in seeds:
            for pos, t in enumerate(trials):
                classes = platform_classes(src, t)
                for strat in strategies:
                    jobs.append(TrialJob(source=source, seed=1000 * seed + pos,
                                         trial=TrialConfig(strategy=strat, rounds=rounds,
                                                           stop_confidence=0.0),
                                         preset=preset_name, overrides=over,
                                         platform_classes=classes, trial_id=t["id"],
                                         tags={"trial": t["id"], "model": model, "seed": seed}))
    return jobs


# ---------------------------------------------------------------------------------- summary
def _acc_block(correct: list[bool], seeds_of: list[int]) -> dict:
    """Accuracy of paired runs, its spread over seeds and over runs, Wilson interval."""
    c = np.asarray(correct, dtype=float)
    per_seed = [float(c[np.asarray(seeds_of) == s].mean()) for s in sorted(set(seeds_of))]
    lo, hi = stats.wilson(int(c.sum()), c.size)
    return {"accuracy": float(c.mean()) if c.size else float("nan"),
            "std_over_seeds": stats.mean_std(per_seed)["std"],
            "std_over_trials_and_seeds": float(c.std(ddof=1)) if c.size > 1 else 0.0,
            "ci95": [lo, hi], "correct": int(c.sum()), "n": int(c.size)}


def _budget_block(runs_s: list[dict], budgets: list[int]) -> tuple[dict, list[float]]:
    """Accuracy at every budget and at the matched budget (mean correctness over the budgets);
    also the per-run matched correctness (for the paired tests)."""
    seeds_of = [r["seed"] for r in runs_s]
    per_k = {}
    matched = np.zeros(len(runs_s))
    for k in budgets:
        ck = [correct_at(r["decisions"], r["truth"], k) for r in runs_s]
        per_k[str(k)] = _acc_block(ck, seeds_of)
        matched += np.asarray(ck, dtype=float)
    matched /= max(1, len(budgets))
    per_seed = [float(matched[np.asarray(seeds_of) == sd].mean())
                for sd in sorted(set(seeds_of))]
    block = {"per_budget": per_k, "matched": {
        "accuracy": float(matched.mean()) if matched.size else float("nan"),
        "std_over_seeds": stats.mean_std(per_seed)["std"],
        "std_over_trials_and_seeds": float(matched.std(ddof=1)) if matched.size > 1
        else 0.0, "budgets": budgets, "n": int(matched.size)}}
    return block, matched.tolist()


def _curves(runs_s: list[dict]) -> dict:
    """Mean accuracy, entropy, p(true match) and touches per decision over the runs."""
    n_dec = min(len(r["decisions"]) for r in runs_s)
    acc_r = np.array([[np.argmax(r["decisions"][j]["probs"]) + 1 == r["truth"]
                       for j in range(n_dec)] for r in runs_s], dtype=float)
    ent_r = np.array([[r["decisions"][j]["entropy"] for j in range(n_dec)] for r in runs_s])
    ptrue = np.array([[r["decisions"][j]["probs"][r["truth"] - 1] for j in range(n_dec)]
                      for r in runs_s])
    tot = np.array([[r["decisions"][j]["total"] for j in range(n_dec)] for r in runs_s])
    return {"decision": list(range(1, n_dec + 1)), "accuracy": acc_r.mean(0).tolist(),
            "entropy_mean": ent_r.mean(0).tolist(), "entropy_std": ent_r.std(0).tolist(),
            "p_true_mean": ptrue.mean(0).tolist(), "touches_mean": tot.mean(0).tolist()}


def _paired_tests(by_s: dict[str, list[dict]], matched: dict[str, list[float]],
                  budgets: list[int]) -> dict:
    strategies = list(by_s)
    return {
        "fixed_rounds": stats.pairwise_tests({s: [r["correct"] for r in by_s[s]]
                                              for s in strategies}, "mcnemar"),
        "matched_budget": stats.pairwise_tests(matched, "wilcoxon"),
        "per_budget": {str(k): stats.pairwise_tests(
            {s: [correct_at(r["decisions"], r["truth"], k) for r in by_s[s]]
             for s in strategies}, "mcnemar") for k in budgets},
        "note": "pairs are (trial, seed); fixed rounds and each budget: exact McNemar on "
                "correct/incorrect; matched budget (mean correctness over the budgets): "
                "Wilcoxon signed-rank; p_holm: Holm-adjusted over the strategy pairs",
    }


def summarise(runs: list[dict], strategies: list[str], budgets: list[int],
              trial_ids: list[str]) -> dict:
    """Accuracies, curves, per-trial table, confusions and paired tests per model."""
    out: dict[str, Any] = {}
    models = sorted({r["model"] for r in runs}, key=[r["model"] for r in runs].index)
    for model in models:
        rr = [r for r in runs if r["model"] == model]
        by_s = {s: sorted((r for r in rr if r["strategy"] == s),
                          key=lambda r: (r["seed"], trial_ids.index(r["trial"])))
                for s in strategies}
        keys = {s: [(r["trial"], r["seed"]) for r in by_s[s]] for s in strategies}
        if len({tuple(k) for k in keys.values()}) > 1:
            raise InputError("strategies ran on different trials/seeds; cannot pair them")
        fixed, budget, matched, curves, per_trial, conf, shares = {}, {}, {}, {}, {}, {}, {}
        fabrics = sorted({c for r in rr for c in r["classes"][1:]})
        for s, runs_s in by_s.items():
            fixed[s] = _acc_block([r["correct"] for r in runs_s], [r["seed"] for r in runs_s])
            budget[s], matched[s] = _budget_block(runs_s, budgets)
            curves[s] = _curves(runs_s)
            per_trial[s] = {t: float(np.mean([r["correct"] for r in runs_s if r["trial"] == t]))
                            for t in trial_ids if any(r["trial"] == t for r in runs_s)}
            truth_f = [r["classes"][0] for r in runs_s]
            pred_f = [r["classes"][r["prediction"]] for r in runs_s]
            conf[s] = {"labels": fabrics,
                       "matrix": stats.confusion(truth_f, pred_f, fabrics).tolist()}
            # share of comparison touches spent on the true match (at the end of the run)
            sh = [r["final_touches"][r["truth"] - 1] / max(1, sum(r["final_touches"]))
                  for r in runs_s]
            shares[s] = stats.mean_std(sh)
        tests = _paired_tests(by_s, matched, budgets)
        out[model] = {"fixed_rounds": fixed, "budget": budget, "curves": curves,
                      "per_trial": per_trial, "confusion": conf, "tests": tests,
                      "touch_share_on_match": shares,
                      "any_significant": {
                          "fixed_rounds": any(t["significant"] for t in tests["fixed_rounds"]),
                          "matched_budget": any(t["significant"]
                                                for t in tests["matched_budget"])}}
    return out


def figures(outdir: Path, summary: dict, strategies: list[str], budgets: list[int],
            rounds: int) -> list[str]:
    written = []
    multi = len(summary) > 1
    for model, m in summary.items():
        sfx = f"_{model}" if multi else ""
        fixed = m["fixed_rounds"]
        matched = {s: m["budget"][s]["matched"] for s in strategies}
        written.append(charts.bars(
            outdir / f"accuracy{sfx}.png", strategies,
            {f"{rounds} rounds": ([fixed[s]["accuracy"] for s in strategies],
                                  [fixed[s]["std_over_seeds"] for s in strategies]),
             f"budget {budgets[0]}-{budgets[-1]} touches": (
                 [matched[s]["accuracy"] for s in strategies],
                 [matched[s]["std_over_seeds"] for s in strategies])},
            "accuracy", f"Accuracy per strategy ({model})",
            reference={"thesis, human-matched budget": [THESIS_MATCHED.get(s)
                                                        for s in strategies]}))
        cv = m["curves"]
        x = cv[strategies[0]]["decision"]
        written.append(charts.lines(
            outdir / f"accuracy_vs_round{sfx}.png", x,
            {s: (cv[s]["accuracy"], None) for s in strategies}, "decision (1 = after baseline)",
            "accuracy", f"Accuracy against the round ({model})", ylim=(0, 1.02)))
        written.append(charts.lines(
            outdir / f"uncertainty_vs_round{sfx}.png", x,
            {s: (cv[s]["entropy_mean"], cv[s]["entropy_std"]) for s in strategies},
            "decision (1 = after baseline)", "predictive entropy [nats]",
            f"Uncertainty against the round ({model})"))
        ks = sorted(int(k) for k in m["budget"][strategies[0]]["per_budget"])
        written.append(charts.lines(
            outdir / f"accuracy_vs_budget{sfx}.png", ks,
            {s: ([m["budget"][s]["per_budget"][str(k)]["accuracy"] for k in ks], None)
             for s in strategies}, "touch budget (total touches incl. baseline)", "accuracy",
            f"Accuracy at a touch budget ({model})", ylim=(0, 1.02),
            hlines={"humans (thesis)": THESIS_MATCHED["humans"]}))
        tids = list(m["per_trial"][strategies[0]])
        table = np.array([[m["per_trial"][s].get(t, np.nan) for s in strategies] for t in tids])
        written.append(charts.heatmap(outdir / f"per_trial{sfx}.png", table,
                                      [f"trial {t}" for t in tids], strategies,
                                      f"Accuracy per trial ({model}, {rounds} rounds)"))
        labels = m["confusion"][strategies[0]]["labels"]
        written.append(charts.confusion_grid(
            outdir / f"confusion{sfx}.png",
            {s: np.array(m["confusion"][s]["matrix"]) for s in strategies}, labels,
            suptitle=f"Reference fabric vs chosen fabric ({model}, {rounds} rounds)"))
    return [str(w) for w in written]


# ---------------------------------------------------------------------------------- command
def run(args: argparse.Namespace) -> dict:
    t0 = time.perf_counter()
    tf = load_trials(find_trial_file(args.trials_file))
    trials = tf["trials"]
    if args.trials:
        want = [t.strip() for t in args.trials.split(",") if t.strip()]
        unknown = [w for w in want if w not in {t["id"] for t in trials}]
        if unknown:
            raise InputError(f"--trials: unknown trial id(s) {unknown} in {tf['path']}")
        trials = [t for t in trials if t["id"] in want]
    from tactex_ros.core.strategies import STRATEGIES
    for s in args.strategies:
        if s not in STRATEGIES:
            raise InputError(f"unknown strategy {s!r}; choose from {', '.join(STRATEGIES)}")
    budgets = sorted(set(args.budgets))
    if not budgets or budgets[0] < 1:
        raise InputError("--budgets must be positive touch counts")
    overrides = learner_set(args.set)
    jobs = build_jobs(trials, args.source, args.strategies, args.models, args.seeds,
                      args.rounds, args.config, overrides, args.weights)
    backend = backend_of(args).resolved()
    workers = backend.workers
    config = {"trial_file": tf["path"], "trials": [t["id"] for t in trials],
              "source": args.source, "strategies": args.strategies, "models": args.models,
              "seeds": args.seeds, "rounds": args.rounds, "budgets": budgets,
              "preset": args.config, "overrides": overrides, "weights": args.weights,
              "workers": workers, "backend": backend.name, "jobs": len(jobs)}
    outdir = results_dir(args.out, "explore", config)
    if not args.quiet:
        print(f"explore: {len(trials)} trials x {len(args.strategies)} strategies x "
              f"{len(args.models)} models x {len(args.seeds)} seeds = {len(jobs)} trials, "
              f"{workers} workers -> {outdir}", flush=True)
    results = run_jobs(jobs, backend, threads=args.threads, description="explore",
                       quiet=args.quiet)
    runs = [compact(r) for r in results]
    write_json(outdir / "runs.json", runs)
    summary = summarise(runs, args.strategies, budgets, [t["id"] for t in trials])
    dec = [d["decision_s"] for r in runs for d in r["decisions"]]
    wall = time.perf_counter() - t0
    doc = {"experiment": "explore", "settings": config,
           "thesis_reference": {"matched_budget_accuracy": THESIS_MATCHED,
                                "note": "thesis Table 5.2; differences not significant there"},
           "timing": {"wall_s": wall, "workers": workers, "threads_per_worker": args.threads,
                      "decisions": len(dec), "decision_s_median": float(np.median(dec)),
                      "decision_s_mean": float(np.mean(dec)),
                      "trial_wall_s_median": float(np.median([r["wall_s"] for r in runs]))},
           "models": summary}
    doc["figures"] = figures(outdir, summary, args.strategies, budgets, args.rounds)
    write_json(outdir / "summary.json", doc)
    if not args.quiet:
        print_summary(doc, args.strategies)
    return doc


def print_summary(doc: dict, strategies: list[str]) -> None:
    r = doc["settings"]["rounds"]
    b = doc["settings"]["budgets"]
    for model, m in doc["models"].items():
        print(f"model {model}: accuracy ({r} rounds | budget {b[0]}-{b[-1]} touches)")
        for s in strategies:
            f, mb = m["fixed_rounds"][s], m["budget"][s]["matched"]
            print(f"  {s:9s} {100 * f['accuracy']:6.2f} % ± {100 * f['std_over_seeds']:.2f} | "
                  f"{100 * mb['accuracy']:6.2f} % ± {100 * mb['std_over_seeds']:.2f}"
                  f"   (thesis budget: {100 * THESIS_MATCHED.get(s, float('nan')):.2f} %)")
        sig = m["any_significant"]
        print(f"  paired tests: significant difference (Holm, 0.05): fixed rounds "
              f"{'yes' if sig['fixed_rounds'] else 'no'}, matched budget "
              f"{'yes' if sig['matched_budget'] else 'no'}")
    t = doc["timing"]
    print(f"wall {t['wall_s']:.1f} s, decision median {t['decision_s_median']:.3f} s "
          f"({t['decisions']} decisions, {t['workers']} workers)")


def cmd(args: argparse.Namespace) -> int:
    run(args)
    return 0


def register(sub: argparse._SubParsersAction) -> None:
    from tactex_ros.core.config import PRESETS
    p = sub.add_parser("explore", help="strategies on fixed trials (thesis Table 5.2)")
    p.add_argument("--trials-file", default="human_study",
                   help="trial file: a path or a name in config/trials (default human_study)")
    p.add_argument("--trials", help="comma-separated trial ids to run (default all)")
    p.add_argument("--source", default="sim",
                   help="touch source (default sim; trial files name catalogue fabrics, so the "
                        "sim difficulty does not apply)")
    p.add_argument("--strategies", nargs="+", default=STRATEGIES_DEFAULT)
    p.add_argument("--models", nargs="+", default=["small_inception"])
    p.add_argument("--weights", help="torchvision checkpoint for model inception_v3")
    p.add_argument("--seeds", type=int, nargs="+", default=[0])
    p.add_argument("--rounds", type=int, default=20)
    p.add_argument("--budgets", type=int, nargs="+", default=BUDGETS_DEFAULT,
                   help="total-touch budgets (baseline of 5 included) read from the runs")
    p.add_argument("--config", default="cnn", help=f"learner preset: {', '.join(PRESETS)}")
    p.add_argument("--set", action="append", metavar="PATH=VALUE",
                   help="learner override, e.g. --set learner.input_size=32 (repeatable)")
    p.add_argument("--out", help="results folder (default results/explore)")
    add_runner_args(p)
    p.set_defaults(func=cmd)
