"""Exploration strategies: each one is a single scoring function over the comparison platforms.

``score(probs, touches, rng, model)`` gets the (T, C) table of the reference's class
probabilities (Monte-Carlo dropout passes of the CNN, or posterior draws of the descriptor
model's belief), the (C,) touches so far per comparison platform, the trial's random generator
and the learner, and returns a (C,) score over the comparisons (higher = touch next) or
``None`` for "touch nothing more". A strategy with ``includes_reference = True`` scores
(C + 1,) platforms instead, index 0 being the reference (it may touch the reference again).

Tie-breaking (``Strategy.choose``): among the platforms whose score is within ``TIE_TOL`` of the
best, the one touched least so far wins; if still tied, the lowest platform index. So when every
score is equal (e.g. a collapsed network that outputs the same softmax in every pass) the choice
degrades to round-robin over the least-touched platforms instead of hammering platform 0.
"""

from __future__ import annotations

import numpy as np

from .errors import InputError

TIE_TOL = 1e-9
_EPS = 1e-12


# ----------------------------------------------------------------------------- scores
# Read only the (T, C) table, so they apply to MC-dropout passes, ensemble members or
# posterior draws alike; (C,) float64, higher = more uncertain.
def expected_variance(probs: np.ndarray) -> np.ndarray:
    """(T, C) -> (C,) variance over passes of each class probability."""
    return np.asarray(probs, dtype=np.float64).var(axis=0)


def entropy_contribution(probs: np.ndarray) -> np.ndarray:
    """(T, C) -> (C,) -pbar_i log pbar_i, pbar = mean over passes (nats)."""
    pbar = np.asarray(probs, dtype=np.float64).mean(axis=0)
    return -pbar * np.log(pbar + _EPS)


def bald_contribution(probs: np.ndarray) -> np.ndarray:
    """(T, C) -> (C,) per-class terms of the mutual information (nats); they sum to BALD."""
    p = np.asarray(probs, dtype=np.float64)
    pbar = p.mean(axis=0)
    term = -pbar * np.log(pbar + _EPS) + (p * np.log(p + _EPS)).mean(axis=0)
    return np.maximum(term, 0.0)


def predictive_entropy(probs: np.ndarray) -> float:
    """(T, C) -> entropy of the mean softmax (nats)."""
    return float(entropy_contribution(probs).sum())


class Strategy:
    """Base class; subclasses override ``score`` only. ``stop_confidence``: the belief the
    trial stops at (``make_strategy`` sets the trial's), for a strategy that plans to the
    stop."""

    name = "base"
    includes_reference = False
    stop_confidence = 0.9

    def score(self, probs: np.ndarray, touches: np.ndarray, rng: np.random.Generator,
              model: object = None) -> np.ndarray | None:
        raise NotImplementedError

    def choose(self, probs: np.ndarray, touches: np.ndarray, rng: np.random.Generator,
               tie_break: bool = True, model: object = None,
               reference_touches: int = 1) -> tuple[int | None, np.ndarray | None]:
        """(chosen index into the scores or None, the scores or None).

        Scores are (C,) over the comparisons, or (C + 1,) with the reference at index 0 when
        ``includes_reference``. ``tie_break=False`` is the unguarded plain argmax (first index
        among equal scores), kept for the before/after runs of ``tactex experiment stability``.
        """
        s = self.score(probs, touches, rng, model)
        if s is None:
            return None, None
        if not tie_break:
            return int(np.argmax(np.asarray(s, dtype=np.float64))), s
        counts = (np.r_[reference_touches, np.asarray(touches)] if self.includes_reference
                  else touches)
        return break_ties(s, counts), s


def break_ties(scores: np.ndarray, touches: np.ndarray) -> int:
    """argmax of ``scores``; ties -> fewest ``touches``; then lowest index."""
    s = np.asarray(scores, dtype=np.float64)
    if s.ndim != 1 or s.shape != np.shape(touches):
        raise ValueError(f"scores {s.shape} and touches {np.shape(touches)} must be equal 1-D")
    if not np.all(np.isfinite(s)):
        s = np.nan_to_num(s, nan=-np.inf)
    best = s.max()
    cand = np.flatnonzero(s >= best - TIE_TOL * max(1.0, abs(best)))
    t = np.asarray(touches)[cand]
    return int(cand[np.flatnonzero(t == t.min())[0]])


