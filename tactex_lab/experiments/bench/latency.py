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
"""

from __future__ import annotations

import platform
import statistics
import time

import numpy as np
import torch

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


def measure(config: str, n_touches: int, repeats: int, frames: list[np.ndarray],
            epochs_override: int | None = None) -> dict:
    _, name, over = parse_config(config)
    if epochs_override:
        over["epochs"] = epochs_override
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
        configs: tuple[str, ...] = ("seed_faithful", "cnn", "default")) -> dict:
    """Measure, print a table, return ``{config: {str(n): median seconds}}`` plus details."""
    frames = _frames(max(touch_counts) + 1)   # distinct frames: no descriptor cache hits
    spec = dict(zip([parse_config(c)[0] for c in configs], configs))
    configs = tuple(spec)
    out: dict = {c: {} for c in configs}
    add: dict = {c: [] for c in configs}
    p99: dict = {c: {} for c in configs}
    for n in touch_counts:
        for c in configs:
            faithful = parse_config(spec[c])[1] == "seed_faithful"
            ep = seed_epochs if faithful else None
            reps = max(1, repeats // 2) if faithful else repeats
            d = measure(spec[c], n, reps, frames, ep)
            out[c][str(n)] = d["median_s"]
            p99[c][str(n)] = d["p99_s"]
            add[c].append(d["add_touch_median_s"])
    print(f"decision time per round, median [s]  (torch {torch.__version__}, "
          f"{torch.get_num_threads()} threads, {platform.processor() or platform.machine()})")
    last = configs[-1]
    print(f"{'touches':>8}  " + "  ".join(f"{c:>14}" for c in configs) + "   " +
          "  ".join(f"{c + '/' + last:>20}" for c in configs[:-1]))
    for n in touch_counts:
        vals = [out[c][str(n)] for c in configs]
        ratios = [v / vals[-1] if vals[-1] > 0 else float("inf") for v in vals[:-1]]
        print(f"{n:>8}  " + "  ".join(f"{v:>14.4f}" for v in vals) + "   " +
              "  ".join(f"{r:>19.3g}x" for r in ratios))
    print("99th percentile [s] at " + ", ".join(
        f"{n} touches: " + " / ".join(f"{c} {p99[c][str(n)]:.4f}" for c in configs)
        for n in touch_counts))
    out["p99_s"] = p99
    print("adding one touch (descriptor / rotated views), median [s]: " +
          ", ".join(f"{c} {statistics.median(v):.3f}" for c, v in add.items()))
    out["add_touch_median_s"] = {c: statistics.median(v) for c, v in add.items()}
    if "seed_faithful" in configs:
        print(f"seed_faithful: trained {seed_epochs} epoch(s) per round, training time scaled "
              f"x{preset('seed_faithful').epochs / seed_epochs:g} to its 10 epochs")
    return out
