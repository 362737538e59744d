"""Both touch sources implement ``sources.base.TouchSource``, and the trial code uses only it:
the scene draw, class numbers, the trial's no-contact frame and the depth perturbation."""

from __future__ import annotations

import inspect
from pathlib import Path

import cv2
import numpy as np
import pytest

from tactex_ros.core.errors import InputError
from tactex_ros.sources import open_source, trial_scene
from tactex_ros.sources.base import TouchSource


@pytest.fixture(scope="module")
def sim():
    return open_source("sim")


@pytest.fixture()
def replay(tmp_path: Path):
    rng = np.random.default_rng(0)
    for cls in ("a", "b", "c"):
        (tmp_path / cls).mkdir()
        for k in range(2):
            img = rng.integers(0, 255, (240, 320, 3), dtype=np.uint8)
            cv2.imwrite(str(tmp_path / cls / f"{k}.png"), img)
    return open_source(f"replay:{tmp_path}")


def test_both_sources_have_the_protocol_and_its_signatures(sim, replay):
    members = [m for m in dir(TouchSource) if not m.startswith("_")]
    assert set(members) == {"classes", "known_classes", "by_number", "draw_scene",
                            "no_contact", "trial"}
    for src in (sim, replay):
        assert isinstance(src, TouchSource)
        for m in members:
            want = getattr(TouchSource, m)
            if callable(want):
                assert list(inspect.signature(getattr(src, m)).parameters) == \
                    list(inspect.signature(want).parameters)[1:], (type(src).__name__, m)


def test_replay_scene_numbers_no_contact_and_depth(replay):
    assert replay.classes == replay.known_classes == ["a", "b", "c"]
    assert replay.draw_scene(2, 0) is None and replay.no_contact(0) is None
    with pytest.raises(InputError, match="class number 2"):
        replay.by_number(2)
    with pytest.raises(InputError, match="depth spread 0.3 mm"):
        replay.trial(["a", "a", "b"], 0, depth_spread_mm=0.3)
    classes, truth = trial_scene(replay, 2, seed=3)
    assert len(classes) == 3 and classes[0] == classes[truth] and set(classes) <= {"a", "b", "c"}


def test_sim_scene_numbers_no_contact_and_depth(sim):
    classes, truth = trial_scene(sim, 3, seed=4)
    # the comparisons are fabrics the source drew at its difficulty (known now, not catalogue)
    assert all(c in sim.known_classes and c not in sim.classes for c in classes[1:])
    assert classes[0] == classes[truth]
    assert sim.by_number(1) == sim.classes[0]
    # the trial's touches carry the no-contact frame the source names for the seed
    t = sim.trial(classes, 4)(1)
    np.testing.assert_array_equal(t.no_contact, sim.no_contact(4))
    # depth spread: depth = nominal middle + U(-s, s) from the seed's own stream, clipped
    s = 0.3
    lo, hi = sim.renderer.sensor.depth_mm
    d = float(np.clip(0.5 * (lo + hi) + np.random.default_rng([4, 29]).uniform(-s, s), 0.02, 2))
    t = sim.trial(classes, 4, depth_spread_mm=s)(2)
    assert t.no_contact is None
    np.testing.assert_array_equal(
        t.frame, sim.press(classes[2], np.random.default_rng([4, 23]), depth_mm=d))
