"""``tactex experiment classify``: supervised texture classification (thesis Table 5.1, Fig 5.1).

All classes of a source are learnt at once (one classifier over C classes):

- ``sim``: the 25 catalogue fabrics (or ``--classes``); per class ``--train`` 10, ``--val`` 20,
  ``--test`` 20 touches (the thesis's split), each a new random press (random window, rotation
  and depth). The touches depend on the seed only, so every model sees the same data for a seed.
- ``replay:DIR``: recorded presses; one press gives one contact frame, so touches are split *by
  press*, never by frame: per class the presses are shuffled (seeded) and divided by
  ``--replay-split`` (default 0.2,0.4,0.4 = the thesis's 10:20:20), at least one press each;
  a class with fewer than 3 presses is refused. octopi-dev has 5-7 presses per class, i.e.
  1 training, 2 validation and 2-3 test presses.

Training (``OnlineLearner`` with ``num_classes`` = C): every training touch is stored as
``augment`` random rotations (thesis: 10); one epoch = one full shuffled pass over the stored
views (``train_round`` with the ``epochs`` schedule, 1 epoch per call); batch-norm statistics
are re-estimated after each epoch when the preset says so. After every epoch: accuracy on the
unrotated training touches, accuracy and loss on the validation touches (eval mode, no dropout).
The test accuracy is measured with the weights of the epoch with the best validation accuracy
(earliest on ties); the last epoch's test accuracy is reported too.

Models: ``small_inception`` (input ``--input-size``, default 64 px), ``inception_v3_random``
and ``inception_v3`` (needs ``--weights``; included by default only when given). The full
network needs at least 75 px; it runs at ``--inception-input-size`` (default 80). ``--fourier``
trains on log-magnitude Fourier spectra (``learner.fourier``).

Each (model, seed) is one job; jobs run on the job runner (``--workers``, ``--backend``) with
one torch thread each.
"""

from __future__ import annotations

import argparse
import copy
import time
from pathlib import Path
from typing import Any

import numpy as np

from tactex_ros.core.errors import InputError
from tactex_lab.analysis import charts, stats
from tactex_lab.experiments.common import learner_set, results_dir, write_json
from tactex_lab.experiments.runner import add_runner_args, backend_of, cached_source, run_parallel

# thesis Table 5.1 (test accuracy)
THESIS = {"inception_v3": 0.9682, "inception_v3_random": 0.9432, "small_inception": 0.9426}
MIN_INCEPTION_PX = 75


# ---------------------------------------------------------------------------------- data
def sim_split(source: Any, classes: list[str], counts: tuple[int, int, int], seed: int
              ) -> dict[str, list[tuple[np.ndarray, int]]]:
    """{"train"|"val"|"test": [(frame, label)]}: fresh presses per class and split."""
    out: dict[str, list] = {"train": [], "val": [], "test": []}
    for ci, c in enumerate(classes):
        for si, (split, n) in enumerate(zip(out, counts, strict=True)):
            rng = np.random.default_rng([seed, 101, ci, si])
            out[split] += [(source.press(c, rng), ci) for _ in range(n)]
    return out


def replay_counts(n: int, fractions: tuple[float, float, float]) -> tuple[int, int, int]:
    """Presses per split for a class with ``n`` presses (>= 1 each; needs n >= 3)."""
    if n < 3:
        raise InputError(f"a class needs >= 3 presses for a train/val/test split, has {n}")
    tot = sum(fractions)
    n_tr = max(1, int(round(fractions[0] / tot * n)))
    n_va = max(1, int(round(fractions[1] / tot * n)))
    while n_tr + n_va > n - 1:
        if n_va > 1:
            n_va -= 1
        else:
            n_tr -= 1
    return n_tr, n_va, n - n_tr - n_va


def replay_split(source: Any, classes: list[str], fractions: tuple[float, float, float],
                 seed: int) -> tuple[dict[str, list[tuple[np.ndarray, int]]], dict]:
    """Split each class's presses (files) into train/val/test; returns data and the file lists."""
    out: dict[str, list] = {"train": [], "val": [], "test": []}
    files: dict[str, dict[str, list[str]]] = {}
    for ci, c in enumerate(classes):
        presses = source.presses(c)
        try:
            n_tr, n_va, _ = replay_counts(len(presses), fractions)
        except InputError as exc:
            raise InputError(f"class {c!r}: {exc}") from None
        order = np.random.default_rng([seed, 103, ci]).permutation(len(presses))
        parts = {"train": order[:n_tr], "val": order[n_tr:n_tr + n_va],
                 "test": order[n_tr + n_va:]}
        files[c] = {}
        for split, idx in parts.items():
            files[c][split] = [presses[i].name for i in idx]
            out[split] += [(source.frame(presses[i]), ci) for i in idx]
    return out, files


