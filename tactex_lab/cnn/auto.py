"""Model ``cnn_auto``: a wrapper learner that starts on the cheapest CNN and moves up a ladder.

The trial starts on the first stage of ``AutoSettings.auto_ladder`` (by default
``small_inception`` at 48 px, then 96 px) and moves one stage up only on evidence from the trial
itself, checked at the start of every training round (``train_round``, once per decision):

- *held-back touches*: every comparison touch added after the first round is classified by the
  current model before it is trained on (the engine asks ``heldout_proba`` right after
  ``add_touch``); if fewer than ``auto_heldout_acc`` of the last ``auto_window`` such touches were
  right, the model is not enough;
- *uncertainty that does not fall*: after ``auto_patience`` rounds on a stage, the predictive
  entropy of the reference fell by less than ``auto_min_drop`` (relative) over the last
  ``auto_patience`` rounds and is still above ``auto_entropy`` x log C.

On escalation the next stage's learner starts from the old weights where they fit (same variant:
all; small -> full Inception: the stem), every stored touch is re-added from the raw frames kept
here, and ``auto_catchup`` extra rounds are trained at once (their time counts in the round's
``TrainStats.seconds``; ``TrainStats.escalation`` says why).
"""

from __future__ import annotations

import io
import math
import time

import numpy as np
import torch

from tactex_lab.cnn.learner import OnlineLearner
from tactex_ros.core.config import CNN_MODELS, AutoSettings, CnnSettings
from tactex_ros.core.schema import validate
from tactex_ros.core.errors import InputError
from tactex_ros.core.learners import TrainStats
from tactex_ros.core.strategies import predictive_entropy
from tactex_ros.core.touch import Touch


def parse_ladder(text: str, default_size: int) -> list[tuple[str, int]]:
    """``'small_inception@32,inception_v3_random@96'`` -> [(model, input px), ...]."""
    out = []
    for part in (p.strip() for p in text.split(",")):
        if not part:
            continue
        name, _, size = part.partition("@")
        if name not in CNN_MODELS:
            raise InputError(f"auto_ladder: unknown model {name!r}; choose from "
                             f"{', '.join(CNN_MODELS)}")
        try:
            px = int(size) if size else default_size
        except ValueError:
            raise InputError(f"auto_ladder: bad input size {size!r} in {part!r}") from None
        if not 32 <= px <= 512:
            raise InputError(f"auto_ladder: input size {px} outside 32..512")
        if name != "small_inception" and px < 75:
            raise InputError(f"auto_ladder: {name} needs an input of at least 75 px, got {px}")
        out.append((name, px))
    if not out:
        raise InputError("auto_ladder is empty")
    return out


