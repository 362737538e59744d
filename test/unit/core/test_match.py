"""The descriptor model: texture descriptor, match belief, information gain, stop rule."""

import math

import numpy as np
import pytest

from tactex_ros.core import texture
from tactex_ros.core.config import preset
from tactex_ros.core.engine import TrialConfig, TrialEngine, trial_preset
from tactex_ros.core.errors import InputError
from tactex_ros.core.match import MatchModel, softmax
from tactex_ros.core.strategies import Strategy
from tactex_ros.core.touch import Touch


def _frames(kind: int, rng: np.random.Generator, n: int = 1) -> list[Touch]:
    """Touches of a synthetic texture class: a grating of period 6 + 4 kind px at a random
    angle, pressed into a smooth background (the no-contact frame)."""
    yy, xx = np.mgrid[0:240, 0:320].astype(np.float32)
    bg = np.stack([60 + 20 * np.sin(xx / 90.0), 95 + 10 * np.cos(yy / 70.0),
                   105 + 0 * xx], axis=-1)
    out = []
    for _ in range(n):
        a = rng.uniform(0, np.pi)
        period = 6.0 + 4.0 * kind
        g = np.sin(2 * np.pi * (xx * np.cos(a) + yy * np.sin(a)) / period)
        contact = bg + 6.0 * g[..., None] * np.array([1.0, 0.6, -0.8])
        noise = rng.normal(0, 1.0, bg.shape)
        out.append(Touch(frame=np.clip(contact + noise, 0, 255).astype(np.uint8),
                         no_contact=np.clip(bg + rng.normal(0, 1.0, bg.shape), 0, 255)
                         .astype(np.uint8)))
    return out


def test_descriptor_invariant_to_half_turn_and_sized():
    t = _frames(1, np.random.default_rng(0))[0]
    d = texture.describe(t.frame, t.no_contact)
    r = texture.describe(t.frame[::-1, ::-1].copy(), t.no_contact[::-1, ::-1].copy())
    assert d.shape == (texture.DIM,) == (106,)
    # equal up to pixel sampling (LBP interpolation, the half-resolution LBP's resize)
    np.testing.assert_allclose(d, r, rtol=1e-3, atol=2e-3)
    other = _frames(3, np.random.default_rng(0))[0]
    assert np.abs(texture.describe(other.frame, other.no_contact) - d).max() > 0.5
    with pytest.raises(InputError, match="no-contact frame"):
        texture.describe(t.frame, t.no_contact[:100])


def test_belief_matches_hand_computed_value():
    # D = 1: reference 0, c1 0, c2 2 (one touch each). Scene spread s = std([0, 0, 2]),
    # scale = sqrt(s^2 + (0.05 s)^2); no repeats -> sigma^2 = kappa^2 = 0.25; v = 1 + 1 = 2.
    m = MatchModel(2, prior_scale=0.5, prior_strength=4.0, temperature=1.0)
    for p, x in ((0, 0.0), (1, 0.0), (2, 2.0)):
        m.add(p, np.array([x]))
    s = np.std([0.0, 0.0, 2.0])
    u = 2.0 / math.sqrt(s ** 2 + (0.05 * s) ** 2)
    gap = 0.5 * u ** 2 / 0.25 / 2.0          # l1 - l2 (the log v terms cancel)
    assert m.belief()[0] == pytest.approx(1.0 / (1.0 + math.exp(-gap)), rel=1e-9)
    # a second reference touch at 2: reference mean 1, k = 2, v = 1/2 + 1 = 1.5; the spread
    # of the platform means [1, 0, 2] changes the units
    m.add(0, np.array([2.0]))
    s2 = np.std([1.0, 0.0, 2.0])
    sc = math.sqrt(s2 ** 2 + (0.05 * s2) ** 2)
    # pooled within-platform variance: reference touches 0 and 2 around 1 -> SS = 2 / sc^2
    sigma2 = (4.0 * 0.25 + 2.0 / sc ** 2) / (4.0 + 1.0)
    l1 = -0.5 * math.log(1.5) - 0.5 * (1.0 / sc) ** 2 / sigma2 / 1.5
    l2 = -0.5 * math.log(1.5) - 0.5 * (1.0 / sc) ** 2 / sigma2 / 1.5
    np.testing.assert_allclose(m.belief(), softmax(np.array([l1, l2])), rtol=1e-9)


