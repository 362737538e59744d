"""The product's statistics: the Wilson score interval of a proportion (the session report's
accuracy band; the lab's analysis takes the same one, ``tactex_lab.analysis.stats``)."""

from __future__ import annotations


def wilson(successes: int, n: int, confidence: float = 0.95) -> tuple[float, float]:
    """The Wilson score interval (low, high) of the proportion ``successes`` / ``n`` at
    ``confidence`` (scipy's ``binomtest(successes, n).proportion_ci(method="wilson")``, no
    continuity correction); (0.0, 1.0) for n = 0: no trial, any proportion."""
    if n <= 0:
        return 0.0, 1.0
    from scipy.stats import binomtest
    ci = binomtest(int(successes), int(n)).proportion_ci(confidence_level=confidence,
                                                          method="wilson")
    return float(ci.low), float(ci.high)