# ---------------------------------------------------------------------------------- one job
def _eval(learner: Any, x: list, y: np.ndarray) -> tuple[np.ndarray, float, float]:
    """(predictions, accuracy, mean cross-entropy) of eval-mode softmax averaged over views."""
    import torch
    counts = [t.shape[0] for t in x]
    p = learner.predict_proba(torch.cat(x))
    probs = np.stack([c.mean(0) for c in np.split(p, np.cumsum(counts)[:-1])])
    pred = probs.argmax(1)
    loss = float(-np.mean(np.log(np.clip(probs[np.arange(len(y)), y], 1e-12, 1.0))))
    return pred, float(np.mean(pred == y)), loss


def run_one(spec: dict) -> dict:
    """Train and evaluate one (model, seed); ``spec`` is plain data (see ``build_specs``)."""
    import torch

    from tactex_ros.core.config import preset
    from tactex_lab.cnn.learner import OnlineLearner
    torch.set_num_threads(spec["threads"])
    t0 = time.perf_counter()
    src = cached_source(spec["source"])
    classes = spec["classes"]
    if spec["source"].startswith("replay:"):
        data, files = replay_split(src, classes, tuple(spec["replay_split"]), spec["seed"])
    else:
        data, files = sim_split(src, classes, tuple(spec["counts"]), spec["seed"]), None
    t_data = time.perf_counter() - t0
    cfg = preset(spec["preset"], **spec["overrides"])
    cfg = cfg.replace(epochs=1, steps=0)
    learner = OnlineLearner(len(classes), cfg, seed=spec["seed"], model_name=spec["model"])
    for img, label in data["train"]:
        learner.add_touch(img, label)
    evals = {s: ([learner.test_tensor(img) for img, _ in data[s]],
                 np.array([lab for _, lab in data[s]])) for s in data}
    curves: dict[str, list[float]] = {"train_loss": [], "train_acc": [], "val_acc": [],
                                      "val_loss": [], "epoch_s": []}
    best = (-1.0, 0, None)
    for epoch in range(1, spec["epochs"] + 1):
        st = learner.train_round()
        _, tr_acc, _ = _eval(learner, *evals["train"])
        _, va_acc, va_loss = _eval(learner, *evals["val"])
        for k, v in (("train_loss", st.mean_loss), ("train_acc", tr_acc), ("val_acc", va_acc),
                     ("val_loss", va_loss), ("epoch_s", st.seconds)):
            curves[k].append(float(v))
        if va_acc > best[0]:
            best = (va_acc, epoch, copy.deepcopy(learner.model.state_dict()))
    last_pred, last_acc, _ = _eval(learner, *evals["test"])
    learner.model.load_state_dict(best[2])
    pred, acc, loss = _eval(learner, *evals["test"])
    return {"model": spec["model"], "seed": spec["seed"], "input_size": cfg.input_size,
            "fourier": cfg.fourier, "test_acc": acc, "test_loss": loss,
            "test_acc_last_epoch": last_acc, "best_epoch": best[1], "best_val_acc": best[0],
            "curves": curves, "test_truth": evals["test"][1].tolist(),
            "test_pred": pred.tolist(), "n": {s: len(data[s]) for s in data},
            "files": files, "data_s": t_data, "wall_s": time.perf_counter() - t0}


