"""What the trial engine asks of a learner (``core/build.make_learner`` builds one by name).

A learner holds one trial's touches over C comparison platforms (classes 0..C-1) and gives the
engine a (T, C) table of the reference and a (C,) belief over which comparison matches.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Protocol

import numpy as np

from .config import LearnerSettings
from .touch import Touch


@dataclass
class TrainStats:
    """What one training round did (a learner that trains nothing reports steps 0)."""

    seconds: float
    steps: int
    mean_loss: float
    skipped: int = 0              # steps skipped for a non-finite loss or gradient (guards)
    grad_norm: float = float("nan")   # median gradient norm before clipping
    restored: bool = False        # round rolled back (too many bad steps), learning rate halved
    escalation: str | None = None  # a wrapper learner ('auto') moved up a stage: why


class Learner(Protocol):
    """The engine's view of a learner (``core/engine.py``); one that trains is also a
    ``TrainingLearner``."""

    model_name: str
    cfg: LearnerSettings

    def add_touch(self, touch: Touch, label: int) -> Any:
        """Store a comparison touch of class ``label`` (0..C-1); returns its stored sample."""

    def add_reference(self, touch: Touch) -> None:
        """Store a reference touch (every one counts for the decision)."""

    def heldout_proba(self, x: Any) -> np.ndarray:
        """(C,) probabilities of the sample ``x`` just added, before it was trained on."""

    def reference_probs(self) -> np.ndarray:
        """(T, C) class probabilities of the reference (passes, members or draws)."""

    def belief(self, probs: np.ndarray) -> np.ndarray:
        """(C,) belief over which comparison matches, from ``reference_probs``' table."""


class TrainingLearner(Learner, Protocol):
    """A learner that trains a model between decisions (the lab's CNNs)."""

    def train_round(self) -> TrainStats:
        """One round of training; what it did."""


class StatefulLearner(Learner, Protocol):
    """A learner whose state can be written after a round and read back on resume, so a
    resumed trial continues without re-training (the lab's CNNs). The bytes are opaque to the
    product: the trial record stores them (``record.TrialRecord.write_checkpoint``).

    ``load_state`` is called on a fresh learner (same class, settings and seed) after the
    touches stored before the checkpoint were added again in their order; it raises
    InputError when the bytes are not a state of this learner or do not fit those touches."""

    def save_state(self) -> bytes:
        """The learner's state now (weights, optimiser, random generators, ...)."""

    def load_state(self, data: bytes) -> None:
        """Continue from ``save_state``'s bytes (InputError when they do not fit)."""


def can_checkpoint(learner: Learner) -> bool:
    """True when the learner offers ``save_state`` / ``load_state`` (``StatefulLearner``)."""
    return callable(getattr(learner, "save_state", None)) and \
        callable(getattr(learner, "load_state", None))


def train_round(learner: Learner) -> TrainStats | None:
    """One round of training of a ``TrainingLearner``; None for a learner that trains
    nothing (the descriptor)."""
    train = getattr(learner, "train_round", None)
    return None if train is None else train()

