"""One Wilson score interval for the product and the lab (``core.stats.wilson``, scipy's
``binomtest(...).proportion_ci(method="wilson")``): exact values, the edges, n = 0."""

import math

import pytest

from tactex_ros.core.stats import wilson


def _by_hand(k: int, n: int, z: float = 1.959963984540054) -> tuple[float, float]:
    """(p + z^2/2n -+ z sqrt(p(1-p)/n + z^2/4n^2)) / (1 + z^2/n), z of the two-sided 95 %."""
    p = k / n
    mid, half = p + z * z / (2 * n), z * math.sqrt(p * (1 - p) / n + z * z / (4 * n * n))
    return (mid - half) / (1 + z * z / n), (mid + half) / (1 + z * z / n)


def test_exact_values():
    assert wilson(8, 10) == pytest.approx((0.4901624715366418, 0.9433178485456248), abs=1e-15)
    assert wilson(1, 2) == pytest.approx((0.0945312057342307, 0.9054687942657693), abs=1e-15)
    for k, n in ((3, 7), (1, 40), (39, 40), (250, 1000)):
        assert wilson(k, n) == pytest.approx(_by_hand(k, n), abs=1e-14)
    lo, hi = wilson(8, 10, confidence=0.99)                  # wider at 99 %
    assert lo < 0.4901624715366418 and hi > 0.9433178485456248


def test_the_edges_and_no_trial():
    assert wilson(0, 10) == (0.0, pytest.approx(0.27753279986288926, abs=1e-15))
    assert wilson(10, 10) == (pytest.approx(0.7224672001371109, abs=1e-15), 1.0)
    assert wilson(0, 0) == (0.0, 1.0)


def test_the_lab_takes_the_products():
    stats = pytest.importorskip("tactex_lab.analysis.stats")
    assert stats.wilson is wilson