def build_specs(args: argparse.Namespace) -> tuple[list[dict], list[str], dict]:
    from tactex_ros.core.config import preset
    from tactex_lab.cnn.models import MODEL_NAMES
    src = cached_source(args.source)
    all_classes = list(src.classes)
    if args.classes:
        want = [c.strip() for c in args.classes.split(",") if c.strip()]
        classes = []
        for c in want:
            if c.isdigit() and c not in all_classes:
                c = src.by_number(int(c))
            if c not in all_classes:
                raise InputError(f"--classes: unknown class {c!r}; available: "
                                 f"{', '.join(all_classes)}")
            classes.append(c)
    else:
        classes = all_classes
    if len(classes) < 2:
        raise InputError("classification needs at least 2 classes")
    models = args.models or (["inception_v3"] if args.weights else []) + \
        ["inception_v3_random", "small_inception"]
    base = learner_set(args.set)
    if args.fourier:
        base["fourier"] = True
    if min(args.train, args.val, args.test) < 1:
        raise InputError("--train, --val and --test need at least 1 touch per class")
    fr = tuple(float(x) for x in args.replay_split.split(","))
    if len(fr) != 3 or min(fr) <= 0:
        raise InputError("--replay-split: three positive fractions, e.g. 0.2,0.4,0.4")
    specs, sizes = [], {}
    for m in models:
        if m not in MODEL_NAMES:
            raise InputError(f"unknown model {m!r}; choose from {', '.join(MODEL_NAMES)}")
        over = dict(base)
        if m == "inception_v3":
            if not args.weights:
                raise InputError("model inception_v3 needs --weights (torchvision checkpoint);"
                                 " inception_v3_random is the untrained network")
            over["weights"] = args.weights
        size = args.input_size if m == "small_inception" else args.inception_input_size
        if m != "small_inception" and size < MIN_INCEPTION_PX:
            raise InputError(f"--inception-input-size {size}: the full network needs >= "
                             f"{MIN_INCEPTION_PX} px")
        over["input_size"] = size
        sizes[m] = size
        preset(args.config, **over)  # validate here
        for seed in args.seeds:
            specs.append({"source": args.source, "classes": classes, "model": m, "seed": seed,
                          "counts": (args.train, args.val, args.test), "replay_split": fr,
                          "preset": args.config, "overrides": over, "epochs": args.epochs,
                          "threads": args.threads})
    return specs, classes, sizes


def summarise(results: list[dict], classes: list[str]) -> dict:
    out = {}
    for m in dict.fromkeys(r["model"] for r in results):
        rr = [r for r in results if r["model"] == m]
        cm = sum(stats.confusion(r["test_truth"], r["test_pred"], range(len(classes)))
                 for r in rr)
        curves = {k: {"mean": np.mean([r["curves"][k] for r in rr], 0).tolist(),
                      "std": np.std([r["curves"][k] for r in rr], 0).tolist()}
                  for k in ("train_loss", "train_acc", "val_acc", "val_loss")}
        out[m] = {"test_acc": stats.mean_std([r["test_acc"] for r in rr]),
                  "test_acc_last_epoch": stats.mean_std([r["test_acc_last_epoch"] for r in rr]),
                  "best_val_acc": stats.mean_std([r["best_val_acc"] for r in rr]),
                  "best_epoch": [r["best_epoch"] for r in rr],
                  "per_seed": {str(r["seed"]): r["test_acc"] for r in rr},
                  "input_size": rr[0]["input_size"], "fourier": rr[0]["fourier"],
                  "epoch_s_median": float(np.median([s for r in rr
                                                     for s in r["curves"]["epoch_s"]])),
                  "job_wall_s": [r["wall_s"] for r in rr],
                  "thesis_test_acc": THESIS.get(m),
                  "curves": curves,
                  "confusion": {"labels": classes, "matrix": cm.tolist()},
                  "n": rr[0]["n"]}
    return out


def figures(outdir: Path, summary: dict) -> list[str]:
    models = list(summary)
    w = [charts.bars(outdir / "accuracy.png", models,
                     {"test accuracy (best-val epoch)": (
                         [summary[m]["test_acc"]["mean"] for m in models],
                         [summary[m]["test_acc"]["std"] for m in models])},
                     "test accuracy", "Texture classification",
                     reference={"thesis Table 5.1": [THESIS.get(m) for m in models]})]
    for key, ylabel, name in (("acc", "accuracy", "curves_accuracy.png"),
                              ("loss", "cross-entropy", "curves_loss.png")):
        series = {}
        for m in models:
            c = summary[m]["curves"]
            series[f"{m} train"] = (c[f"train_{key}"]["mean"], c[f"train_{key}"]["std"])
            series[f"{m} val"] = (c[f"val_{key}"]["mean"], c[f"val_{key}"]["std"])
        n = len(next(iter(series.values()))[0])
        w.append(charts.lines(outdir / name, list(range(1, n + 1)), series, "epoch", ylabel,
                              f"Training and validation {ylabel}",
                              ylim=(0, 1.02) if key == "acc" else None))
    for m in models:
        cm = np.array(summary[m]["confusion"]["matrix"])
        w.append(charts.confusion(outdir / f"confusion_{m}.png", cm,
                                  summary[m]["confusion"]["labels"],
                                  f"{m}: test confusion (all seeds, "
                                  f"{100 * summary[m]['test_acc']['mean']:.1f} %)"))
    return [str(p) for p in w]


