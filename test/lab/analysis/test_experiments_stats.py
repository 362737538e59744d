"""Statistics helpers of the experiments on hand-computed cases."""

import math

import numpy as np
import pytest

from tactex_lab.analysis import stats


def test_mean_std_sample_std():
    r = stats.mean_std([1, 2, 3, 4])
    assert r["mean"] == 2.5 and r["n"] == 4
    assert r["std"] == pytest.approx(math.sqrt(5 / 3))
    assert stats.mean_std([0.7]) == {"mean": 0.7, "std": 0.0, "n": 1}
    assert stats.mean_std([])["n"] == 0


def test_wilson_interval():
    lo, hi = stats.wilson(0, 10)
    assert lo == 0.0 and hi == pytest.approx(0.2775, abs=1e-3)
    lo, hi = stats.wilson(5, 10)
    assert lo == pytest.approx(0.2366, abs=1e-3) and hi == pytest.approx(0.7634, abs=1e-3)


def test_confusion_rows_truth_columns_prediction():
    cm = stats.confusion(["a", "a", "b", "c"], ["a", "b", "b", "a"], ["a", "b", "c"])
    np.testing.assert_array_equal(cm, [[1, 1, 0], [0, 1, 0], [1, 0, 0]])
    assert stats.confusion([], [], ["a", "b"]).shape == (2, 2)


def test_mcnemar_exact_on_discordant_pairs():
    a = [1, 1, 1, 0, 0, 1]
    b = [0, 0, 0, 0, 1, 1]
    r = stats.mcnemar_exact(a, b)
    assert (r["a_only"], r["b_only"], r["n_discordant"]) == (3, 1, 4)
    assert r["p"] == pytest.approx(2 * 5 / 16)          # 2 * P(X <= 1), X ~ Bin(4, 1/2)
    r = stats.mcnemar_exact([1] * 6 + [0], [0] * 6 + [0])
    assert r["p"] == pytest.approx(2 / 64)               # 2 * (1/2)^6
    assert stats.mcnemar_exact([1, 0], [1, 0])["p"] == 1.0
    with pytest.raises(ValueError):
        stats.mcnemar_exact([1], [1, 0])


def test_wilcoxon_paired_exact_and_zero_differences():
    r = stats.wilcoxon_paired([1, 2, 3, 4, 5, 7], [0, 0, 0, 0, 0, 7])
    assert r["n_nonzero"] == 5
    assert r["p"] == pytest.approx(2 / 32)               # all 5 ranks positive: 2 * (1/2)^5
    assert stats.wilcoxon_paired([0.5, 1], [0.5, 1])["p"] == 1.0


def test_holm_adjustment():
    assert stats.holm([0.01, 0.04, 0.03]) == pytest.approx([0.03, 0.06, 0.06])
    assert stats.holm([0.5, 0.9]) == pytest.approx([1.0, 1.0])


def test_pairwise_tests_pairs_and_flags():
    out = stats.pairwise_tests({"x": [1] * 8, "y": [0] * 8, "z": [1] * 8})
    assert [(r["a"], r["b"]) for r in out] == [("x", "y"), ("x", "z"), ("y", "z")]
    assert out[0]["p"] == pytest.approx(2 / 256) and out[0]["significant"]
    assert out[1]["p"] == 1.0 and not out[1]["significant"]


def test_js_distance_hand_computed():
    assert stats.js_distance([1, 0], [0, 1]) == pytest.approx(1.0)
    assert stats.js_distance([3, 1, 2], [6, 2, 4]) == pytest.approx(0.0, abs=1e-7)
    # M = (0.75, 0.25); KL(p||M) = log2(4/3); KL(q||M) = 0.5 log2(2/3) + 0.5 log2(2)
    jsd = 0.5 * (math.log2(4 / 3) + 0.5 * math.log2(2 / 3) + 0.5)
    assert stats.js_distance([2, 0], [3, 3]) == pytest.approx(math.sqrt(jsd))
    assert stats.js_distance([1, 2], [2, 1]) == pytest.approx(stats.js_distance([2, 1], [1, 2]))
    with pytest.raises(ValueError):
        stats.js_distance([1, -1], [1, 1])


def test_tie_share():
    assert stats.tie_share([1, 3, 3, 0], 1) == 0.5
    assert stats.tie_share([1, 3, 3, 0], 0) == 0.0
    assert stats.tie_share([5, 1, 1], 0) == 1.0
    assert stats.tie_share([1, 1, 1, 1], 2) == 0.25
