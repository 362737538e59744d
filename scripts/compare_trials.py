#!/usr/bin/env python3
"""Compare two folders of `tactex trial --json` outputs file by file, without timing fields.

    python scripts/compare_trials.py BEFORE_DIR AFTER_DIR

Files are grouped by the name before the first ``_`` (e.g. ``sim_3.json`` -> ``sim``). Each pair
is compared twice: the whole JSON without the timing fields (``*_s`` of a round, ``cpu_s``,
``seconds``), floats rounded to 6 decimals; and the outcome fields only (prediction, truth,
touches, stop reason, classes, and every round's platform, belief, scores, touches, model).
Prints one line per group: how many were compared and how many were identical each way.

Both sides are read in today's shape: a file written before rounds had a learner-typed
``detail`` (``train_loss``, ``input_size``, ... beside the common fields; a descriptor's were
placeholders) is converted first (``upgrade``, with ``tactex_ros.core.engine.training_of``),
so outcomes of the two shapes compare field by field.
"""

from __future__ import annotations

import json
import math
import sys
from pathlib import Path

TIMING = {"train_s", "score_s", "choose_s", "cpu_s", "decision_s", "seconds"}
ROUND_FIELDS = ("round", "platform", "probs", "scores", "touches", "reference_touches", "model",
                "heldout", "degenerate", "predictive_entropy", "detail")


def upgrade(d: dict) -> dict:
    """A trial JSON in today's shape: every round's training fields in its ``detail`` (None for
    a learner that trains nothing), ``models`` / ``escalations`` labelled from it."""
    from tactex_ros.core.engine import TRAINING_FIELDS, training_of
    rounds = []
    for r in d.get("rounds", []) + [d.get("final")]:
        if r is None or "detail" in r:
            rounds.append(r)
            continue
        t = training_of(r)
        r = {k: v for k, v in r.items() if k not in TRAINING_FIELDS}
        r["detail"] = {**t, "kind": "training"} if t else None
        rounds.append(r)
    out = {**d, "rounds": rounds[:-1], "final": rounds[-1]}
    label = {r["round"]: (r["model"] if not r["detail"] else
                          f"{r['model']}@{r['detail']['input_size']}") for r in rounds if r}
    if "models" in d:
        out["models"] = sorted(set(label.values()))
    if "escalations" in d:
        out["escalations"] = [{**e, "model": label.get(e["round"], e["model"])}
                              for e in d["escalations"]]
    return out
TRIAL_FIELDS = ("prediction", "truth", "correct", "touches", "stop_reason", "reference_touches",
                "failed_touches", "prediction_class", "truth_class", "classes")


def norm(x):
    """``x`` without timing fields, floats to 6 decimals (NaN as a string)."""
    if isinstance(x, dict):
        return {k: norm(v) for k, v in x.items() if k not in TIMING}
    if isinstance(x, list):
        return [norm(v) for v in x]
    if isinstance(x, float):
        return "nan" if math.isnan(x) else round(x, 6)
    return x


def outcome(d: dict) -> dict:
    """The outcome fields of a trial JSON, normalised."""
    rounds = d.get("rounds", []) + [d.get("final")]
    return {**{k: norm(d.get(k)) for k in TRIAL_FIELDS},
            "rounds": [{k: norm((r or {}).get(k)) for k in ROUND_FIELDS} for r in rounds]}


def main(before: Path, after: Path) -> int:
    groups: dict[str, list] = {}
    for f in sorted(before.glob("*.json")):
        g = groups.setdefault(f.stem.split("_")[0], [0, 0, 0, []])
        g[0] += 1
        other = after / f.name
        if not other.is_file():
            g[3].append(f"{f.name} (missing)")
            continue
        a, b = upgrade(json.loads(f.read_text())), upgrade(json.loads(other.read_text()))
        g[1] += norm(a) == norm(b)
        if outcome(a) == outcome(b):
            g[2] += 1
        else:
            g[3].append(f.name)
    for name, (n, full, out, bad) in groups.items():
        print(f"{name}: {n} compared, {full} identical (whole JSON), {out} identical (outcome "
              f"fields)" + (f"; differ: {', '.join(bad)}" if bad else ""))
    return 0 if all(g[2] == g[0] for g in groups.values()) else 1


if __name__ == "__main__":
    if len(sys.argv) != 3:
        print(__doc__, file=sys.stderr)
        sys.exit(2)
    sys.exit(main(Path(sys.argv[1]), Path(sys.argv[2])))
