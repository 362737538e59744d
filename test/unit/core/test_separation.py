"""The "not sure" rule of the stop: the two best comparisons' separation (core/match.py) and
the engine's stop that needs it (``TrialConfig.stop_separation``)."""

import math

import numpy as np
import pytest

from tactex_ros.core.calibration import PLACEHOLDER_FRAME
from tactex_ros.core.config import preset
from tactex_ros.core.engine import (TrialEngine, separated, stop_reason, trial_preset)
from tactex_ros.core.match import MatchModel, separation
from tactex_ros.core.touch import Touch


def test_separation_hand_computed():
    # D = 2; a = (0, 0) from 2 touches, b = (1, 2) from 1; sigma^2 = (1, 4):
    # d2 = 1/1 + 4/4 = 2, v = 1/2 + 1 = 1.5 -> t = 2 / 1.5 / 2
    means = np.array([[9.0, 9.0], [0.0, 0.0], [1.0, 2.0]])
    t = separation(means, np.array([1.0, 2.0, 1.0]), np.array([1.0, 4.0]), 1, 2)
    assert t == pytest.approx(2.0 / 1.5 / 2.0, rel=1e-12)


def test_model_separation_is_of_the_two_best_comparisons():
    # D = 1, no repeats: sigma^2 = kappa^2 = 1 (prior only). Reference 0; c1 0.1, c2 0.3 (the
    # two best), c3 5. Scene units: scale = sqrt(s^2 + (0.05 s)^2), s = std of the 4 means.
    m = MatchModel(3, prior_scale=1.0, prior_strength=4.0, temperature=1.0)
    for p, x in ((0, 0.0), (1, 0.1), (2, 0.3), (3, 5.0)):
        m.add(p, np.array([x]))
    s = np.std([0.0, 0.1, 0.3, 5.0])
    sc = math.sqrt(s ** 2 + (0.05 * s) ** 2)
    assert m.separation() == pytest.approx((0.2 / sc) ** 2 / 2.0, rel=1e-9)


def test_stop_rule_needs_separation():
    assert separated(None, 2.0) and separated(0.5, 0.0) and separated(2.5, 2.0)
    assert not separated(2.0, 2.0) and not separated(1.0, 2.0)
    assert stop_reason(0.95, 0.9, 1, 10, True, sure_allowed=False) is None
    assert stop_reason(0.95, 0.9, 10, 10, True, sure_allowed=False) == "rounds"
    assert stop_reason(0.95, 0.9, 1, 10, True, sure_allowed=True) == "confident"


def _const_touch(values: list[float]):
    """Touch function: platform p gives descriptor values[p] (+ a tiny alternating offset so
    repeated touches have a spread)."""
    n = [0] * len(values)

    def touch(p: int) -> Touch:
        n[p] += 1
        x = np.full(4, values[p]) + (0.01 if n[p] % 2 else -0.01) * np.arange(1, 5)
        return Touch(PLACEHOLDER_FRAME, None, None, x)
    return touch


def test_engine_ends_not_sure_when_two_comparisons_are_alike():
    # comparisons 1 and 2 give the same descriptors, so the belief splits about evenly between
    # them; at a stop threshold of 0.3 that split is "sure" without the rule, and not with it
    cfg = preset("default", guards=False)
    alike = [0.0, 0.0, 0.0, 3.0, 6.0]
    off = TrialEngine(4, cfg, trial_preset("default", rounds=6, stop_confidence=0.3), seed=0)
    res0 = off.run(_const_touch(alike), truth=1)
    assert res0.stop_reason == "confident" and res0.sure is True and res0.touches < 5 + 6
    on = TrialEngine(4, cfg, trial_preset("default", rounds=6, stop_confidence=0.3,
                                          stop_separation=0.5), seed=0)
    res = on.run(_const_touch(alike), truth=1)
    assert res.stop_reason == "rounds" and res.sure is False and res.touches == 5 + 6
    assert max(res.final.probs) >= 0.3            # confident enough, but not sure
    # c2 far from c1: separated, the stop is allowed at once
    far = TrialEngine(4, cfg, trial_preset("default", rounds=6, stop_confidence=0.3,
                                           stop_separation=0.5), seed=0)
    res2 = far.run(_const_touch([0.0, 0.0, 1.5, 3.0, 6.0]), truth=1)
    assert res2.stop_reason == "confident" and res2.sure is True and res2.correct
