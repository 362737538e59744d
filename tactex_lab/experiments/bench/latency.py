"""Per-round decision time (train + score + choose) against the number of stored touches.

For each touch count n (total touches, reference included) and each configuration, an engine over
4 comparison platforms gets the reference and n-1 comparison touches (round-robin), then
``decide()`` runs ``repeats`` times; the median decision time is reported. Configurations are
interleaved per touch count so both see the same machine state.

Configurations: ``default`` (texture descriptor + match belief, strategy infogain), ``cnn``
(the CNN default before real presses decided: small Inception, 48 px, 8 steps) and
``seed_faithful`` (the thesis). The seed-faithful configuration (299 px, 10 epochs per round) trains for ``seed_epochs`` epochs
and its training time is scaled by 10 / seed_epochs (training cost is linear in epochs); the
output says so. Frames come from the fabric simulator (content does not change
the cost of a CNN or of a descriptor; the frames only have to be valid).

``devices``: every CNN configuration is timed on each (``learner.device``), side by side in one
run (``seed_faithful@cpu``, ``seed_faithful@cuda``, ...); a configuration without a CNN runs
once, on the CPU. On a GPU the thesis configuration trains its full epochs (no scaling), and
one decision is made untimed first (CUDA context, cuDNN's first kernels). Training and scoring
times are wall-clock times that end with a read-back to the host, so the GPU's queued work is
inside them.
"""

from __future__ import annotations

import platform
import statistics
import time

import numpy as np
import torch

from tactex_lab.cnn.device import cuda_report, resolve_device
from tactex_ros.core.config import preset
from tactex_ros.core.engine import TrialSpec, trial_preset
from tactex_ros.core.texture import clear_cache
from tactex_ros.sources import open_source


def _frames(n: int, seed: int = 0) -> list[np.ndarray]:
    src = open_source("sim:medium")
    touch = src.trial(src.classes[:5], seed)
    return [touch(i % 5) for i in range(n)]


def parse_config(text: str) -> tuple[str, str, dict]:
    """``preset`` or ``label=preset:learner.PATH=value,...`` -> (label, preset, learner
    overrides), e.g. ``prepared=default:learner.representation=rep.npz``."""
    from ..common import learner_set
    label, sep, rest = text.partition("=")
    if not sep:
        return text, text, {}
    name, _, kv = rest.partition(":")
    return label, name, learner_set([it for it in kv.split(",") if it],
                                    option=f"--configs {text!r}:")


def has_device(config: str) -> bool:
    """Whether ``config``'s learner runs on a torch device (a CNN: ``learner.device``)."""
    _, name, over = parse_config(config)
    return "device" in type(preset(name, **over)).model_fields


def measure(config: str, n_touches: int, repeats: int, frames: list[np.ndarray],
            epochs_override: int | None = None, device: str = "cpu") -> dict:
    _, name, over = parse_config(config)
    if epochs_override:
        over["epochs"] = epochs_override
    if device != "cpu":
        over["device"] = device
    cfg = preset(name, **over)
    eng = TrialSpec(4, cfg, trial_preset(name, rounds=10**3 - 1, stop_confidence=0.0),
                    seed=0).engine()      # driven step by step: the steps are what is timed
    clear_cache()
    add_s = []
    for k in range(n_touches):
        t0 = time.perf_counter()
        if k == 0:
            eng.add_touch(0, frames[0])
        else:
            eng.add_touch(1 + (k - 1) % 4, frames[1 + (k - 1) % (len(frames) - 1)])
        add_s.append(time.perf_counter() - t0)
    scale = (preset(name).epochs / epochs_override) if epochs_override else 1.0
    if device != "cpu":
        eng.decide()                      # untimed: CUDA context and first kernels
    times, train, score = [], [], []
    for _ in range(repeats):
        rec = eng.decide()
        train.append(rec.train_s * scale)
        score.append(rec.score_s)
        times.append(rec.train_s * scale + rec.score_s + rec.choose_s)
    return {"median_s": statistics.median(times),
            "p99_s": float(np.percentile(times, 99)), "train_median_s": statistics.median(train),
            "score_median_s": statistics.median(score), "repeats": repeats, "scaled": scale,
            "add_touch_median_s": statistics.median(add_s)}


