"""``tactex experiment saliency``: Input x Gradient and Grad-CAM maps (thesis 2.4, 5.5, A.2).

Two parts, both on ``--source`` (default: the simulator; ``replay:DIR`` for recorded presses),
spatial inputs and, with ``--fourier both|on``, log-magnitude Fourier inputs
(``learner.fourier``; thesis appendix A.2):

- **classify**: a classifier over ``--classes`` classes trained from scratch on all presses of a
  class but one (``--rounds`` rounds of the learner's schedule), for ``--folds`` folds (fold f
  holds out press f of every class). Held-out accuracy per input kind (spatial / Fourier), and
  for fold 0 the maps of the held-out press of every class (one image per class), target = the
  true class: ``classify_<kind>.png`` (rows: classes; columns: input, Input x Gradient, Grad-CAM).
- **explore**: one active-exploration trial (variance strategy) over the first 4 of those
  classes, the reference being class ``--reference``. The fixed validation set is one press per
  comparison class that the trial never touches; after every round the maps of the current model
  on it are computed: ``explore_<kind>_rounds.png`` (rows: classes; per round a Grad-CAM overlay)
  and ``explore_<kind>_round<r>.png`` for the first and last round (input, IxG, Grad-CAM).

Outputs: ``summary.json`` (accuracies, per-round validation accuracy and the mean map
concentration, classes and presses used) and the figures.
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np
import torch

from tactex_ros.core.config import preset
from tactex_ros.core.config import TrialConfig
from tactex_ros.core.engine import TrialSpec
from tactex_ros.core.errors import InputError
from tactex_lab.cnn.learner import OnlineLearner
from tactex_lab.cnn.saliency import display_image, grad_cam, input_x_gradient
from tactex_lab.analysis import charts
from tactex_lab.experiments.common import progress, results_dir, write_json


class Pool:
    """Presses per class: replay files (fixed, few) or simulator presses (fresh, seeded)."""

    def __init__(self, spec: str, n_classes: int, per_class: int, seed: int) -> None:
        from tactex_ros.sources import open_source
        self.src = open_source(spec)
        self.kind = spec.partition(":")[0]
        rng = np.random.default_rng([seed, 41])
        if self.kind == "replay":
            ok = [c for c in self.src.classes if len(self.src.presses(c)) >= 5]
            if len(ok) < n_classes:
                raise InputError(f"{spec}: only {len(ok)} classes with >= 5 presses")
            self.classes = sorted(rng.choice(ok, n_classes, replace=False).tolist())
            self.frames = {c: [self.src.frame(p) for p in self.src.presses(c)]
                           for c in self.classes}
        else:
            names = self.src.classes
            self.classes = sorted(rng.choice(names, n_classes, replace=False).tolist())
            self.frames = {c: [self.src.press(c, rng) for _ in range(per_class)]
                           for c in self.classes}

    def split(self, fold: int) -> tuple[dict, dict]:
        """(train frames per class, held-out frame per class) for ``fold``."""
        train, held = {}, {}
        for c, fr in self.frames.items():
            k = fold % len(fr)
            held[c] = fr[k]
            train[c] = [f for i, f in enumerate(fr) if i != k]
        return train, held


def concentration(maps: np.ndarray, top: float = 0.1) -> float:
    """Share of the total map mass in its top ``top`` fraction of pixels (1/N..1)."""
    m = maps.reshape(len(maps), -1)
    k = max(1, int(top * m.shape[1]))
    s = np.sort(m, axis=1)[:, ::-1]
    return float(np.mean(s[:, :k].sum(1) / np.maximum(s.sum(1), 1e-12)))


def maps_for(learner: OnlineLearner, frames: list[np.ndarray], targets: list[int]):
    x = torch.cat([learner.test_tensor(f) for f in frames])
    probs = learner.predict_proba(x)
    ixg = input_x_gradient(learner.model, x, targets)
    cam = grad_cam(learner.model, x, targets)
    return display_image(x, learner.cfg.fourier), ixg, cam, probs


def run_classify(args, pool: Pool, kind: str, out: Path) -> dict:
    fourier = kind == "fourier"
    cfg = preset(args.config, fourier=fourier, **({"input_size": args.input_size}
                                                  if args.input_size else {}))
    correct, n = 0, 0
    fold0 = None
    for fold in progress(range(args.folds), f"classify ({kind})", args.folds, args.quiet):
        train, held = pool.split(fold)
        L = OnlineLearner(len(pool.classes), cfg, seed=args.seed + fold)
        for k, c in enumerate(pool.classes):
            for f in train[c]:
                L.add_touch(f, k)
        for _ in range(args.rounds):
            L.train_round()
        frames = [held[c] for c in pool.classes]
        targets = list(range(len(pool.classes)))
        if fold == 0:
            fold0 = maps_for(L, frames, targets)
            probs = fold0[3]
        else:
            probs = L.predict_proba(torch.cat([L.test_tensor(f) for f in frames]))
        correct += int(sum(int(np.argmax(p)) == t for p, t in zip(probs, targets, strict=True)))
        n += len(targets)
    imgs, ixg, cam, probs = fold0
    charts.saliency_rows(out / f"classify_{kind}.png", pool.classes, imgs, ixg, cam, probs,
                list(range(len(pool.classes))),
                f"classifier, {kind} inputs ({cfg.input_size} px); held-out press per class "
                f"(fold 0)")
    return {"kind": kind, "held_out_accuracy": correct / n, "correct": correct, "n": n,
            "folds": args.folds, "input_size": cfg.input_size,
            "ixg_concentration_top10": concentration(ixg),
            "gradcam_concentration_top10": concentration(cam)}


def run_explore(args, pool: Pool, kind: str, out: Path) -> dict:
    fourier = kind == "fourier"
    cfg = preset(args.config, fourier=fourier, **({"input_size": args.input_size}
                                                  if args.input_size else {}))
    comps = pool.classes[:4]
    ref_cls = comps[args.reference % len(comps)]
    train, held = pool.split(0)
    val = [held[c] for c in comps]
    used = {c: 0 for c in comps}

    def touch(p: int) -> np.ndarray:
        c = ref_cls if p == 0 else comps[p - 1]
        fr = train[c]
        if p == 0:
            return fr[-1]       # the reference press; comparisons cycle through the others
        i = used[c] % max(1, len(fr) - (1 if c == ref_cls else 0))
        used[c] += 1
        return fr[i]
    spec = TrialSpec(len(comps), cfg, TrialConfig(strategy="variance", rounds=args.explore_rounds,
                                                  stop_confidence=0.0),
                     seed=args.seed, platform_ids=tuple(["reference"] + comps))
    eng = spec.engine()
    per_round = []
    maps = []

    def on_round(rec) -> None:
        imgs, ixg, cam, probs = maps_for(eng.learner, val, list(range(len(comps))))
        acc = float(np.mean([int(np.argmax(p)) == t for t, p in enumerate(probs)]))
        per_round.append({"round": rec.round, "validation_accuracy": acc,
                          "p_true": [float(probs[t][t]) for t in range(len(comps))],
                          "gradcam_concentration_top10": concentration(cam),
                          "ixg_concentration_top10": concentration(ixg),
                          "reference_probs": rec.probs, "next": rec.platform})
        maps.append((rec.round, imgs, ixg, cam, probs))
    res = eng.run(touch, truth=comps.index(ref_cls) + 1, on_round=on_round)   # reads its learner
    for r_i in (0, len(maps) - 1):
        rnd, imgs, ixg, cam, probs = maps[r_i]
        charts.saliency_rows(out / f"explore_{kind}_round{rnd}.png", comps, imgs, ixg, cam, probs,
                    list(range(len(comps))),
                    f"exploration, {kind} inputs, after decision {rnd}: fixed validation set "
                    f"(one untouched press per class)")
    charts.gradcam_rounds(out / f"explore_{kind}_rounds.png", comps, maps,
                          f"Grad-CAM on the validation set after each decision ({kind})")
    return {"kind": kind, "comparisons": comps, "reference": ref_cls, "correct": res.correct,
            "touches": res.touches, "rounds": per_round}


def run(args) -> int:
    kinds = {"off": ["spatial"], "on": ["fourier"], "both": ["spatial", "fourier"]}[args.fourier]
    torch.set_num_threads(args.threads)
    cfg = {k: v for k, v in vars(args).items() if k != "func"}
    out = results_dir(args.out, "saliency", cfg)
    t0 = time.perf_counter()
    pool = Pool(args.source, args.classes, args.per_class, args.seed)
    doc = {"source": args.source, "classes": pool.classes,
           "presses_per_class": {c: len(f) for c, f in pool.frames.items()},
           "classify": {}, "explore": {}}
    for kind in kinds:
        if "classify" in args.parts:
            doc["classify"][kind] = run_classify(args, pool, kind, out)
        if "explore" in args.parts:
            doc["explore"][kind] = run_explore(args, pool, kind, out)
    doc["wall_s"] = time.perf_counter() - t0
    write_json(out / "summary.json", doc)
    for kind, d in doc["classify"].items():
        print(f"classify {kind}: held-out accuracy {d['held_out_accuracy']:.2f} "
              f"({d['correct']}/{d['n']}, {d['folds']} folds)")
    for kind, d in doc["explore"].items():
        accs = [r["validation_accuracy"] for r in d["rounds"]]
        print(f"explore {kind}: trial {'right' if d['correct'] else 'wrong'}, validation "
              f"accuracy by round {', '.join(f'{a:.2f}' for a in accs)}")
    print(f"results in {out}")
    return 0


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("saliency", help="Input x Gradient and Grad-CAM maps; Fourier inputs")
    p.add_argument("--source", default="sim", help="replay:DIR or sim[:q] (default sim)")
    p.add_argument("--parts", nargs="+", default=["classify", "explore"],
                   choices=["classify", "explore"])
    p.add_argument("--classes", type=int, default=6)
    p.add_argument("--per-class", type=int, default=6, help="presses per class (sim source)")
    p.add_argument("--folds", type=int, default=5)
    p.add_argument("--rounds", type=int, default=25, help="training rounds of the classifier")
    p.add_argument("--explore-rounds", type=int, default=10)
    p.add_argument("--reference", type=int, default=0, help="reference = comparison class k")
    p.add_argument("--fourier", choices=["off", "on", "both"], default="both")
    p.add_argument("--config", default="cnn")
    p.add_argument("--input-size", type=int, default=0, help="override the preset's input size")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--threads", type=int, default=1)
    p.add_argument("--out", help="results folder (default results/saliency)")
    p.add_argument("--quiet", action="store_true")
    p.set_defaults(func=run)