class AutoLearner:
    """The learner of the current ladder stage, plus what escalation needs (raw touches, the
    stage's held-back outcomes and reference entropies)."""

    def __init__(self, num_classes: int, cfg: AutoSettings, seed: int = 0) -> None:
        self.base_cfg = validate(cfg)
        self.num_classes = num_classes
        self.seed = seed
        self.ladder = parse_ladder(cfg.auto_ladder, cfg.input_size)
        self.stage = 0
        self.inner = self._stage_learner()
        self._ref_touches: list[Touch] = []            # raw touches, for re-adding on
        self._frames: list[tuple[int, Touch]] = []     # escalation: (class, touch)
        self._heldout: list[bool] = []                 # this stage's held-back outcomes
        self._entropies: list[float] = []              # this stage's reference entropies
        self._last_label: int | None = None
        self._rounds = 0                               # train_round calls (= decisions)

    def _stage_learner(self) -> OnlineLearner:
        name, size = self.ladder[self.stage]
        return OnlineLearner(self.num_classes, self.base_cfg.as_model(name, input_size=size),
                             seed=self.seed, model_name=name)

    # the stage learner's identity, for the round records
    @property
    def model_name(self) -> str:
        return self.inner.model_name

    @property
    def cfg(self) -> CnnSettings:
        return self.inner.cfg

    @property
    def rounds_trained(self) -> int:
        return self.inner.rounds_trained

    def add_touch(self, touch: Touch, label: int):
        x = self.inner.add_touch(touch, label)
        self._frames.append((label, touch))
        self._last_label = label
        return x

    def add_reference(self, touch: Touch) -> None:
        self.inner.add_reference(touch)
        self._ref_touches.append(touch)

    def heldout_proba(self, x) -> np.ndarray:
        """The stage learner's (C,) probabilities of the touch just added; the outcome counts
        for the held-back test."""
        p = self.inner.heldout_proba(x)
        self._heldout.append(bool(int(np.argmax(p)) == self._last_label))
        return p

    def train_round(self) -> TrainStats:
        """Escalate first when the evidence says so, then train the stage learner one round."""
        escalation = self._escalation_reason()
        extra_s = self._escalate() if escalation else 0.0
        self._rounds += 1
        stats = self.inner.train_round()
        stats.seconds += extra_s
        stats.escalation = escalation
        return stats

    def reference_probs(self) -> np.ndarray:
        probs = self.inner.reference_probs()
        self._entropies.append(predictive_entropy(probs))
        return probs

    def belief(self, probs: np.ndarray) -> np.ndarray:
        return self.inner.belief(probs)

    def save_state(self) -> bytes:
        """The state after a round (``StatefulLearner``): the stage, the stage learner's own
        state and the evidence gathered on this stage. The raw touches are not written: the
        same touches are added again before ``load_state``."""
        buf = io.BytesIO()
        torch.save({"stage": self.stage, "ladder": self.ladder, "inner": self.inner.save_state(),
                    "heldout": list(self._heldout), "entropies": list(self._entropies),
                    "last_label": self._last_label, "rounds": self._rounds,
                    "touches": len(self._frames), "references": len(self._ref_touches)}, buf)
        return buf.getvalue()

    def load_state(self, data: bytes) -> None:
        """Continue from ``save_state``'s bytes: the stage learner of the saved stage is built
        again from the touches added since this learner was made, then its state loaded
        (InputError, named, when the bytes do not fit)."""
        try:
            st = torch.load(io.BytesIO(data), map_location="cpu", weights_only=True)
            stage, inner = int(st["stage"]), st["inner"]
            ladder = [tuple(x) for x in st["ladder"]]
        except Exception as exc:  # noqa: BLE001 - torch raises many kinds for bad bytes
            raise InputError(f"learner state unreadable ({type(exc).__name__}: {exc})") \
                from None
        if ladder != [tuple(x) for x in self.ladder] or not 0 <= stage < len(self.ladder) or \
                st.get("touches") != len(self._frames) or \
                st.get("references") != len(self._ref_touches):
            raise InputError("learner state of another ladder or other touches")
        if stage != self.stage:
            self.stage = stage
            self.inner = self._stage_learner()
            for label, touch in self._frames:
                self.inner.add_touch(touch, label)
            for touch in self._ref_touches:
                self.inner.add_reference(touch)
        self.inner.load_state(inner)
        self._heldout = [bool(x) for x in st["heldout"]]
        self._entropies = [float(x) for x in st["entropies"]]
        self._last_label = st["last_label"]
        self._rounds = int(st["rounds"])

    def _escalation_reason(self) -> str | None:
        """Evidence from this trial that the current stage is not enough (None = stay)."""
        if self.stage + 1 >= len(self.ladder):
            return None
        c = self.base_cfg
        w = c.auto_window
        if len(self._heldout) >= w:
            acc = float(np.mean(self._heldout[-w:]))
            if acc < c.auto_heldout_acc:
                return (f"held-back touches: {acc:.2f} of the last {w} classified right "
                        f"< {c.auto_heldout_acc:g}")
        hist = self._entropies
        k = c.auto_patience
        if len(hist) > k:
            h_now, h_then = hist[-1], hist[-1 - k]
            floor = c.auto_entropy * math.log(self.num_classes)
            if h_now > floor and h_now > (1.0 - c.auto_min_drop) * h_then:
                return (f"entropy not falling: {h_then:.3f} -> {h_now:.3f} nats over {k} rounds, "
                        f"above {floor:.3f}")
        return None

    def _escalate(self) -> float:
        """Move to the next stage; returns the seconds spent (re-adding, catch-up training)."""
        t0 = time.perf_counter()
        old = self.inner
        self.stage += 1
        self.inner = self._stage_learner()
        self.inner.transfer_from(old)
        for label, touch in self._frames:
            self.inner.add_touch(touch, label)
        for touch in self._ref_touches:
            self.inner.add_reference(touch)
        for _ in range(min(self.base_cfg.auto_catchup, self._rounds)):
            self.inner.train_round()
        self._heldout = []
        self._entropies = []
        return time.perf_counter() - t0
