"""``tactex experiment humans``: human trials vs the robot (thesis 4.4.1, Fig 5.9, 5.10, Table 5.3).

Input: a human trial file (format in ``config/humans/example.yaml`` and ``docs/research/experiments.md``):
per participant and trial, the visits in order as ``[platform, seconds]`` (0 = reference,
1..C = comparison platforms of the trial file) and the answer (1..C). Optionally the robot's runs
of the same trial file (``--robot``: an ``explore`` results folder or its ``runs.json``).

Computed:

- Humans' accuracy (overall; mean ± std over participants; per trial) and a confusion matrix
  (reference fabric vs chosen fabric), like the robot's.
- Relative time per object: a person's seconds per *comparison* platform, normalised to sum 1.
  The reference is left out: the robot touches the reference exactly once (its first touch is
  the test sample), so including it would measure that design choice, not where attention goes.
  The robot's counterpart is its touches per comparison platform, normalised — at the end of
  the run (``final``) and, as a second view, at the decision where its total touches equal the
  person's number of visits (``matched``; see ``common.decision_at_budget``).
- Jensen–Shannon distance (base 2, in [0, 1]) between those distributions: human–human (every
  pair of participants who did the trial) and human–robot per strategy (every participant x
  robot seed), averaged per trial, then over trials (trials that both sides ran).
- Share of trials in which the most-touched comparison (longest total time for a person) is the
  one predicted; ties count 1/k when the prediction is among k tied objects.
"""

from __future__ import annotations

import argparse
import json
from itertools import combinations
from pathlib import Path
from typing import Any

import numpy as np

from tactex_ros.core.errors import InputError
from tactex_ros.core.paths import config_file, read_yaml
from tactex_lab.analysis import charts, stats
from tactex_lab.experiments.common import decision_at_budget, results_dir, write_json
from tactex_lab.experiments.trials import find_trial_file, load_trials, platform_classes


def find_humans_file(spec: str | None) -> Path:
    """A path, or a name under ``config/humans`` (``example`` = the default)."""
    return config_file(spec or "example", "humans", "human trial file")


def _record(e: dict, pid: str, tid: str, trial: dict, where: str) -> dict:
    """One participant's trial: answer and visits checked, time per comparison summed [s]."""
    C = len(trial["comparisons"])
    ans = e["answer"]
    if not isinstance(ans, int) or isinstance(ans, bool) or not 1 <= ans <= C:
        raise InputError(f"{where}: answer {ans!r} must be a platform 1..{C}")
    time_c = np.zeros(C)
    ref_s = 0.0
    visits = []
    if not isinstance(e["visits"], list) or not e["visits"]:
        raise InputError(f"{where}: visits must be a non-empty list of [platform, seconds]")
    for v in e["visits"]:
        if (not isinstance(v, (list, tuple)) or len(v) != 2 or
                not isinstance(v[0], int) or not 0 <= v[0] <= C or
                not isinstance(v[1], (int, float)) or v[1] < 0):
            raise InputError(f"{where}: visit {v!r} must be [platform 0..{C}, seconds >= 0]")
        visits.append((int(v[0]), float(v[1])))
        if v[0] == 0:
            ref_s += float(v[1])
        else:
            time_c[v[0] - 1] += float(v[1])
    truth = trial["comparisons"].index(trial["reference"]) + 1
    return {"participant": pid, "trial": tid, "visits": visits, "answer": ans,
            "time": time_c.tolist(), "reference_s": ref_s, "n_visits": len(visits),
            "truth": truth, "correct": ans == truth}


