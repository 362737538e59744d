"""The numpy MLP metric (issue 23's nonlinear metric): forward, loss and backward on a tiny
seeded set, exact values and finite differences; training scenes; training starts at the
whitening and lowers its loss."""

import numpy as np
import pytest

from tactex_lab.analysis import mlp_metric
from tactex_ros.core import representation
from tactex_ros.core.errors import InputError


@pytest.fixture
def tiny():
    rng = np.random.default_rng(7)
    lib = {f"c{i}": rng.normal(i, 1.0, (3, 5)) for i in range(4)}
    base = representation.fit(lib)
    m = mlp_metric.MLPMetric(base, rng.normal(0, .5, (3, 5)), rng.normal(0, .1, 3),
                             rng.normal(0, .5, (5, 3)))
    x = np.concatenate(list(lib.values()))
    return m, x, np.repeat(np.arange(4), 3)


def test_forward_exact(tiny):
    m, x, _ = tiny
    f = m.apply(x)
    assert f.shape == (12, 5)
    np.testing.assert_allclose(f[0], [-0.63628415, -0.66863202, -1.44343585, -1.14916689,
                                      -1.09968935], atol=1e-8)
    np.testing.assert_allclose(f[5], [-0.71592612, -1.83837659, -0.69207945, 0.22607216,
                                      -0.52437807], atol=1e-8)
    # the residual branch on top of the whitening, by hand
    z = m.base.apply(x)
    np.testing.assert_allclose(f, z + np.maximum(z @ m.w1.T + m.b1, 0) @ m.w2.T)
    assert m.apply(x[None, :2]).shape == (1, 2, 5)


def test_episodes_exact_and_valid(tiny):
    _, _, cls = tiny
    a, cand, true = mlp_metric.episodes(cls, 4, 3, np.random.default_rng(1))
    assert a.tolist() == [3, 6, 11, 11]
    assert cand.tolist() == [[10, 4, 8], [5, 7, 2], [10, 7, 0], [9, 0, 5]]
    assert true.tolist() == [1, 1, 0, 0]
    a, cand, true = mlp_metric.episodes(cls, 500, 4, np.random.default_rng(2))
    for i in range(500):
        pos = cand[i, true[i]]
        assert cls[pos] == cls[a[i]] and pos != a[i]
        negs = [cls[cand[i, k]] for k in range(4) if k != true[i]]
        assert len(set(negs)) == 3 and cls[a[i]] not in negs
    with pytest.raises(InputError):
        mlp_metric.episodes(cls, 4, 5, np.random.default_rng(0))   # 4 classes < 5


@pytest.mark.parametrize("loss, value, w1, b1, w2", [
    ("episode", 0.5702989746327644, [0.01585287, 0.0459327, 0.03792668, 0.03697655, 0.03733163],
     [-0.0484286, 0.0995269, -0.01679912], [0.0764803, 0.0447361, 0.04238952]),
    ("triplet", 0.5856217433828883, [0.0902917, 0.22364896, 0.17019883, 0.15518533, 0.14252364],
     [-0.22018854, 0.68965839, -0.03819944], [0.03629343, 0.40030518, 0.04818339])])
def test_loss_and_backward_exact_and_match_finite_differences(tiny, loss, value, w1, b1, w2):
    m, x, cls = tiny
    a, cand, true = mlp_metric.episodes(cls, 4, 3, np.random.default_rng(1))
    z = m.base.apply(x)
    f, pre = m.forward(z)
    v, gf = mlp_metric.loss_and_grad(f, a, cand, true, 10.0, loss)
    g = mlp_metric.backward(m, z, pre, gf)
    assert v == pytest.approx(value, abs=1e-12)
    np.testing.assert_allclose(g["w1"][0], w1, atol=1e-8)
    np.testing.assert_allclose(g["b1"], b1, atol=1e-8)
    np.testing.assert_allclose(g["w2"][0], w2, atol=1e-8)

    def at(p, idx, eps):
        w = getattr(m, p)
        old = w[idx]
        w[idx] = old + eps
        out = mlp_metric.loss_and_grad(m.forward(z)[0], a, cand, true, 10.0, loss)[0]
        w[idx] = old
        return out
    for p in ("w1", "b1", "w2"):
        for idx in np.ndindex(getattr(m, p).shape):
            num = (at(p, idx, 1e-6) - at(p, idx, -1e-6)) / 2e-6
            assert num == pytest.approx(g[p][idx], abs=1e-7)


def test_fit_starts_at_the_whitening_and_lowers_its_loss():
    rng = np.random.default_rng(3)
    lib = {f"c{i}": rng.normal(0.3 * i, 1.0, (4, 6)) for i in range(8)}
    x = np.concatenate(list(lib.values()))
    m0, _ = mlp_metric.fit(lib, hidden=4, steps=0)
    np.testing.assert_allclose(m0.apply(x), representation.fit(lib).apply(x))
    m, log = mlp_metric.fit(lib, hidden=8, steps=150, scenes=64, lr=1e-2, seed=1)
    assert log["loss"][-1]["loss"] < 0.7 * log["loss"][0]["loss"]
    assert log["tau"] > 0 and np.any(m.w2 != 0)
    with pytest.raises(InputError):
        mlp_metric.fit(lib, loss="hinge")
