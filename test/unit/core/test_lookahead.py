"""Strategy ``lookahead``: the chance of reaching the stop within one / two touches
(``MatchModel.stop_chance``) and the touch it chooses, on tiny scenes whose answer is known."""

import numpy as np
import pytest

from tactex_ros.core.config import STRATEGY_NAMES, TrialConfig
from tactex_ros.core.errors import InputError
from tactex_ros.core.match import MatchModel
from tactex_ros.core.strategies import (GAIN_WEIGHT, LookaheadStrategy, make_strategy)


def _midpoint_scene() -> MatchModel:
    """Two comparisons at -1 and +1 touched 50 times each (exactly), the reference touched
    once, at 0: the belief is 0.5 / 0.5; sigma^2 = 4 x 0.5^2 / (4 + 98) (prior only)."""
    m = MatchModel(2, prior_scale=0.5, prior_strength=4.0, temperature=1.0, scene_units=False)
    m.add(0, np.array([0.0]))
    for _ in range(50):
        m.add(1, np.array([-1.0]))
        m.add(2, np.array([1.0]))
    return m


def test_only_the_reference_can_end_a_midpoint_scene_in_one_touch():
    m = _midpoint_scene()
    assert m.belief() == pytest.approx([0.5, 0.5])
    c = m.stop_chance(np.random.default_rng(0), 0.9)
    assert c.shape == (2, 3)
    # one more reference touch lands near one side (its mean moves to about +-0.49, sd 0.07):
    # sure; a comparison touch moves a mean of 50 by 1/51 of a noise: the reference stays
    # between them
    assert c[0].tolist() == [1.0, 0.0, 0.0]
    # within two: the reference, or a comparison and then the reference
    assert c[1].tolist() == [1.0, 1.0, 1.0]


def test_the_stop_chance_is_one_at_a_stop_every_belief_reaches_and_zero_above_one():
    m = _midpoint_scene()
    assert m.stop_chance(np.random.default_rng(0), 0.5).tolist() == [[1.0] * 3, [1.0] * 3]
    assert m.stop_chance(np.random.default_rng(0), 1.01).tolist() == [[0.0] * 3, [0.0] * 3]


def test_lookahead_touches_the_reference_of_a_midpoint_scene():
    class Learner:                        # what the strategy reads of the descriptor learner
        match = _midpoint_scene()

        def stop_chance(self, rng, theta):
            return self.match.stop_chance(rng, theta)

        def info_gain(self, rng):
            return self.match.info_gain(rng)

    s = make_strategy("lookahead", 0.9)
    assert isinstance(s, LookaheadStrategy) and s.stop_confidence == 0.9
    choice, scores = s.choose(np.full((4, 2), 0.5), np.array([50, 50]),
                              np.random.default_rng(0), model=Learner())
    assert choice == 0
    # scores: P(1) + P(2) + GAIN_WEIGHT x the information gain (0..ln 2 nats here)
    top = GAIN_WEIGHT * np.log(2) + 1e-9
    assert 0.0 <= scores[0] - 2.0 <= top
    assert 0.0 <= scores[1] - 1.0 <= top and 0.0 <= scores[2] - 1.0 <= top


def test_far_from_the_stop_the_information_gain_decides():
    class Learner:
        match = _midpoint_scene()

        def stop_chance(self, rng, theta):
            return self.match.stop_chance(rng, theta)

        def info_gain(self, rng):
            return np.array([0.1, 0.3, 0.2])

    s = make_strategy("lookahead", 1.0)       # a stop no belief reaches: chances all 0
    s.stop_confidence = 1.01
    choice, scores = s.choose(np.full((4, 2), 0.5), np.array([1, 1]),
                              np.random.default_rng(0), model=Learner())
    assert choice == 1                        # comparison 1, the largest gain
    assert scores.tolist() == pytest.approx([1e-4, 3e-4, 2e-4])


def test_lookahead_is_registered_and_needs_the_descriptor_model():
    assert "lookahead" in STRATEGY_NAMES
    assert make_strategy("lookahead").stop_confidence == 0.9      # 0: the class's stop
    assert TrialConfig(strategy="lookahead").strategy == "lookahead"
    with pytest.raises(InputError, match="descriptor"):
        make_strategy("lookahead").score(np.full((2, 2), 0.5), np.array([1, 1]),
                                         np.random.default_rng(0), model=object())
    with pytest.raises(InputError, match="draws"):
        _midpoint_scene().stop_chance(np.random.default_rng(0), 0.9, draws=0)
