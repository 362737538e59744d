"""``tactex experiment sim-embedding``: train the small CNN on the simulator's fabrics only and
write it as the product's numpy weights file (``tactex_ros/core/embedding.py``).

This is how the shipped ``tactex_ros/core/data/embedding_sim.npz`` is made: nothing recorded
(no ``../shared`` press) goes into it. The training set is ``learned_features.sim_training_set``
(the 25 catalogue fabrics and ``--variants`` more drawn around them, ``--per-class`` presses
each in the recorded mode); the network, its steps and its input scale are
``learned_features.train_cnn``'s, on one torch thread (the same seed gives the same file on the
same torch build). docs/research/unseen_materials.md, "A network trained on the simulator's
fabrics", screens it class-disjoint on both real libraries.
"""

from __future__ import annotations

import argparse
import platform
from pathlib import Path

from tactex_ros.core.errors import InputError
from tactex_lab.analysis.learned_features import AUGS


def make(cache_dir: str | Path, out: str | Path, seed: int = 0, steps: int = 1500,
         variants: int = 150, per_class: int = 8, norm: str = "global",
         aug: str = "geometric") -> dict:
    """Train on ``sim_training_set(cache_dir, variants, per_class)`` and write the weights file
    ``out``; returns its ``trained_on`` record."""
    import torch

    from tactex_lab.analysis import learned_features as lf
    train = lf.sim_training_set(cache_dir, variants=variants, per_class=per_class)
    body, log = lf.train_cnn(train["half"], train["cls"], steps=steps, seed=seed, norm=norm,
                             aug=aug)
    trained_on = {"source": "sim:0:recorded", "catalogue_fabrics": 25, "variants": variants,
                  "per_class": per_class, "presses": int(len(train["cls"])),
                  "classes": int(len(set(train["cls"].tolist()))), "seed": seed,
                  "steps": steps, "norm": norm, "aug": aug, "final_loss": round(log["loss"], 4),
                  "train_seconds": round(log["seconds"], 1), "torch": torch.__version__,
                  "python": platform.python_version(), "recorded_presses": 0}
    emb = lf.to_embedding(body, log, trained_on)
    Path(out).parent.mkdir(parents=True, exist_ok=True)
    emb.save(out)
    return trained_on


def register(esub: argparse._SubParsersAction) -> None:
    p = esub.add_parser("sim-embedding", help="train the small CNN on the simulator's fabrics "
                                              "only and write the product's numpy weights file")
    p.add_argument("--cache-dir", required=True,
                   help="where the rendered training presses are cached (e.g. under /tmp)")
    p.add_argument("--out", required=True,
                   help="weights file to write (.npz; the shipped one is "
                        "tactex_ros/core/data/embedding_sim.npz)")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--steps", type=int, default=1500, help="training steps")
    p.add_argument("--variants", type=int, default=150,
                   help="simulated fabrics drawn beside the 25 catalogue ones")
    p.add_argument("--per-class", type=int, default=8, help="presses of each fabric")
    p.add_argument("--norm", choices=("global", "image"), default="global",
                   help="the network's input scale (learned_features.train_cnn)")
    p.add_argument("--aug", choices=AUGS, default="geometric",
                   help="the training's augmentation (learned_features.train_cnn)")

    def func(args: argparse.Namespace) -> int:
        for name, low in (("steps", 1), ("variants", 0), ("per_class", 2), ("seed", 0)):
            if getattr(args, name) < low:
                raise InputError(f"--{name.replace('_', '-')} must be >= {low}, "
                                 f"got {getattr(args, name)}")
        Path(args.cache_dir).mkdir(parents=True, exist_ok=True)
        rec = make(args.cache_dir, args.out, args.seed, args.steps, args.variants,
                   args.per_class, args.norm, args.aug)
        print(f"embedding trained on {rec['classes']} simulated fabrics ({rec['presses']} "
              f"presses), {rec['steps']} steps, loss {rec['final_loss']} -> {args.out}")
        return 0

    p.set_defaults(func=func)
