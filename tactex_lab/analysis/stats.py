"""Statistics helpers of the experiments: summaries, confusion matrices, paired tests, JS distance.

- ``mean_std``: mean and sample standard deviation (ddof = 1; 0 for a single value).
- ``wilson``: 95 % Wilson score interval of a proportion, the product's
  (``tactex_ros.core.stats.wilson``; (0, 1) for n = 0).
- ``confusion``: confusion matrix (rows = truth, columns = prediction) via scikit-learn.
- ``mcnemar_exact``: exact McNemar test of two classifiers on the same paired items — only the
  discordant pairs count; under H0 each discordant pair is equally likely either way, so the
  smaller count is Binomial(n_discordant, 1/2): two-sided ``scipy.stats.binomtest`` p-value.
- ``wilcoxon_paired``: Wilcoxon signed-rank test on paired continuous values (e.g. per-trial
  accuracies paired by trial and seed); zero differences are dropped (scipy's ``wilcox``
  method); p = 1 when every difference is zero.
- ``holm``: Holm–Bonferroni adjustment of a family of p-values.
- ``js_distance``: Jensen–Shannon *distance* (square root of the divergence) in bits, so it lies
  in [0, 1]; inputs are normalised to sum 1 first.
- ``pareto_front``: the (time, accuracy) points no other point beats.
- ``spearman_interval``: Spearman rho of two rankings with a bootstrap interval (scenes
  resampled, paired across settings).
"""

from __future__ import annotations

from itertools import combinations
from typing import Any
from collections.abc import Sequence

import numpy as np

from tactex_ros.core.stats import wilson as wilson      # the product's, one for both


def mean_std(values: Sequence[float]) -> dict:
    """{"mean", "std" (ddof = 1, 0 for n = 1), "n"}; NaN mean for no values."""
    v = np.asarray(list(values), dtype=np.float64)
    if v.size == 0:
        return {"mean": float("nan"), "std": float("nan"), "n": 0}
    return {"mean": float(v.mean()), "std": float(v.std(ddof=1)) if v.size > 1 else 0.0,
            "n": int(v.size)}


def confusion(truth: Sequence, pred: Sequence, labels: Sequence) -> np.ndarray:
    """(L, L) int counts, rows = true label, columns = predicted label, in ``labels`` order."""
    from sklearn.metrics import confusion_matrix
    labels = list(labels)
    if len(truth) == 0:
        return np.zeros((len(labels), len(labels)), dtype=np.int64)
    return confusion_matrix(list(truth), list(pred), labels=labels).astype(np.int64)


def mcnemar_exact(a_correct: Sequence[bool], b_correct: Sequence[bool]) -> dict:
    """Exact (binomial) McNemar test of paired correctness vectors.

    Returns ``a_only`` (a right, b wrong), ``b_only``, ``n_discordant`` and the two-sided
    ``p``; p = 1 without discordant pairs.
    """
    from scipy.stats import binomtest
    a = np.asarray(a_correct, dtype=bool)
    b = np.asarray(b_correct, dtype=bool)
    if a.shape != b.shape:
        raise ValueError(f"paired vectors differ in length: {a.shape} vs {b.shape}")
    a_only = int(np.sum(a & ~b))
    b_only = int(np.sum(~a & b))
    n = a_only + b_only
    p = 1.0 if n == 0 else float(binomtest(min(a_only, b_only), n, 0.5).pvalue)
    return {"test": "exact McNemar (binomial on discordant pairs)", "a_only": a_only,
            "b_only": b_only, "n_discordant": n, "n": int(a.size), "p": min(1.0, p)}


def wilcoxon_paired(a: Sequence[float], b: Sequence[float]) -> dict:
    """Wilcoxon signed-rank test of paired values (zero differences dropped), two-sided."""
    from scipy.stats import wilcoxon
    x = np.asarray(a, dtype=np.float64)
    y = np.asarray(b, dtype=np.float64)
    if x.shape != y.shape:
        raise ValueError(f"paired vectors differ in length: {x.shape} vs {y.shape}")
    d = x - y
    nz = int(np.count_nonzero(d))
    if nz == 0:
        return {"test": "Wilcoxon signed-rank", "statistic": 0.0, "n_nonzero": 0,
                "n": int(x.size), "mean_difference": 0.0, "p": 1.0}
    res = wilcoxon(x, y, zero_method="wilcox", alternative="two-sided")
    return {"test": "Wilcoxon signed-rank", "statistic": float(res.statistic), "n_nonzero": nz,
            "n": int(x.size), "mean_difference": float(d.mean()), "p": float(res.pvalue)}