def load_humans(path: str | Path, trial_file: str | None = None) -> dict[str, Any]:
    """Parse and check a human trial file against its trial file.

    Returns {"path", "trial_file": <loaded trial file>, "records": [{participant, trial,
    visits: [(platform, seconds)], answer, time (C,), reference_s, n_visits, truth}, ...]}.
    """
    path = Path(path)
    doc = read_yaml(path, "human trial file")
    if not isinstance(doc, dict) or not isinstance(doc.get("participants"), list):
        raise InputError(f"human trial file {path}: needs a list 'participants'")
    tf = load_trials(find_trial_file(trial_file or doc.get("trial_file")))
    trials = {t["id"]: t for t in tf["trials"]}
    records = []
    seen_ids: set[str] = set()
    for pi, part in enumerate(doc["participants"]):
        if not isinstance(part, dict) or "id" not in part or not isinstance(part.get("trials"),
                                                                            list):
            raise InputError(f"{path}: participant {pi + 1} needs 'id' and a list 'trials'")
        pid = str(part["id"])
        if pid in seen_ids:
            raise InputError(f"{path}: duplicate participant id {pid!r}")
        seen_ids.add(pid)
        done: set[str] = set()
        for e in part["trials"]:
            where = f"{path}: participant {pid}"
            if not isinstance(e, dict) or not {"trial", "visits", "answer"} <= set(e):
                raise InputError(f"{where}: each trial needs trial, visits and answer")
            tid = str(e["trial"])
            where += f", trial {tid}"
            if tid not in trials:
                raise InputError(f"{where}: no such trial in {tf['path']}")
            if tid in done:
                raise InputError(f"{where}: listed twice")
            done.add(tid)
            records.append(_record(e, pid, tid, trials[tid], where))
    if not records:
        raise InputError(f"{path}: no human trials")
    return {"path": str(path), "trial_file": tf, "records": records}


def load_robot(spec: str) -> list[dict]:
    """Runs of ``tactex experiment explore``: its results folder or runs.json."""
    p = Path(spec)
    if p.is_dir():
        p = p / "runs.json"
    if not p.is_file():
        raise InputError(f"--robot {spec}: no runs.json of an explore run there")
    try:
        runs = json.loads(p.read_text())
    except json.JSONDecodeError as exc:
        raise InputError(f"--robot {p}: not JSON ({exc})") from None
    if not isinstance(runs, list) or not runs or "final_touches" not in runs[0]:
        raise InputError(f"--robot {p}: not the runs.json of an explore run")
    return runs


def _mean(xs: list[float]) -> float:
    return float(np.mean(xs)) if xs else float("nan")


def _robot_js(rob: list[dict], recs: list[dict], strategies: list[str], h_trials: list[str],
              kind: str) -> dict:
    """Per strategy: JS distance of each person's time to the robot's touches per comparison,
    averaged per trial and over trials; the robot's touches at the end of its run (``final``)
    or at the decision with the person's number of visits (``matched``)."""
    per_s = {}
    for s in strategies:
        per_t = {}
        for t in h_trials:
            rr = [r for r in rob if r["strategy"] == s and r["trial"] == t]
            if not rr:
                continue
            d = []
            for h in (r for r in recs if r["trial"] == t):
                for r in rr:
                    tc = (r["final_touches"] if kind == "final" else
                          decision_at_budget(r["decisions"], h["n_visits"])["touches"])
                    d.append(stats.js_distance(h["time"], tc))
            per_t[t] = _mean(d)
        per_s[s] = {"per_trial": per_t, "mean": _mean(list(per_t.values())),
                    "std": stats.mean_std(per_t.values())["std"]}
    return per_s


def _compare_robot(out: dict, js: dict, recs: list[dict], robot: list[dict],
                   model: str | None, tids: list[str], h_trials: list[str],
                   hh: dict[str, float]) -> None:
    """Add the robot's runs of ``model`` (default: the first) to ``out`` and ``js``."""
    models = sorted({r["model"] for r in robot})
    model = model or models[0]
    if model not in models:
        raise InputError(f"--model {model!r} not in the robot runs ({', '.join(models)})")
    rob = [r for r in robot if r["model"] == model]
    strategies = list(dict.fromkeys(r["strategy"] for r in rob))
    out["robot"] = {"model": model, "strategies": strategies,
                    "trials": sorted({r["trial"] for r in rob}, key=tids.index)}
    for kind in ("final", "matched"):
        js[f"human_robot_{kind}"] = _robot_js(rob, recs, strategies, h_trials, kind)
    common = [t for t in hh if t in js["human_robot_final"][strategies[0]]["per_trial"]]
    js["human_human_on_robot_trials"] = _mean([hh[t] for t in common])
    mt = {}
    for s in strategies:
        rr = [r for r in rob if r["strategy"] == s]
        mt[s] = _mean([stats.tie_share(r["final_touches"], r["prediction"] - 1) for r in rr])
    out["most_touched_is_answer"]["robot"] = mt
    out["robot"]["accuracy"] = {s: _mean([float(r["correct"]) for r in rob
                                          if r["strategy"] == s]) for s in strategies}


