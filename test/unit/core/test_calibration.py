"""The belief's temperature calibrated with classes left out (core/calibration.py) and the
trial's honest end (sure / not sure), on constructed data with known answers."""

import numpy as np
import pytest

from tactex_ros.core import calibration as cal
from tactex_ros.core import representation as rp
from tactex_ros.core.config import TrialConfig, preset
from tactex_ros.core.engine import TrialSpec, run_trial
from tactex_ros.core.errors import InputError
from tactex_ros.core.match import softmax
from tactex_ros.core.touch import Touch


def _known_temperature(beta: float, n: int = 4000, c: int = 4, seed: int = 0):
    """Decisions whose true match is drawn from softmax(beta * l): the NLL is minimal at beta."""
    rng = np.random.default_rng(seed)
    out = []
    for _ in range(n):
        ev = rng.normal(0.0, 8.0, (1, c))
        truth = int(rng.choice(c, p=softmax(beta * ev[0])))
        out.append(cal.Trajectory(ev, truth, np.zeros(1)))
    return out


def test_nll_recovers_a_known_temperature():
    trajs = _known_temperature(0.3)
    beta = cal.fit_temperature(trajs, "nll")
    assert beta == pytest.approx(0.3, rel=0.08)
    assert cal.nll(trajs, beta) < cal.nll(trajs, 0.1) and cal.nll(trajs, beta) < cal.nll(trajs, 1.0)
    # calibrated: the ECE at the fitted temperature is small, far smaller when 10x too sharp
    assert cal.ece(trajs, beta) < 0.03 < cal.ece(trajs, 10 * beta)


def test_stop_rule_temperature_keeps_wrong_stops_within_one_minus_theta():
    trajs = _known_temperature(0.3, n=600, seed=1)
    thetas = (0.8, 0.9, 0.95)
    beta = cal.fit_temperature(trajs, "stop", thetas)
    assert all(cal.wrong_stop_rate(trajs, beta, th) <= 1 - th for th in thetas)
    nxt = cal.GRID[np.searchsorted(cal.GRID, beta) + 1]
    assert any(cal.wrong_stop_rate(trajs, nxt, th) > 1 - th for th in thetas)
    with pytest.raises(InputError, match="one of nll, stop"):
        cal.fit_temperature(trajs, "other")
    # target: at most 3 % wrong stops at 0.9 is stricter than 1 - 0.9, so a cooler belief
    cool = cal.fit_temperature(trajs, "target", (0.9,), 0.03)
    assert cool < beta and cal.wrong_stop_rate(trajs, cool, 0.9) <= 0.03
    with pytest.raises(InputError, match="wrong-stop rate"):
        cal.fit_temperature(trajs, "target", (0.9,), None)


def test_per_family_temperature_is_set_by_the_worst_family():
    # two families whose evidence is sharp to a different degree: pooled, the sharper family's
    # decisions dilute the other's wrong stops; per family, the cooler one decides
    sharp = _known_temperature(0.6, n=600, seed=2)
    cool = _known_temperature(0.15, n=600, seed=3)
    thetas = (0.8, 0.9, 0.95)
    per = [cal.fit_temperature(f, "stop", thetas) for f in (sharp, cool)]
    worst = cal.fit_temperature_families([sharp, cool], "stop", thetas)
    assert worst == min(per) == per[1] < per[0]
    assert all(cal.wrong_stop_rate(f, worst, th) <= 1 - th for f in (sharp, cool) for th in thetas)
    assert cal.fit_temperature(sharp + cool, "stop", thetas) > worst
    with pytest.raises(InputError, match="per-family"):
        cal.fit_temperature_families([sharp], "nll")


def test_wrong_stop_rate_counts_the_first_confident_decision():
    ev = np.array([[0.0, 0.0], [5.0, 0.0], [0.0, 9.0]])    # belief crosses 0.9 at step 1
    t = cal.Trajectory(ev, truth=1, extra=np.arange(3))
    assert cal.wrong_stop_rate([t], 1.0, 0.9) == 1.0        # stopped on class 0: wrong
    assert cal.wrong_stop_rate([t], 1.0, 0.9999) == 0.0     # first crossing at step 2: right


def _library(rng, classes=12, presses=5, d=106):
    return {f"k{c}": rng.normal(0, 1.0, d) + rng.normal(0, 0.5, (presses, d))
            for c in range(classes)}


def test_left_out_trajectories_run_the_engine_on_known_descriptors():
    lib = _library(np.random.default_rng(2))
    trajs = cal.trajectories(lib, lambda d: rp.fit(d, kind="lda", dims=6), preset("default"),
                             folds=3, scenes=4, comparisons=3, budget=4, seed=0)
    assert len(trajs) == 12
    for t in trajs:
        assert t.evidence.shape == (5, 3) and 0 <= t.truth < 3
        assert list(t.extra) == [0, 1, 2, 3, 4]
    # well separated classes: the left-out trials end right
    assert np.mean([np.argmax(t.evidence[-1]) == t.truth for t in trajs]) >= 0.9
    with pytest.raises(InputError, match="cannot fill"):
        cal.trajectories(lib, rp.fit, preset("default"), folds=3, comparisons=5)


def _engine_trial(stop: float, spread: float, rounds: int = 3):
    """A 3-comparison trial on known descriptors: the reference is class 2; ``spread`` is the
    within-class noise (large = the classes overlap, the belief stays unsure)."""
    rng = np.random.default_rng(0)
    centres = rng.normal(0, 1.0, (3, 106))
    frame = cal.PLACEHOLDER_FRAME
    spec = TrialSpec(3, preset("default", guards=False),
                     TrialConfig(strategy="infogain", rounds=rounds, stop_confidence=stop))
    truth = 2

    def touch(p: int) -> Touch:
        c = truth - 1 if p == 0 else p - 1
        return Touch(frame, None, None, centres[c] + rng.normal(0, spread, 106))

    return run_trial(spec, touch, truth=truth)


def test_trial_says_not_sure_when_the_budget_ends_below_the_threshold():
    unsure = _engine_trial(stop=0.999999, spread=30.0)
    d = unsure.to_dict()
    assert unsure.sure is False and d["sure"] is False and d["stop_reason"] == "rounds"
    assert d["confidence"] == pytest.approx(max(unsure.final.probs)) and d["confidence"] < 0.999999
    sure = _engine_trial(stop=0.9, spread=0.05)
    assert sure.sure is True and sure.stop_reason == "confident" and sure.correct
    assert _engine_trial(stop=0.0, spread=0.05).sure is None      # no stop rule
