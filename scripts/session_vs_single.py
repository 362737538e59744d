#!/usr/bin/env python3
"""Run every trial of a finished study session again on its own (one graph start per trial,
the same placement as the mock camera's scene, the same seed and settings) and compare the
answers and the accuracy with the session's.

    .venv/bin/python scripts/session_vs_single.py SESSION_DIR OUT_DIR [--domain-id N]

Writes OUT_DIR/<trial record>/ (one record per trial) and OUT_DIR/comparison.json.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path


def main(argv: list[str] | None = None) -> int:
    from tactex_ros.trial import session as sess
    from tactex_ros.trial.record import read_result
    from tactex_ros.ros.graph import describe
    from tactex_ros.ros.devrun.launcher import run_graph

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("session_dir")
    ap.add_argument("out_dir")
    ap.add_argument("--domain-id", type=int, default=None)
    ap.add_argument("--timeout", type=float, default=900.0)
    args = ap.parse_args(argv)
    d, out = Path(args.session_dir), Path(args.out_dir).resolve()
    summ = sess.summary(d)
    rows = []
    for r in summ["trials"]:
        if not r["done"]:
            continue
        rec = d / r["record"]
        cfg = json.loads((rec / "config.json").read_text())
        if (out / r["record"] / "result.json").is_file():
            single = read_result(out / r["record"])
        else:
            nodes = describe(True, rec / "scene.yaml", explorer={
                "config": cfg["explorer"]["config"], "seed": cfg["explorer"]["seed"],
                "learner": cfg["learner"], "trial": cfg["trial"], "record_dir": str(out),
                "trial_id": r["record"]})
            run = run_graph(nodes, out / "logs" / r["record"], timeout_s=args.timeout,
                            domain_id=args.domain_id)
            single = run.result or {"error": run.failure}
        pred = single.get("prediction")
        rows.append({"trial": r["id"], "seed": r["seed"], "session": r["prediction"],
                     "single": pred, "same_answer": pred == r["prediction"],
                     "session_touches": r["touches"], "single_touches": single.get("touches"),
                     "session_correct": r["correct"], "single_correct": pred in r["truth"]})
        print(json.dumps(rows[-1]), flush=True)
    n = len(rows)
    res = {"trials": n,
           "session_accuracy": sum(x["session_correct"] for x in rows) / n if n else None,
           "single_accuracy": sum(x["single_correct"] for x in rows) / n if n else None,
           "same_answers": sum(x["same_answer"] for x in rows),
           "same_touches": sum(x["session_touches"] == x["single_touches"] for x in rows),
           "rows": rows}
    out.mkdir(parents=True, exist_ok=True)
    (out / "comparison.json").write_text(json.dumps(res, indent=2))
    print(json.dumps({k: v for k, v in res.items() if k != "rows"}))
    return 0


if __name__ == "__main__":
    sys.exit(main())