def cmd(args: argparse.Namespace) -> int:
    t0 = time.perf_counter()
    specs, classes, sizes = build_specs(args)
    backend = backend_of(args).resolved()
    workers = min(len(specs), backend.workers)   # 0 (ray): every CPU of the cluster
    config = {"source": args.source, "classes": classes, "models": list(sizes),
              "input_sizes": sizes, "seeds": args.seeds, "epochs": args.epochs,
              "split": {"train": args.train, "val": args.val, "test": args.test}
              if not args.source.startswith("replay:") else {"replay_split": args.replay_split},
              "preset": args.config, "overrides": specs[0]["overrides"] if specs else {},
              "fourier": args.fourier, "weights": args.weights, "workers": workers,
              "backend": backend.name}
    outdir = results_dir(args.out, "classify", config)
    if not args.quiet:
        print(f"classify: {len(classes)} classes, models {', '.join(sizes)}, seeds "
              f"{args.seeds}, {args.epochs} epochs, {workers} workers -> {outdir}", flush=True)
    results = run_parallel(run_one, specs, backend, "classify (model x seed)", args.quiet)
    summary = summarise(results, classes)
    doc = {"experiment": "classify", "settings": config, "models": summary,
           "thesis_reference": THESIS, "wall_s": time.perf_counter() - t0,
           "runs": [{k: v for k, v in r.items() if k not in ("test_truth", "test_pred")}
                    for r in results]}
    doc["figures"] = figures(outdir, summary)
    write_json(outdir / "summary.json", doc)
    if not args.quiet:
        for m, s in summary.items():
            ref = THESIS.get(m)
            print(f"  {m:20s} test {100 * s['test_acc']['mean']:6.2f} % ± "
                  f"{100 * s['test_acc']['std']:.2f} (n={s['test_acc']['n']} seeds, "
                  f"{s['input_size']} px, {s['epoch_s_median']:.1f} s/epoch)"
                  + (f"   thesis {100 * ref:.2f} %" if ref else ""))
        print(f"wall {doc['wall_s']:.1f} s")
    return 0


def register(sub: argparse._SubParsersAction) -> None:
    from tactex_ros.core.config import PRESETS
    p = sub.add_parser("classify", help="texture classification, all classes (thesis Table 5.1)")
    p.add_argument("--source", default="sim", help="sim (25 catalogue fabrics) or replay:DIR")
    p.add_argument("--classes", help="comma-separated subset (names, or fabric numbers for sim)")
    p.add_argument("--train", type=int, default=10, help="training touches per class (sim)")
    p.add_argument("--val", type=int, default=20, help="validation touches per class (sim)")
    p.add_argument("--test", type=int, default=20, help="test touches per class (sim)")
    p.add_argument("--replay-split", default="0.2,0.4,0.4",
                   help="train,val,test fractions of each class's presses (replay)")
    p.add_argument("--models", nargs="+",
                   help="default: inception_v3 (with --weights), inception_v3_random, "
                        "small_inception")
    p.add_argument("--weights", help="torchvision checkpoint for inception_v3")
    p.add_argument("--seeds", type=int, nargs="+", default=[0, 1, 2, 3, 4])
    p.add_argument("--epochs", type=int, default=30)
    p.add_argument("--input-size", type=int, default=64, help="small_inception input [px]")
    p.add_argument("--inception-input-size", type=int, default=80,
                   help="input of the full network [px], >= 75 (thesis: 299)")
    p.add_argument("--fourier", action="store_true", help="train on Fourier spectra")
    p.add_argument("--config", default="cnn", help=f"learner preset: {', '.join(PRESETS)}")
    p.add_argument("--set", action="append", metavar="PATH=VALUE",
                   help="learner override, e.g. learner.lr=1e-3 (repeatable)")
    p.add_argument("--out", help="results folder (default results/classify)")
    add_runner_args(p)
    p.set_defaults(func=cmd)