def test_info_gain_prefers_the_reference_when_it_is_the_noisy_one():
    # c1 and c2 known from 10 touches each; one reference touch half way: only touching the
    # reference again can separate them.
    rng = np.random.default_rng(0)
    m = MatchModel(2, temperature=1.0)
    for p, mu in ((1, -1.0), (2, 1.0)):
        for _ in range(10):
            m.add(p, mu + 0.3 * rng.standard_normal(3))
    m.add(0, np.zeros(3))
    g = m.info_gain(np.random.default_rng(1), draws=200)
    assert g.shape == (3,) and int(np.argmax(g)) == 0 and g[0] > 2 * max(g[1], g[2])


def test_posterior_draws_shape_and_mean_near_belief():
    m = MatchModel(3, temperature=0.5)
    rng = np.random.default_rng(2)
    for p in range(4):
        for _ in range(3):
            m.add(p, rng.normal(p % 3, 1.0, 5))
    draws = m.samples(2000, np.random.default_rng(3))
    assert draws.shape == (2000, 3)
    np.testing.assert_allclose(draws.sum(axis=1), 1.0)
    assert int(np.argmax(draws.mean(axis=0))) == int(np.argmax(m.belief()))


def test_belief_refuses_missing_platforms_and_bad_descriptors():
    m = MatchModel(2)
    m.add(0, np.ones(3))
    with pytest.raises(InputError, match="missing"):
        m.belief()
    with pytest.raises(InputError, match="differs"):
        m.add(1, np.ones(4))
    with pytest.raises(InputError, match="finite"):
        m.add(1, np.array([np.nan, 1.0, 1.0]))


def _touch_fn(platform_kinds: list[int], seed: int):
    rng = np.random.default_rng(seed)
    return lambda p: _frames(platform_kinds[p], rng)[0]


def test_stop_rule_stops_confident_and_records_why():
    # reference = kind 0 = comparison 1; the others clearly different
    kinds = [0, 0, 2, 4, 6]
    eng = TrialEngine(4, preset("default"), trial_preset("default", rounds=10), seed=0)
    res = eng.run(_touch_fn(kinds, 0), truth=1)
    assert res.correct and res.stop_reason == "confident"
    # at or above the shipped stop (0.9; 0.95 before the height map joined the descriptor)
    assert max(res.final.probs) >= eng.trial_cfg.stop_confidence and res.touches < 15
    eng2 = TrialEngine(4, preset("default"), trial_preset("default", rounds=2,
                                                           stop_confidence=0.0), seed=0)
    res2 = eng2.run(_touch_fn(kinds, 0), truth=1)
    assert res2.stop_reason == "rounds" and res2.touches == 7
    assert res2.to_dict()["stop_reason"] == "rounds"


class _ReferenceFirst(Strategy):
    """Scores the reference highest (constructed case for the engine's index mapping)."""

    name = "reference_first"
    includes_reference = True

    def score(self, probs, touches, rng, model=None):
        return np.r_[1.0, np.zeros(len(touches))]


def test_reference_retouch_is_pressed_and_used():
    kinds = [0, 0, 2, 4]
    touched = []
    fn = _touch_fn(kinds, 1)

    def touch(p):
        touched.append(p)
        return fn(p)

    eng = TrialEngine(3, preset("default"), TrialConfig(rounds=2, stop_confidence=0.0), seed=0)
    eng.strategy = _ReferenceFirst()
    res = eng.run(touch, truth=1)
    assert touched == [0, 1, 2, 3, 0, 0]
    assert [r.platform for r in res.rounds] == [0, 0]
    assert res.reference_touches == 3 and res.final.reference_touches == 3
    assert eng.learner.match.counts.tolist() == [3, 1, 1, 1]


def test_infogain_needs_the_descriptor_model():
    with pytest.raises(InputError, match="descriptor"):
        TrialEngine(2, preset("cnn", input_size=32, steps=1),
                    TrialConfig(strategy="infogain", rounds=1), seed=0)