def analyse(humans: dict, robot: list[dict] | None, source: str = "sim",
            model: str | None = None) -> dict:
    """Humans' accuracy, confusion, visits, JS distances of their time per comparison among
    themselves and (with ``robot`` runs) to the robot's touches; most-touched = answer."""
    from tactex_lab.experiments.runner import cached_source
    src = cached_source(source)
    tf = humans["trial_file"]
    tids = [t["id"] for t in tf["trials"]]
    classes = {t["id"]: platform_classes(src, t) for t in tf["trials"]}
    recs = humans["records"]
    h_trials = [t for t in tids if any(r["trial"] == t for r in recs)]

    # ---- humans' accuracy and confusion
    parts = sorted({r["participant"] for r in recs}, key=[r["participant"] for r in recs].index)
    per_part = {p: _mean([float(r["correct"]) for r in recs if r["participant"] == p])
                for p in parts}
    per_trial_acc = {t: _mean([float(r["correct"]) for r in recs if r["trial"] == t])
                     for t in h_trials}
    truth_f = [classes[r["trial"]][0] for r in recs]
    pred_f = [classes[r["trial"]][r["answer"]] for r in recs]
    fabrics = sorted({c for t in h_trials for c in classes[t][1:]})
    out: dict[str, Any] = {
        "n_participants": len(parts), "n_trials": len(h_trials), "n_records": len(recs),
        "accuracy": {"overall": _mean([float(r["correct"]) for r in recs]),
                     "over_participants": stats.mean_std(per_part.values()),
                     "per_participant": per_part, "per_trial": per_trial_acc},
        "confusion": {"labels": fabrics,
                      "matrix": stats.confusion(truth_f, pred_f, fabrics).tolist()},
        "visits": {"mean": _mean([r["n_visits"] for r in recs]),
                   "min": int(min(r["n_visits"] for r in recs)),
                   "max": int(max(r["n_visits"] for r in recs)),
                   "reference_time_share": _mean([r["reference_s"] / max(
                       1e-9, r["reference_s"] + sum(r["time"])) for r in recs])},
        "most_touched_is_answer": {"humans": _mean([stats.tie_share(r["time"], r["answer"] - 1)
                                                    for r in recs])},
    }

    # ---- human-human JS distance per trial
    hh = {}
    for t in h_trials:
        rt = [r for r in recs if r["trial"] == t]
        d = [stats.js_distance(a["time"], b["time"]) for a, b in combinations(rt, 2)]
        if d:
            hh[t] = _mean(d)
    js: dict[str, Any] = {"human_human": {"per_trial": hh, "mean": _mean(list(hh.values())),
                                          "std": stats.mean_std(hh.values())["std"]}}

    if robot:
        _compare_robot(out, js, recs, robot, model, tids, h_trials, hh)
    out["js_distance"] = js
    out["notes"] = {
        "distribution": "time (humans) or touches (robot) per comparison platform, normalised;"
                        " the reference is excluded",
        "js": "scipy.spatial.distance.jensenshannon, base 2 (0 = same, 1 = disjoint)",
        "most_touched": "ties count 1/k when the answer is among k tied objects",
    }
    return out


