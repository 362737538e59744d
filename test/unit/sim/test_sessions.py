"""Recording sessions (``sim:recorded``): every class its own session background, every press
its own no-contact frame; the live mode (``sim``) keeps one background per trial."""

from __future__ import annotations

import numpy as np
import pytest

from tactex_ros.core.errors import InputError
from tactex_ros.sim.render import GelSightRenderer, SensorModel
from tactex_ros.sources import open_source


@pytest.fixture(scope="module")
def renderer() -> GelSightRenderer:
    return GelSightRenderer()


def _means(frames: list[np.ndarray]) -> np.ndarray:
    return np.array([f.reshape(-1, 3).mean(axis=0) for f in frames])


@pytest.mark.slow
def test_session_and_press_spreads_follow_the_sensor_model(renderer):
    s = renderer.sensor
    rng = np.random.default_rng(0)
    sessions = [renderer.session_background(rng) for _ in range(300)]
    m = _means(sessions)
    # one brightness factor: the channel means move together by session_offset_rgb per unit
    np.testing.assert_allclose(m.std(axis=0), s.session_offset_rgb, rtol=0.15)
    assert np.corrcoef(m.T)[0, 1] > 0.95
    base = sessions[0]
    presses = [renderer.press_background(base, rng) for _ in range(300)]
    np.testing.assert_allclose(_means(presses).std(axis=0), s.press_offset_rgb, rtol=0.15)
    np.testing.assert_allclose(_means(presses).mean(axis=0), _means([base])[0], atol=0.05)
    # the large-scale pattern moves (not only brightness and contrast)
    a, b = sessions[1], sessions[2]
    za = (a - a.mean((0, 1))) / a.std((0, 1))
    zb = (b - b.mean((0, 1))) / b.std((0, 1))
    assert np.abs(za - zb).mean() > 0.05
    for f in sessions[:3] + presses[:3]:
        assert f.dtype == np.float32 and f.shape == (240, 320, 3)
        assert f.min() >= 0 and f.max() <= 255


def test_no_session_spread_gives_the_sensors_background():
    zero = (0.0, 0.0, 0.0)
    r = GelSightRenderer(SensorModel(session_offset_rgb=zero, session_contrast_rgb=zero,
                                     session_pattern=0.0))
    bg = r.session_background(np.random.default_rng(1))
    np.testing.assert_allclose(bg, r.background, atol=1e-3)


def test_contact_frame_is_rendered_on_the_given_background(renderer):
    rng = np.random.default_rng(2)
    bright = np.clip(renderer.background + 20.0, 0, 255).astype(np.float32)
    heights = np.zeros((240, 320), np.float32)          # flat: no contact pattern
    a = renderer.render(heights, 0.3, np.random.default_rng(5))
    b = renderer.render(heights, 0.3, np.random.default_rng(5), background=bright)
    assert (b.astype(float) - a).mean() == pytest.approx(20.0 * (bright < 255).mean(), abs=0.6)
    with pytest.raises(ValueError, match="background of shape"):
        renderer.render(heights, 0.3, rng, background=bright[:100])
    with pytest.raises(ValueError, match="float32"):
        renderer.no_contact(rng, background=bright.astype(np.float64))


def test_recorded_trials_share_a_class_session_live_trials_one_background():
    rec, live = open_source("sim:recorded"), open_source("sim")
    assert rec.recorded and not live.recorded
    classes = ["denim", "satin", "denim"]
    touch = rec.trial(classes, seed=3)
    ts = [touch(i) for i in (0, 1, 2, 0, 2)]
    m = _means([t.no_contact for t in ts])
    # the same class (platforms 0 and 2): backgrounds within the press spread (+ rounding);
    # another class: its own session, a different background
    same = np.abs(m[[0, 2, 3, 4]] - m[0]).max()
    other = np.abs(m[1] - m[0]).max()
    assert same < 1.0 < other
    # every press its own no-contact frame, and the contact frame is on it
    assert not np.array_equal(ts[0].no_contact, ts[3].no_contact)
    for t in ts:
        assert np.abs(t.frame.astype(float).mean() - t.no_contact.astype(float).mean()) < 3.0
    # a class's session is the same in every trial (a recorded dataset's is fixed)
    again = rec.trial(["satin", "denim"], seed=11)(1).no_contact
    assert np.abs(_means([again])[0] - m[0]).max() < 1.0
    # live: one no-contact frame for every touch of the trial
    lt = live.trial(classes, seed=3)
    assert np.array_equal(lt(0).no_contact, lt(1).no_contact)


@pytest.mark.parametrize("spec", ["sim:medium:live", "sim:easy:hard", "sim:recorded:easy",
                                  "sim:2"])
def test_bad_sim_specs_are_named(spec):
    with pytest.raises(InputError, match="sim"):
        open_source(spec)


def test_good_sim_specs():
    assert open_source("sim:recorded").difficulty == 0.5
    s = open_source("sim:hard:recorded")
    assert s.recorded and s.difficulty == 0.8
