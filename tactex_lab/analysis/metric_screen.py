"""Screening a nonlinear metric (``mlp_metric``) against the plain whitening on cached
descriptors, class-disjoint in both directions, no trials (``tactex experiment unseen
--screen-mlp``).

For each direction (test A with B as the library, and the reverse) and each per-press feature
(``frame``, ``frames4``), the whitening and every MLP of the grid are fitted on the library's
presses only and scored on the test side with ``experiment unseen``'s screening proxy
(``scene_hits``, also behind ``real.nearest_mean_accuracy``: share of 3000 seeded 1 + 4 scenes whose nearest comparison,
in the belief's scene units, is the match; 1 press per platform and the means of 2). The
scenes are the same for every metric (paired): ``vs_whiten`` counts the scenes only the MLP
got right and those only the whitening got right, with an exact McNemar p.

The caches are ``experiment unseen``'s (``--cache-dir``, descriptors of the presses, under
/tmp); nothing trained is written.
"""

from __future__ import annotations

import itertools
import time
from collections.abc import Callable

import numpy as np

from tactex_ros.core import representation
from tactex_lab.analysis import mlp_metric
from tactex_lab.analysis.stats import mcnemar_exact
from tactex_lab.analysis.learned_features import library_view

#: (loss, hidden, decay) of the MLPs screened.
GRID = tuple(itertools.product(("episode", "triplet"), (64,), (1e-3, 1e-2, 1e-1)))


def scene_hits(x: np.ndarray, cls: np.ndarray, rep, per: int, scenes: int = 3000,
               seed: int = 0) -> np.ndarray:
    """Per scene (bool, ``scenes``): the proxy of ``real.nearest_mean_accuracy`` (the same
    seeded scenes), kept per scene for paired tests."""
    rng = np.random.default_rng(seed)
    classes = sorted(set(cls.tolist()))
    rows = {c: np.flatnonzero(cls == c) for c in classes}
    z = x if rep is None else rep.apply(x)
    hits = np.zeros(scenes, dtype=bool)
    for s in range(scenes):
        comps = rng.choice(len(classes), 4, replace=False)
        t = int(rng.integers(4))
        ref_rows = rng.permutation(rows[classes[comps[t]]])
        means = [z[ref_rows[:per]].mean(0)]
        for i, c in enumerate(comps):
            r = rows[classes[c]]
            if i == t and len(ref_rows) > per:
                r = ref_rows[per:]
            means.append(z[rng.choice(r, min(per, len(r)), replace=False)].mean(0))
        m = np.vstack(means)
        spread = m.std(0)
        scale = np.sqrt(spread ** 2 + (0.05 * np.median(spread)) ** 2) + 1e-12
        hits[s] = int(np.argmin((((m[1:] - m[0]) / scale) ** 2).sum(1))) == t
    return hits


def screen(a: dict[str, np.ndarray], b: dict[str, np.ndarray],
           features: dict[str, Callable[[dict], np.ndarray]], grid=GRID, steps: int = 600,
           seeds: tuple[int, ...] = (0,), scenes: int = 3000) -> list[dict]:
    """Caches ``a``, ``b`` (``cls`` and the arrays ``features`` read: {name: cache -> (n, D)}).
    Every (direction, feature, metric) row: acc_1, acc_2, fit seconds, apply microseconds per
    press, and against the whitening on the same ``scenes`` (``vs_whiten``)."""
    rows = []
    for name, test, lib in (("a_with_b", a, b), ("b_with_a", b, a)):
        for feat, read in features.items():
            x, cls = read(test), test["cls"]
            xl = read(library_view(lib))
            libd = {c: xl[lib["cls"] == c] for c in sorted(set(lib["cls"].tolist()))}
            t0 = time.perf_counter()
            white = representation.fit(libd, kind="whiten")
            base = {per: scene_hits(x, cls, white, per, scenes) for per in (1, 2)}
            rows.append({"direction": name, "feature": feat, "metric": "whiten",
                         "fit_s": time.perf_counter() - t0,
                         "acc_1": float(base[1].mean()), "acc_2": float(base[2].mean())})
            print(_line(rows[-1]), flush=True)
            for (loss, hidden, decay), seed in itertools.product(grid, seeds):
                m, log = mlp_metric.fit(libd, hidden=hidden, loss=loss, decay=decay,
                                        steps=steps, seed=seed)
                t1 = time.perf_counter()
                for _ in range(100):
                    m.apply(x[:1])
                apply_us = (time.perf_counter() - t1) / 100 * 1e6
                hits = {per: scene_hits(x, cls, m, per, scenes) for per in (1, 2)}
                rows.append({"direction": name, "feature": feat, "metric": "mlp",
                             "loss": loss, "hidden": hidden, "decay": decay, "seed": seed,
                             "steps": steps, "fit_s": log["seconds"], "apply_us": apply_us,
                             "train_loss": [log["loss"][0]["loss"], log["loss"][-1]["loss"]],
                             "acc_1": float(hits[1].mean()), "acc_2": float(hits[2].mean()),
                             "vs_whiten": {str(per): mcnemar_exact(hits[per], base[per])
                                           for per in (1, 2)}})
                print(_line(rows[-1]), flush=True)
    return rows