def figures(outdir: Path, res: dict) -> list[str]:
    w = [charts.confusion(outdir / "humans_confusion.png",
                          np.array(res["confusion"]["matrix"]), res["confusion"]["labels"],
                          f"Humans: reference vs chosen fabric "
                          f"(accuracy {100 * res['accuracy']['overall']:.1f} %)")]
    js = res["js_distance"]
    groups = ["human-human"]
    means = [js["human_human"]["mean"]]
    stds = [js["human_human"]["std"]]
    if "robot" in res:
        for s in res["robot"]["strategies"]:
            groups.append(f"human-{s}")
            means.append(js["human_robot_final"][s]["mean"])
            stds.append(js["human_robot_final"][s]["std"])
    w.append(charts.bars(outdir / "js_distance.png", groups,
                         {"mean over trials (± std)": (means, stds)},
                         "Jensen-Shannon distance", "Time/touches per object: JS distance"))
    trials = list(js["human_human"]["per_trial"])
    cols = ["human-human"] + ([f"human-{s}" for s in res["robot"]["strategies"]]
                              if "robot" in res else [])
    table = [[js["human_human"]["per_trial"].get(t, np.nan)] +
             ([js["human_robot_final"][s]["per_trial"].get(t, np.nan)
               for s in res["robot"]["strategies"]] if "robot" in res else []) for t in trials]
    if trials:
        w.append(charts.heatmap(outdir / "js_per_trial.png", np.array(table, dtype=float),
                                [f"trial {t}" for t in trials], cols,
                                "JS distance per trial"))
    mt = res["most_touched_is_answer"]
    groups = ["humans"] + (list(mt["robot"]) if "robot" in mt else [])
    vals = [mt["humans"]] + (list(mt["robot"].values()) if "robot" in mt else [])
    w.append(charts.bars(outdir / "most_touched.png", groups, {"share of trials": (vals, None)},
                         "share", "Most-touched object is the answer"))
    return [str(p) for p in w]


def cmd(args: argparse.Namespace) -> int:
    path = find_humans_file(args.humans)
    humans = load_humans(path, args.trials_file)
    robot = load_robot(args.robot) if args.robot else None
    outdir = results_dir(args.out, "humans", {"humans": str(path), "robot": args.robot,
                                              "source": args.source, "model": args.model})
    res = analyse(humans, robot, args.source, args.model)
    res["figures"] = figures(outdir, res)
    write_json(outdir / "summary.json", {"experiment": "humans", "humans_file": str(path),
                                         "trial_file": humans["trial_file"]["path"], **res})
    if not args.quiet:
        a = res["accuracy"]
        print(f"humans: {res['n_participants']} participants, {res['n_trials']} trials, "
              f"accuracy {100 * a['overall']:.2f} % (participants: "
              f"{100 * a['over_participants']['mean']:.2f} ± "
              f"{100 * a['over_participants']['std']:.2f} %)")
        js = res["js_distance"]
        print(f"JS distance human-human {js['human_human']['mean']:.3f}")
        if "robot" in res:
            for s in res["robot"]["strategies"]:
                print(f"JS distance human-{s} {js['human_robot_final'][s]['mean']:.3f} "
                      f"(matched touches {js['human_robot_matched'][s]['mean']:.3f}); "
                      f"most-touched = prediction "
                      f"{100 * res['most_touched_is_answer']['robot'][s]:.1f} %")
        print(f"humans: most-touched = answer "
              f"{100 * res['most_touched_is_answer']['humans']:.1f} %  -> {outdir}")
    return 0


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("humans", help="human trials vs the robot (thesis Table 5.3)")
    p.add_argument("--humans", default="example",
                   help="human trial file: a path or a name in config/humans (default example)")
    p.add_argument("--trials-file", help="override the file's trial_file")
    p.add_argument("--robot", help="explore results folder (or its runs.json) to compare with")
    p.add_argument("--model", help="model of the robot runs (default: the first)")
    p.add_argument("--source", default="sim", help="resolves fabric numbers to names")
    p.add_argument("--out", help="results folder (default results/humans)")
    p.add_argument("--quiet", action="store_true")
    p.set_defaults(func=cmd)
