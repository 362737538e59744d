"""Exploration strategies: each one is a single scoring function over the comparison platforms.

``score(probs, touches, rng)`` gets the (T, C) Monte-Carlo softmax table of the reference, the
(C,) touches so far per comparison platform and the trial's random generator, and returns a (C,)
score (higher = touch next) or ``None`` for "touch nothing more".

Tie-breaking (``Strategy.choose``): among the platforms whose score is within ``TIE_TOL`` of the
best, the one touched least so far wins; if still tied, the lowest platform index. So when every
score is equal (e.g. a collapsed network that outputs the same softmax in every pass) the choice
degrades to round-robin over the least-touched platforms instead of hammering platform 0.
"""

from __future__ import annotations

import numpy as np

from . import uncertainty as unc
from .errors import TactexError

TIE_TOL = 1e-9


class Strategy:
    """Base class; subclasses override ``score`` only."""

    name = "base"

    def score(self, probs: np.ndarray, touches: np.ndarray,
              rng: np.random.Generator) -> np.ndarray | None:
        raise NotImplementedError

    def choose(self, probs: np.ndarray, touches: np.ndarray, rng: np.random.Generator,
               tie_break: bool = True) -> tuple[int | None, np.ndarray | None]:
        """(chosen comparison index 0..C-1 or None, the (C,) scores or None).

        ``tie_break=False`` is the unguarded plain argmax (first index among equal scores),
        kept for the before/after runs of ``tactex experiment stability``.
        """
        s = self.score(probs, touches, rng)
        if s is None:
            return None, None
        if not tie_break:
            return int(np.argmax(np.asarray(s, dtype=np.float64))), s
        return break_ties(s, touches), s


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

    def score(self, probs, touches, rng):
        return unc.expected_variance(probs)


class EntropyStrategy(Strategy):
    name = "entropy"

    def score(self, probs, touches, rng):
        return unc.entropy_contribution(probs)


class BaldStrategy(Strategy):
    name = "bald"

    def score(self, probs, touches, rng):
        return unc.bald_contribution(probs)


class RandomStrategy(Strategy):
    name = "random"

    def score(self, probs, touches, rng):
        return rng.random(np.shape(touches)[0])


class YotoStrategy(Strategy):
    """"You only touch once": the baseline touches, no revisits (training rounds still run)."""

    name = "yoto"

    def score(self, probs, touches, rng):
        return None


STRATEGIES: dict[str, type[Strategy]] = {
    cls.name: cls for cls in (VarianceStrategy, EntropyStrategy, RandomStrategy, YotoStrategy,
                              BaldStrategy)
}


def make_strategy(name: str) -> Strategy:
    """Strategy by name; TactexError naming the choices for an unknown one."""
    try:
        return STRATEGIES[name]()
    except KeyError:
        raise TactexError(f"unknown strategy {name!r}; choose one of "
                          f"{', '.join(STRATEGIES)}") from None