def _line(r: dict) -> str:
    what = (r["metric"] if r["metric"] != "mlp" else
            f"mlp {r['loss']} h{r['hidden']} decay {r['decay']:g} seed {r['seed']}")
    p = ("" if "vs_whiten" not in r else
         f"  p vs whiten {r['vs_whiten']['1']['p']:.3g} / {r['vs_whiten']['2']['p']:.3g}")
    return (f"{r['direction']} {r['feature']:>8} {what:>36}: {r['acc_1']:.3f} / "
            f"{r['acc_2']:.3f}  fit {r['fit_s']:.1f} s{p}")


#: Issue 33's candidate features (``press_cache.FEATURES``) screened by ``feature_screen``,
#: after today's ``frame`` and ``frames4``.
CANDIDATES = ("frame", "frames4", "fb", "hm", "fb_hm", "frame_fb", "frame_hm", "frame_grow",
              "frames4_fb", "frames4_hm", "frames4_grow", "frames4_all")


#: Further baselines of ``feature_screen`` when their feature is screened (``vs``): today's
#: default descriptor and the best prepared feature before the learned candidates.
BASELINES = (("frame_hm", "none"), ("frames4_hm", "whiten"))


def feature_screen(a: dict[str, np.ndarray], b: dict[str, np.ndarray],
                   features: dict[str, Callable[[dict], np.ndarray]],
                   scenes: int = 3000) -> list[dict]:
    """Every feature of ``features`` with no metric and with the whitening fitted on the other
    library, scored with ``scene_hits`` (1 press / the means of 2), both directions, on the
    same ``scenes`` for every feature: exact McNemar against today's feature (``frame``, no
    metric: ``vs_frame``) and against the whitened frame (``vs_whiten``), and in ``vs``
    against every ``BASELINES`` row screened before it. ``features`` must hold ``frame``."""
    rows = []
    for name, test, lib in (("a_with_b", a, b), ("b_with_a", b, a)):
        base: dict[str, dict[int, np.ndarray]] = {}
        allhits: dict[tuple[str, str], dict[int, np.ndarray]] = {}
        order = ["frame"] + [b for b, _ in BASELINES if b in features and b != "frame"]
        for feat in dict.fromkeys(order + list(features)):
            x, cls, xl = features[feat](test), test["cls"], features[feat](library_view(lib))
            libd = {c: xl[lib["cls"] == c] for c in sorted(set(lib["cls"].tolist()))}
            for kind in ("none", "whiten"):
                rep = None if kind == "none" else representation.fit(libd, kind="whiten")
                hits = {per: scene_hits(x, cls, rep, per, scenes) for per in (1, 2)}
                if feat == "frame":
                    base[kind] = hits
                allhits[feat, kind] = hits
                row = {"direction": name, "feature": feat, "metric": kind, "dims": x.shape[1],
                       "acc_1": float(hits[1].mean()), "acc_2": float(hits[2].mean()),
                       "vs_frame": {str(p): mcnemar_exact(hits[p], base["none"][p])
                                    for p in (1, 2)},
                       "vs_whiten": ({str(p): mcnemar_exact(hits[p], base["whiten"][p])
                                      for p in (1, 2)} if "whiten" in base else None),
                       "vs": {f"{b}/{m}": {str(p): mcnemar_exact(hits[p], allhits[b, m][p])
                                           for p in (1, 2)}
                              for b, m in BASELINES if (b, m) in allhits}}
                rows.append(row)
                vs = "" if row["vs_whiten"] is None else "  p vs frame/whiten " + " ".join(
                    f"{row['vs_whiten'][p]['p']:.2g}" for p in ("1", "2"))
                print(f"{name} {feat:>14} {kind:>6}: {row['acc_1']:.3f} / {row['acc_2']:.3f}"
                      f"  p vs frame {row['vs_frame']['1']['p']:.2g} "
                      f"{row['vs_frame']['2']['p']:.2g}{vs}", flush=True)
    return rows
