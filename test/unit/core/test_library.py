"""The fabric library (core/library.py): the belief with known fabrics, the unknown-fabric
component, the file."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.stats import norm

from tactex_ros.core import library as flib
from tactex_ros.core.config import preset
from tactex_ros.core.descriptor import DescriptorLearner
from tactex_ros.core.errors import InputError
from tactex_ros.core.texture import descriptor_dim
from tactex_ros.core.touch import Touch

# three fabrics in 2 dimensions, 3 presses each
MEANS = {"denim": [4.0, 0.0], "felt": [0.0, 4.0], "silk": [-4.0, -4.0]}
OFFSETS = np.array([[0.5, 0.0], [-0.5, 0.5], [0.0, -0.5]])


def _lib() -> flib.FabricLibrary:
    lib = flib.FabricLibrary()
    for name, m in MEANS.items():
        lib = lib.add(name, np.asarray(m) + OFFSETS, [f"{name}/{i}" for i in range(3)])
    return lib


def _brute_force(lb: flib.LibraryBelief, means: np.ndarray, counts: np.ndarray,
                 scene: np.ndarray) -> np.ndarray:
    """The same model written out: b_h K_h, K_h = P(z_0 = z_h | x) / P(z_0 = z_h) =
    P(x_0, x_h same fabric) / (P(x_0) P(x_h)), the densities tempered."""
    F = lb.F
    prior = np.append(np.ones(F), 1.0) / (F + 1.0)
    xb = means / lb.scale
    dens = np.zeros((len(means), F + 1))
    for p in range(len(means)):
        for f in range(F):
            sd = np.sqrt(lb.s2 * (1 / counts[p] + 1 / lb.n[f]))
            dens[p, f] = np.exp(lb.beta * norm.logpdf(xb[p], lb.means[f], sd).sum())
        sd = np.sqrt(lb.B + lb.s2 / counts[p])
        dens[p, F] = np.exp(lb.beta * norm.logpdf(xb[p], lb.g, sd).sum())
    marg = dens @ prior
    k = np.array([(prior * dens[0] * dens[h]).sum()
                  for h in range(1, len(scene) + 1)]) / (marg[0] * marg[1:])
    r = k ** lb.weight * scene
    return r / r.sum()


def test_known_fabric_placed_again_moves_the_belief_to_its_comparison():
    lb = flib.library_belief(_lib(), None, temperature=0.5, weight=1.0)
    # reference felt; comparisons denim, felt, silk and an unknown fabric at (0, -4)
    means = np.array([[0.2, 3.8], [4.1, 0.2], [-0.1, 4.2], [-3.9, -4.1], [0.0, -4.0]])
    counts = np.array([1.0, 1.0, 1.0, 1.0, 1.0])
    scene = np.array([0.3, 0.3, 0.2, 0.2])        # the scene alone does not favour felt
    b = lb.belief(means, counts, scene)
    np.testing.assert_allclose(b, _brute_force(lb, means, counts, scene), rtol=1e-10)
    assert int(np.argmax(b)) == 1 and b[1] > scene[1] + 0.15     # toward felt
    np.testing.assert_allclose(b, [0.29662204, 0.48967955, 0.08045648, 0.13324193], rtol=1e-6)
    q = lb.posteriors(means, counts)
    assert q.shape == (5, 4) and np.argmax(q[0]) == 1      # the reference is felt
    # half the library's evidence: half as far from the scene belief (in log odds)
    half = flib.library_belief(_lib(), None, temperature=0.5, weight=0.5)
    bh = half.belief(means, counts, scene)
    np.testing.assert_allclose(bh, _brute_force(half, means, counts, scene), rtol=1e-10)
    assert scene[1] < bh[1] < b[1]


def test_an_unknown_fabric_gives_todays_belief_exactly():
    lb = flib.library_belief(_lib(), None, temperature=0.5)
    far = np.array([[40.0, 40.0], [41.0, 40.0], [40.0, 42.0], [39.0, 40.0], [40.0, 38.0]])
    scene = np.array([0.1, 0.6, 0.2, 0.1])
    assert lb.posteriors(far, np.ones(5))[:, -1].min() == 1.0     # every platform: new
    np.testing.assert_allclose(lb.belief(far, np.ones(5), scene), scene, rtol=0, atol=1e-15)
    # the empty library: today's belief, the very array
    empty = flib.library_belief(flib.FabricLibrary(), None, 0.5)
    assert empty.belief(far, np.ones(5), scene) is not None
    np.testing.assert_array_equal(empty.belief(far, np.ones(5), scene), scene)


def test_learner_belief_with_a_library_and_without():
    cfg = preset("descriptor", guards=False)
    D = descriptor_dim(cfg.descriptor_height_map)
    rng = np.random.default_rng(3)
    plain, learned = DescriptorLearner(2, cfg), DescriptorLearner(2, cfg)
    base = {k: rng.normal(0, 1, D) * 3 for k in ("a", "b")}
    lib = flib.FabricLibrary()
    for k, m in base.items():
        lib = lib.add(k, m + rng.normal(0, 0.3, (4, D)), [f"{k}/{i}" for i in range(4)])
    learned.use_library(lib)
    assert learned.library_state == {"used": True, **lib.state()}
    assert plain.library_state == {"used": False}
    for learner in (plain, learned):
        r = np.random.default_rng(7)
        learner.add_reference(Touch(np.zeros((1, 1, 3), np.uint8), descriptor=base["b"]
                                    + r.normal(0, 0.3, D)))
        learner.add_touch(Touch(np.zeros((1, 1, 3), np.uint8), descriptor=base["a"]
                                + r.normal(0, 0.3, D)), 0)
        learner.add_touch(Touch(np.zeros((1, 1, 3), np.uint8), descriptor=base["b"]
                                + r.normal(0, 0.3, D)), 1)
    p0, p1 = plain.belief(None), learned.belief(None)
    np.testing.assert_array_equal(p0, plain.match.belief())
    assert p1[1] > p0[1]


def test_library_file_round_trip_and_state(tmp_path):
    lib = _lib()
    path = flib.save(lib, tmp_path / flib.LIBRARY_FILE)
    back = flib.load(path)
    np.testing.assert_array_equal(back.descriptors, lib.descriptors)
    assert back.names == lib.names and back.sources == lib.sources
    assert back.state() == lib.state() == {"fabrics": 3, "presses": 9,
                                           "sha256": lib.sha256()[:16]}
    # a press filed twice counts once; leaving sources out
    assert lib.add("denim", np.zeros((1, 2)), ["denim/0"]) is lib
    assert lib.without(["felt/0", "felt/1"]).presses == 7
    assert flib.load(tmp_path / "none.npz", missing_ok=True).presses == 0


def test_torn_library_file_is_refused_with_its_path(tmp_path):
    path = flib.save(_lib(), tmp_path / flib.LIBRARY_FILE)
    data = path.read_bytes()
    path.write_bytes(data[: len(data) // 2])
    with pytest.raises(InputError, match=str(path)):
        flib.load(path)
    from tactex_ros.trial.library import LibraryKeeper
    with pytest.raises(InputError, match=str(path)):
        LibraryKeeper(path, preset("descriptor"))


def test_a_library_of_the_other_descriptor_is_refused_by_setting():
    rng = np.random.default_rng(5)
    lib = flib.FabricLibrary()
    for k in ("a", "b"):
        lib = lib.add(k, rng.normal(0, 1, (3, descriptor_dim(False))), [f"{k}/{i}" for i in range(3)])
    with pytest.raises(InputError, match="learner.descriptor_height_map=false"):
        DescriptorLearner(2, preset("descriptor", guards=False)).use_library(lib)
    learner = DescriptorLearner(2, preset("descriptor", guards=False, descriptor_height_map=False))
    learner.use_library(lib)
    assert learner.library_state["used"]
