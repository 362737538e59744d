"""`tactex experiment families`: the offline stop (theta and the not-sure rule) agrees with the
engine run with that stop, and the per-family choices follow their definitions."""

import argparse

import numpy as np

from tactex_ros.core import calibration as cal
from tactex_ros.core.config import TrialConfig, preset
from tactex_ros.core.engine import TrialSpec, run_trial
from tactex_lab.experiments import families as fam


def _library(seed: int, classes: int = 8, presses: int = 4, d: int = 106, noise: float = 0.8):
    rng = np.random.default_rng(seed)
    return {f"k{c}": rng.normal(0, 1.0, d) + rng.normal(0, noise, (presses, d))
            for c in range(classes)}


def test_offline_stop_equals_the_engine_with_the_rule(tmp_path):
    args = argparse.Namespace(folds=2, scenes=6, budget=6, cache_dir=str(tmp_path))
    presses = _library(0)
    trajs = fam.run_family("x", presses, [0], args, 0.05)
    assert len(trajs) == 12 and len(list(tmp_path.glob("trials_x_*.npz"))) == 1
    again = fam.run_family("x", presses, [0], args, 0.05)          # from the cache
    np.testing.assert_array_equal(again[3].evidence, trajs[3].evidence)
    # another descriptor (--feature) is another cache file, never the 106-number one's
    args.feature = "frame_hm"
    fam.run_family("x", {k: np.hstack([v, v[:, :23]]) for k, v in presses.items()}, [0], args,
                   0.05)
    assert len(list(tmp_path.glob("trials_x_frame_hm_*.npz"))) == 1
    del args.feature
    # the same trials run by the engine with the stop 0.9 and the rule off, s0 = 2 (every stop
    # later) and s0 = 3 (5 of 12 end not sure): the same ends
    groups = cal.class_split(sorted(presses), 2, 0)
    base = fam.outcome(trajs, 0.05, 0.9)
    assert base["sure"].all()
    for s0, sure in ((0.0, 12), (2.0, 12), (3.0, 7)):
        off = fam.outcome(trajs, 0.05, 0.9, s0)
        assert np.sum(off["sure"]) == sure
        if s0:
            assert np.all(off["extra"] > base["extra"])
        k = 0
        for g, held in enumerate(groups):
            rng = np.random.default_rng([0, 53, g])
            for s in range(6):
                plat, truth, touch = cal._scene(held, presses, 4, rng)
                spec = TrialSpec(4, preset("descriptor", guards=False),
                                 TrialConfig(rounds=6, stop_confidence=0.9,
                                             stop_separation=s0), seed=s)
                res = run_trial(spec, touch, truth=truth)
                assert res.sure == off["sure"][k] and res.correct == off["correct"][k]
                assert res.touches - 5 == off["extra"][k]
                k += 1


def test_choices_follow_their_definitions(tmp_path):
    args = argparse.Namespace(folds=2, scenes=6, budget=6, cache_dir=str(tmp_path))
    fams = [fam.run_family(f"f{i}", _library(i, noise=n), [0], args, 0.05)
            for i, n in enumerate((0.5, 1.2))]
    s0 = fam.choose_separation(fams, 0.05)
    assert s0 in fam.SEPARATIONS
    for t in fams:
        o = fam.outcome(t, 0.05, 0.9, s0)
        assert np.mean(o["sure"] & ~o["correct"]) <= fam.GOAL or s0 == fam.SEPARATIONS[-1]
    sc = fam.score(fams[0], 0.05, 0.0)
    o = fam.outcome(fams[0], 0.05, 0.9)
    assert sc["0.9"]["wrong_stop"] == np.mean(o["sure"] & ~o["correct"])
    assert sc["0.9"]["not_sure"] == 1 - np.mean(o["sure"])
    p = fam.paired(fams[0], 0.05, fams[0], 0.05)
    assert p["0.9"]["mcnemar_p"] == 1.0 and p["0.9"]["wilcoxon_p"] == 1.0


def test_each_feature_is_described_and_tempered_as_its_preset():
    import pytest
    from tactex_ros.core.descriptor import descriptor_size as size
    from tactex_ros.core.errors import InputError
    default = fam.feature_settings("default")
    assert (size(default), default.match_temperature) == (257, 0.0251)
    assert default.descriptor_embedding_frames == 4
    hm, old = fam.feature_settings("frame_hm"), fam.feature_settings("frame")
    assert (size(hm), hm.match_temperature) == (129, 0.05)
    assert (size(old), old.match_temperature) == (106, 0.05)
    with pytest.raises(InputError, match="default"):
        fam.feature_settings("frames4")