def run(touch_counts: tuple[int, ...] | list[int] = (5, 15, 25), repeats: int = 5,
        seed_epochs: int = 1,
        configs: tuple[str, ...] = ("seed_faithful", "cnn", "default"),
        devices: tuple[str, ...] = ("cpu",)) -> dict:
    """Measure, print a table, return ``{config: {str(n): median seconds}}`` plus details
    (``train_s`` / ``score_s``: the medians of training and scoring). With more than one of
    ``devices`` a CNN configuration ``c`` is reported as ``c@device``."""
    devices = tuple(dict.fromkeys(devices))
    for d in devices:
        resolve_device(d, "--device")     # an absent GPU is refused before any timing
    frames = _frames(max(touch_counts) + 1)   # distinct frames: no descriptor cache hits
    spec: dict[str, tuple[str, str]] = {}     # label -> (config, device)
    for c in configs:
        label = parse_config(c)[0]
        on = devices if has_device(c) else ("cpu",)
        for d in on:
            spec[label if len(devices) == 1 or len(on) == 1 else f"{label}@{d}"] = (c, d)
    configs = tuple(spec)
    out: dict = {c: {} for c in configs}
    add: dict = {c: [] for c in configs}
    p99: dict = {c: {} for c in configs}
    train: dict = {c: {} for c in configs}
    score: dict = {c: {} for c in configs}
    for n in touch_counts:
        for c in configs:
            config, device = spec[c]
            faithful = parse_config(config)[1] == "seed_faithful"
            ep = seed_epochs if faithful and device == "cpu" else None
            reps = max(1, repeats // 2) if faithful else repeats
            d = measure(config, n, reps, frames, ep, device)
            out[c][str(n)] = d["median_s"]
            p99[c][str(n)] = d["p99_s"]
            train[c][str(n)] = d["train_median_s"]
            score[c][str(n)] = d["score_median_s"]
            add[c].append(d["add_touch_median_s"])
    gpus = [d for d in devices if d != "cpu"]
    print(f"decision time per round, median [s]  (torch {torch.__version__}, "
          f"{torch.get_num_threads()} threads, {platform.processor() or platform.machine()}"
          + (f"; {cuda_report()}" if gpus else "") + ")")
    last = configs[-1]
    print(f"{'touches':>8}  " + "  ".join(f"{c:>14}" for c in configs) + "   " +
          "  ".join(f"{c + '/' + last:>20}" for c in configs[:-1]))
    for n in touch_counts:
        vals = [out[c][str(n)] for c in configs]
        ratios = [v / vals[-1] if vals[-1] > 0 else float("inf") for v in vals[:-1]]
        print(f"{n:>8}  " + "  ".join(f"{v:>14.4f}" for v in vals) + "   " +
              "  ".join(f"{r:>19.3g}x" for r in ratios))
    print("training + scoring, median [s]: " + "; ".join(
        f"{n} touches: " + ", ".join(f"{c} {train[c][str(n)]:.3f} + {score[c][str(n)]:.3f}"
                                     for c in configs) for n in touch_counts))
    out["train_s"], out["score_s"] = train, score
    print("99th percentile [s] at " + ", ".join(
        f"{n} touches: " + " / ".join(f"{c} {p99[c][str(n)]:.4f}" for c in configs)
        for n in touch_counts))
    out["p99_s"] = p99
    print("adding one touch (descriptor / rotated views), median [s]: " +
          ", ".join(f"{c} {statistics.median(v):.3f}" for c, v in add.items()))
    out["add_touch_median_s"] = {c: statistics.median(v) for c, v in add.items()}
    if any(parse_config(config)[1] == "seed_faithful" for config, _ in spec.values()):
        print(f"seed_faithful: trained {seed_epochs} epoch(s) per round on the CPU, training "
              f"time scaled x{preset('seed_faithful').epochs / seed_epochs:g} to its 10 epochs"
              + ("; on the GPU all 10 epochs are timed" if gpus else ""))
    return out