def holm(pvalues: Sequence[float]) -> list[float]:
    """Holm–Bonferroni adjusted p-values, in the input order."""
    p = np.asarray(pvalues, dtype=np.float64)
    m = p.size
    order = np.argsort(p, kind="stable")
    adj = np.empty(m)
    running = 0.0
    for rank, i in enumerate(order):
        running = max(running, (m - rank) * p[i])
        adj[i] = min(1.0, running)
    return adj.tolist()


def pairwise_tests(values: dict[str, Sequence], test: str = "mcnemar",
                   alpha: float = 0.05) -> list[dict]:
    """Every pair of named paired vectors: the test, raw and Holm-adjusted p, significance."""
    names = list(values)
    fn = mcnemar_exact if test == "mcnemar" else wilcoxon_paired
    out = []
    for a, b in combinations(names, 2):
        r = fn(values[a], values[b])
        out.append({"a": a, "b": b, **r})
    for r, ph in zip(out, holm([r["p"] for r in out]), strict=True):
        r["p_holm"] = ph
        r["significant"] = bool(ph < alpha)
    return out


def normalise(weights: Sequence[float]) -> np.ndarray:
    """Non-negative weights -> a probability vector (uniform when they sum to 0)."""
    w = np.asarray(weights, dtype=np.float64)
    if np.any(w < 0):
        raise ValueError(f"negative weight in {w.tolist()}")
    s = w.sum()
    return np.full(w.size, 1.0 / w.size) if s <= 0 else w / s


def js_distance(p: Sequence[float], q: Sequence[float]) -> float:
    """Jensen–Shannon distance (base 2, in [0, 1]) between two non-negative weight vectors."""
    from scipy.spatial.distance import jensenshannon
    pp, qq = normalise(p), normalise(q)
    if pp.shape != qq.shape:
        raise ValueError(f"distributions differ in length: {pp.shape} vs {qq.shape}")
    return float(jensenshannon(pp, qq, base=2.0))


def tie_share(weights: Sequence[float], index: int) -> float:
    """1/k if ``index`` is among the k entries equal to the maximum of ``weights``, else 0.

    The expected hit of "the most-touched object is the one predicted" under random tie-breaking.
    """
    w = np.asarray(weights, dtype=np.float64)
    top = np.flatnonzero(np.isclose(w, w.max(), rtol=1e-9, atol=1e-12))
    return 1.0 / top.size if index in top else 0.0


def pareto_front(points: list[tuple[float, float]]) -> list[int]:
    """Indices of the points no other point beats (<= time and >= accuracy, one strictly)."""
    front = []
    for i, (t, a) in enumerate(points):
        dominated = any((t2 <= t and a2 >= a and (t2 < t or a2 > a))
                        for j, (t2, a2) in enumerate(points) if j != i)
        if not dominated:
            front.append(i)
    return sorted(front, key=lambda i: points[i][0])


def spearman_interval(sim_scores: np.ndarray, real_scores: np.ndarray, boot: int = 2000,
                      seed: int = 0) -> dict[str, Any]:
    """Spearman rho between the settings' mean scores on the two sides, with a percentile
    bootstrap 95 % interval (``scipy.stats.bootstrap``: the scenes of each side resampled,
    paired across settings). ``*_scores``: (settings, scenes) per-scene scores."""
    import warnings

    from scipy.stats import ConstantInputWarning, bootstrap, spearmanr
    a, b = np.asarray(sim_scores, float), np.asarray(real_scores, float)

    def rho(ia: np.ndarray, ib: np.ndarray) -> float:
        r = spearmanr(a[:, ia.astype(int)].mean(1), b[:, ib.astype(int)].mean(1)).statistic
        return float(r) if np.isfinite(r) else 0.0     # a resample where one side ties all
        # settings ranks nothing: counted as no agreement

    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ConstantInputWarning)   # handled: nan / 0 above
        point = spearmanr(a.mean(1), b.mean(1)).statistic   # nan if one side ties all
        if a.shape[1] < 2 or b.shape[1] < 2 or not np.isfinite(point):
            ci = [float("nan"), float("nan")]
        else:
            res = bootstrap((np.arange(a.shape[1]), np.arange(b.shape[1])), rho,
                            vectorized=False, n_resamples=boot, method="percentile",
                            rng=np.random.default_rng(seed))
            ci = [float(res.confidence_interval.low), float(res.confidence_interval.high)]
    return {"rho": float(point), "ci95": ci, "settings": int(a.shape[0])}