class VarianceStrategy(Strategy):
    name = "variance"

    def score(self, probs, touches, rng, model=None):
        return expected_variance(probs)


class EntropyStrategy(Strategy):
    name = "entropy"

    def score(self, probs, touches, rng, model=None):
        return entropy_contribution(probs)


class BaldStrategy(Strategy):
    name = "bald"

    def score(self, probs, touches, rng, model=None):
        return bald_contribution(probs)


class RandomStrategy(Strategy):
    name = "random"

    def score(self, probs, touches, rng, model=None):
        return rng.random(np.shape(touches)[0])


class YotoStrategy(Strategy):
    """"You only touch once": the baseline touches, no revisits (training rounds still run)."""

    name = "yoto"

    def score(self, probs, touches, rng, model=None):
        return None


class InfoGainStrategy(Strategy):
    """Expected information about *which comparison matches*, per platform incl. the reference.

    Needs a learner with ``info_gain(rng) -> (C + 1,)`` (the descriptor model,
    ``core/match.py``). It cannot get stuck: a platform whose next touch cannot change the
    belief scores ~0, so touches go where the answer is still open (typically the two leading
    candidates and the reference).
    """

    name = "infogain"
    includes_reference = True

    def score(self, probs, touches, rng, model=None):
        gain = getattr(model, "info_gain", None)
        if gain is None:
            raise InputError("strategy 'infogain' needs the descriptor model (model "
                             "'descriptor'); with a CNN model choose another strategy, e.g. "
                             "--strategy variance")
        return gain(rng)


#: ``lookahead``: weight of the information gain [per nat] beside the stop chances, so that it
#: only breaks their ties (at most ln C nats: below the chances' step 1 / (16 x 8) for C <= 4000)
GAIN_WEIGHT = 1e-3


class LookaheadStrategy(Strategy):
    """Touches for the fewest touches to a sure answer: per platform (incl. the reference),
    the chance that the belief reaches the stop within one touch plus the chance within two
    (``stop_chance``: the second touch the best one from the simulated state), i.e. minus the
    expected number of touches to the stop counted up to a horizon of three; plus
    ``GAIN_WEIGHT`` x the information gain, which decides where no touch can reach the stop
    within two (far from it) and between equal chances.

    Needs a learner with ``stop_chance(rng, theta) -> (2, C + 1)`` and ``info_gain`` (the
    descriptor model, ``core/match.py``); plans to the belief ``stop_confidence`` (the trial's;
    with the e-value stop rule, the threshold rule's), on the scene belief (a fabric
    library's evidence is not simulated).
    """

    name = "lookahead"
    includes_reference = True

    def score(self, probs, touches, rng, model=None):
        chance = getattr(model, "stop_chance", None)
        if chance is None or getattr(model, "info_gain", None) is None:
            raise InputError("strategy 'lookahead' needs the descriptor model (model "
                             "'descriptor'); with a CNN model choose another strategy, e.g. "
                             "--strategy variance")
        c = np.asarray(chance(rng, self.stop_confidence), dtype=np.float64)
        return c[0] + c[1] + GAIN_WEIGHT * np.asarray(model.info_gain(rng), dtype=np.float64)


STRATEGIES: dict[str, type[Strategy]] = {
    cls.name: cls for cls in (VarianceStrategy, EntropyStrategy, RandomStrategy, YotoStrategy,
                              BaldStrategy, InfoGainStrategy, LookaheadStrategy)
}


def make_strategy(name: str, stop_confidence: float = 0.0) -> Strategy:
    """Strategy by name, planning to the stop at belief ``stop_confidence`` (0: the class's
    0.9); InputError naming the choices for an unknown one."""
    try:
        s = STRATEGIES[name]()
    except KeyError:
        raise InputError(f"unknown strategy {name!r}; choose one of "
                         f"{', '.join(STRATEGIES)}") from None
    if stop_confidence > 0:
        s.stop_confidence = float(stop_confidence)
    return s
