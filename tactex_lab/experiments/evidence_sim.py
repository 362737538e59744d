"""``tactex experiment evidence-sim``: fit the e-value stop rule's evidence model
(``tactex_ros/core/evidence.py``) on the simulator's fabrics only and write the product's
shipped ``tactex_ros/core/data/evidence_sim.json``. Nothing recorded goes into it: the 25
catalogue fabrics, ``--per-class`` simulated presses each, described with the shipped default
learner settings (the space is stored with the model and checked where it is used).
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np

from tactex_ros.core.errors import InputError


def make(out: str | Path, per_class: int = 4, seed: int = 0) -> dict:
    """Fit on ``per_class`` presses of every catalogue fabric (``sim:0``, seed ``seed``) and
    write ``out``; returns what was written."""
    from tactex_ros import sources
    from tactex_ros.core.config import preset
    from tactex_ros.core.descriptor import raw_descriptor
    from tactex_ros.core.evidence import descriptor_space, fit_evidence

    cfg = preset("default")
    src = sources.open_source("sim:0")
    names = list(src.classes)
    touch = src.trial(names, seed)
    desc = {n: np.stack([raw_descriptor(touch(i), cfg) for _ in range(per_class)])
            for i, n in enumerate(names)}
    model = fit_evidence(desc, seed=seed)
    rec = {"model": model.to_dict(), "space": descriptor_space(cfg),
           "trained_on": {"source": "sim:0", "classes": len(names), "per_class": per_class,
                          "seed": seed}}
    Path(out).parent.mkdir(parents=True, exist_ok=True)
    Path(out).write_text(json.dumps(rec, indent=1) + "\n")
    return rec


def register(esub: argparse._SubParsersAction) -> None:
    p = esub.add_parser("evidence-sim", help="fit the e-value stop rule's evidence model on the "
                                             "simulator's fabrics and write the shipped file")
    p.add_argument("--file", required=True, help="JSON file to write (the shipped one is "
                                                "tactex_ros/core/data/evidence_sim.json)")
    p.add_argument("--per-class", type=int, default=4, help="presses of each fabric (>= 2)")
    p.add_argument("--seed", type=int, default=0)

    def func(args: argparse.Namespace) -> int:
        if args.per_class < 2:
            raise InputError(f"--per-class must be >= 2, got {args.per_class}")
        rec = make(args.file, args.per_class, args.seed)
        print(f"evidence model {rec['model']} from {rec['trained_on']['classes']} simulated "
              f"fabrics -> {args.file}")
        return 0

    p.set_defaults(func=func)
