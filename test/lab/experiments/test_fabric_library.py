"""`tactex experiment library`: the arms of a trial touch the same presses, the library grows by
the videos each trial touched, and a trial's belief never sees a video the trial touched."""

from __future__ import annotations

import argparse

import numpy as np

import pytest

from tactex_ros.core import descriptor
from tactex_ros.core.config import preset
from tactex_ros.core.errors import InputError
from tactex_ros.core.library import FabricLibrary
from tactex_lab.experiments import fabric_library as fl

CLASSES = [f"c{i}" for i in range(6)]


def _presses(per: int = 4) -> tuple[np.ndarray, np.ndarray]:
    """``per`` synthetic press descriptors (106 numbers) of each class: a class mean + noise."""
    rng = np.random.default_rng(0)
    means = rng.normal(0, 1, (len(CLASSES), 106))
    cls = np.repeat(CLASSES, per)
    x = means.repeat(per, axis=0) + rng.normal(0, 0.3, (len(cls), 106))
    return x, cls


def test_a_trial_never_sees_a_video_it_touched(monkeypatch):
    x, cls = _presses()
    lib = FabricLibrary()
    for i, (v, c) in enumerate(zip(x, cls, strict=True)):
        lib = lib.add(str(c), v[None], [str(i)])
    seen: list[int] = []
    real = descriptor.DescriptorLearner.use_library

    def spy(self, library, weight=fl.EVIDENCE_WEIGHT):
        real(self, library, weight)
        seen.append(self.library_state["presses"])
    monkeypatch.setattr(descriptor.DescriptorLearner, "use_library", spy)
    scene = ["c1", "c0", "c1", "c2", "c3"]
    _, log = fl.run_trial_arm(x, cls, scene, seed=4, budget=4, library=lib,
                                learner="descriptor")
    touched = {v for _, v in log}
    assert seen[0] == len(x) and seen[-1] == len(x) - len(touched)
    assert seen == sorted(seen, reverse=True)


def test_a_replayed_session_learns_and_its_arms_are_paired():
    x, cls = _presses()
    args = argparse.Namespace(trials=5, comparisons=4, budget=3, stop=0.9, weights=[0.25, 1.0],
                              learner="descriptor")
    rows = fl.run_session(x, cls, seed=2, args=args, log=lambda text: None)
    assert [r["trial"] for r in rows] == [1, 2, 3, 4, 5]
    assert rows[0]["library"]["presses"] == 0 and not rows[0]["reference_known"]
    grow = [r["library"]["presses"] for r in rows]
    assert grow == sorted(grow) and grow[-1] > 0
    earlier: set[str] = set()          # every platform is touched in the baseline
    for r in rows:
        assert set(r) >= {"off", "on", "on_w1"}
        assert r["reference_known"] == (r["scene"][0] in earlier)
        assert r["platforms_known"] == sum(c in earlier for c in r["scene"][1:])
        earlier |= set(r["scene"])
    s = fl.summarise(rows, 1, fl.arm_names(args.weights))
    assert s["all"]["n"] == 5 and s["reference_new"]["n"] + s["reference_known"]["n"] == 5
    assert "mcnemar_vs_off" in s["all"]["on"] and "mcnemar_vs_off" not in s["all"]["off"]



def test_a_press_without_contact_never_joins_the_library():
    """A press the contact guard rejects is pressed again in the session's trials and never
    filed in the library; every other press a trial touched is."""
    x, cls = _presses()
    rejected = np.zeros(len(x), bool)
    rejected[[1, 9, 13, 17]] = True                  # one press of c0, c2, c3 and c4
    args = argparse.Namespace(trials=6, comparisons=4, budget=3, stop=0.9, weights=[0.25],
                              learner="descriptor")
    rows = fl.run_session(x, cls, seed=2, args=args, log=lambda text: None, rejected=rejected)
    filed: set[str] = set()
    touched_bad = 0
    for t, (row, scene) in enumerate(zip(rows, fl.study_scenes(CLASSES, 6, 4, 2), strict=True)):
        assert row["library"]["presses"] == len(filed)
        log = fl.run_trial_arm(x, cls, scene, 2 * 1000 + t, 3, None, rejected=rejected,
                                 learner="descriptor")[1]
        touched_bad += sum(bool(rejected[int(v)]) for _, v in log)
        filed |= {v for _, v in log if not rejected[int(v)]}
    assert touched_bad > 0                            # the scenes did touch a rejected press


def test_the_shipped_learner_arm_runs_the_default_settings_on_its_own_descriptor_size():
    """``--learner shipped`` (the default) is the shipped default learner (embedding included)
    with only the guards and the library switch changed; a session on descriptors of its size
    files them in a library of that size."""
    want = preset("default")
    cfg = fl.learner_cfg("shipped", 0, library=True)
    assert cfg.descriptor_embedding == want.descriptor_embedding != ""
    assert cfg.match_temperature == want.match_temperature
    assert (cfg.guards, cfg.fabric_library) == (False, True)
    size = descriptor.descriptor_size(want)
    rng = np.random.default_rng(1)
    means = rng.normal(0, 1, (len(CLASSES), size))
    cls = np.repeat(CLASSES, 4)
    x = means.repeat(4, axis=0) + rng.normal(0, 0.3, (len(cls), size))
    args = argparse.Namespace(trials=3, comparisons=4, budget=2, stop=0.9, weights=[0.25],
                              learner="shipped")
    rows = fl.run_session(x, cls, seed=3, args=args, log=lambda text: None)
    assert rows[-1]["library"]["presses"] > 0
    with pytest.raises(InputError, match="shipped, descriptor"):
        fl.learner_cfg("cnn", size, library=False)
