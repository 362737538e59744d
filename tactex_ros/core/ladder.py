"""Model ``auto``: a ladder of learners that models no more than the scene needs.

The trial starts on the cheapest rung of ``LadderSettings.ladder`` (by default the texture
descriptor, the shipped method) and climbs one rung only where the trial's own evidence says the
scene is hard. Rungs, cheapest first, separated by commas (or ``+``):

- ``descriptor``: the descriptor learner as configured, without a representation;
- ``representation``: the descriptor learner with ``LadderSettings.representation`` (a
  ``tactex prepare`` file). Without that file the rung is skipped (``Ladder.notes`` says so);
- any other name: a preset of ``core/config.py`` whose model is a learner plug-in (``cnn``:
  the lab's small Inception at 48 px), optionally ``@px`` for its input side; built through
  ``core/build.make_learner`` (the product imports no plug-in: a rung whose plug-in is not
  installed is skipped, the note says why).

The evidence (``escalation_reason``, a pure function of the current rung's history) is checked
at every decision (``train_round``, called once per decision) once the rung has seen
``ladder_patience`` decisions:

- *held-back touches*: fewer than ``ladder_heldout_acc`` of the last ``ladder_window``
  comparison touches were classified right by the rung before it stored them;
- *the belief does not sharpen*: the belief in the leading comparison rose by less than
  ``ladder_min_gain`` over the last ``ladder_patience`` decisions and is still below
  ``ladder_sure``;
- *the best two stay close*: the two largest beliefs differ by less than ``ladder_margin``.

On escalation the next rung gets every touch of the trial (the raw touches are kept; a
descriptor rung reuses the descriptor of the rung below, nothing is described twice) and a
training rung gets ``ladder_catchup`` rounds at once (their time counts in the round's
``TrainStats.seconds``; ``TrainStats.escalation`` says why, the round record keeps it). The
strategy ``infogain`` is served by the highest descriptor rung in use, so the touches keep being
chosen by expected information while a CNN decides the belief.
"""

from __future__ import annotations

import json
import logging
import re
import struct
import time
from dataclasses import asdict, dataclass, replace
from typing import Callable

import numpy as np

from .descriptor import raw_descriptor
from .config import PRESETS, LadderSettings, LearnerSettings, learner_settings, preset
from .schema import validate
from .errors import InputError
from .learners import Learner, TrainStats, can_checkpoint, train_round
from .plugins import LEARNERS, available
from .touch import Touch

log = logging.getLogger(__name__)

DESCRIPTOR_RUNGS = ("descriptor", "representation")


@dataclass(frozen=True)
class Rule:
    """The escalation rule's thresholds (``LadderSettings.ladder_*``)."""

    patience: int = 2          # decisions on a rung before any test
    min_gain: float = 0.1      # rise of the leading belief over ``patience`` decisions
    sure: float = 0.9          # a leading belief at or above this counts as sharp
    margin: float = 0.1        # the best two beliefs closer than this: hard
    window: int = 3            # held-back touches judged together
    heldout_acc: float = 0.5   # share of them right below which the rung is not enough

    @staticmethod
    def of(cfg: LadderSettings) -> "Rule":
        return Rule(cfg.ladder_patience, cfg.ladder_min_gain, cfg.ladder_sure,
                    cfg.ladder_margin, cfg.ladder_window, cfg.ladder_heldout_acc)


@dataclass(frozen=True)
class Evidence:
    """Why a rung is not enough: which ``test`` (``heldout``, ``not_sharpening``, ``close``),
    the ``value`` measured (share right, rise of the leading belief, gap of the best two) and the
    ``threshold`` it fell below, after ``decisions`` decisions on the rung."""

    test: str
    value: float
    threshold: float
    decisions: int

    def __str__(self) -> str:
        what = {"heldout": "share of held-back touches classified right",
                "not_sharpening": "rise of the leading belief",
                "close": "gap between the best two beliefs"}[self.test]
        return (f"{self.test}: {what} {self.value:.3f} < {self.threshold:g} after "
                f"{self.decisions} decisions")


def escalation_reason(beliefs: list[np.ndarray], heldout: list[bool],
                      rule: Rule) -> Evidence | None:
    """Why the current rung is not enough, from its own history, or None to stay.

    ``beliefs``: the (C,) belief of every decision made on this rung, oldest first;
    ``heldout``: whether each comparison touch stored on this rung after its first decision was
    classified right before it was stored. Nothing is tested before ``rule.patience``
    decisions on the rung; the tests in order: held-back touches (once ``rule.window`` of
    them), then, while the leading belief is below ``rule.sure``, its rise over the last
    ``rule.patience`` decisions (once there are more than that) and the gap to the second."""
    k, n = rule.patience, len(beliefs)
    if n < k:
        return None
    if len(heldout) >= rule.window:
        acc = float(np.mean(heldout[-rule.window:]))
        if acc < rule.heldout_acc:
            return Evidence("heldout", acc, rule.heldout_acc, n)
    now = np.sort(np.asarray(beliefs[-1], dtype=np.float64))[::-1]
    if now[0] >= rule.sure:
        return None
    if n > k:
        gain = float(now[0] - np.max(beliefs[-1 - k]))
        if gain < rule.min_gain:
            return Evidence("not_sharpening", gain, rule.min_gain, n)
    if len(now) > 1 and now[0] - now[1] < rule.margin:
        return Evidence("close", float(now[0] - now[1]), rule.margin, n)
    return None


def parse_rungs(text: str) -> list[str]:
    """``'descriptor,representation,cnn@64'`` (or ``+`` between rungs, for option values that
    are themselves comma-separated) -> the rung names, checked (InputError)."""
    rungs = [p.strip() for p in re.split(r"[,+]", text) if p.strip()]
    if not rungs:
        raise InputError("ladder is empty")
    for r in rungs:
        name, _, px = r.partition("@")
        if name in DESCRIPTOR_RUNGS:
            if px:
                raise InputError(f"ladder rung {r!r}: a descriptor rung takes no input size")
            continue
        if name not in PRESETS or PRESETS[name].get("model", "descriptor") in ("descriptor",
                                                                                "auto"):
            cands = [p for p in PRESETS if PRESETS[p].get("model", "descriptor")
                     not in ("descriptor", "auto")]
            raise InputError(f"ladder rung {r!r}: one of {', '.join(DESCRIPTOR_RUNGS)} or a "
                             f"preset with a trained model ({', '.join(cands)})[@px]")
        if px and not (px.isdigit() and 32 <= int(px) <= 512):
            raise InputError(f"ladder rung {r!r}: input size must be 32..512 px")
    return rungs


class Ladder:
    """The learner of the current rung plus what escalation needs (raw touches, the rung's
    beliefs and held-back outcomes). A ``core.learners.Learner`` with ``train_round``."""

    def __init__(self, num_classes: int, cfg: LadderSettings, seed: int = 0, *,
                 make: Callable[[int, LearnerSettings, int], Learner]) -> None:
        """``make``: builds a rung's learner from its settings (``core/build.make_learner``)."""
        self.make = make
        self.base_cfg = validate(cfg)
        self.num_classes = num_classes
        self.seed = seed
        self.rule = Rule.of(self.base_cfg)
        self.notes: list[str] = []                      # rungs skipped, and why
        self.rungs: list[str] = []
        for r in parse_rungs(self.base_cfg.ladder):
            why = self._missing(r)
            if why:
                self.notes.append(f"ladder rung {r!r} skipped: {why}")
                log.warning(self.notes[-1])
            else:
                self.rungs.append(r)
        if not self.rungs:
            raise InputError(f"ladder {self.base_cfg.ladder!r}: no usable rung "
                             f"({'; '.join(self.notes)})")
        self.stage = 0
        self.active: list[Learner] = [self._build(0)]   # every rung climbed so far
        self._touches: list[tuple[int, Touch]] = []
        self._references: list[Touch] = []
        self._beliefs: list[np.ndarray] = []            # this rung's decisions
        self._heldout: list[bool] = []                  # this rung's held-back outcomes
        self._last_label: int | None = None
        self._decisions = 0
        self.evidence: Evidence | None = None           # of the last climb

    # ------------------------------------------------------------------ rungs
    def _missing(self, rung: str) -> str | None:
        """Why ``rung`` cannot run here (None: it can)."""
        name = rung.partition("@")[0]
        if name == "representation" and not self.base_cfg.representation:
            return "no representation file (LadderSettings.representation, --representation)"
        if name not in DESCRIPTOR_RUNGS:
            model = PRESETS[name]["model"]
            if model not in available(LEARNERS):
                return f"the learner plug-in {model!r} is not installed"
        return None

    def rung_config(self, rung: str):
        """The learner settings one rung runs with: a descriptor rung the ladder's descriptor
        settings (``DescriptorSettings``), a CNN rung its preset's (``CnnSettings``) with the
        ladder's guards, threads and device."""
        name, _, px = rung.partition("@")
        if name in DESCRIPTOR_RUNGS:
            mine = self.base_cfg.as_model("descriptor").model_dump()
            if name == "descriptor":
                mine["representation"] = ""
            return learner_settings(mine, f"ladder rung {name!r}")
        over = {"guards": self.base_cfg.guards, "threads": self.base_cfg.threads,
                "device": self.base_cfg.device}
        if px:
            over["input_size"] = int(px)
        return preset(name, **over)

    def _build(self, stage: int) -> Learner:
        return self.make(self.num_classes, self.rung_config(self.rungs[stage]), self.seed)

    @property
    def inner(self) -> Learner:
        """The learner of the current rung."""
        return self.active[-1]

    @property
    def cfg(self):
        """The current rung's configuration (its input size goes into the round record)."""
        return self.inner.cfg

    @property
    def model_name(self) -> str:
        r = self.rungs[self.stage]
        return r if r in DESCRIPTOR_RUNGS else self.inner.model_name

    @property
    def rung(self) -> str:
        return self.rungs[self.stage]

    # ------------------------------------------------------------------ Learner
    def add_touch(self, touch: Touch, label: int):
        """Store a comparison touch in every rung climbed so far; returns the current rung's
        sample (for ``heldout_proba``)."""
        touch = self._described(touch)
        self._touches.append((label, touch))
        self._last_label = label
        x = None
        for learner in self.active:
            x = learner.add_touch(touch, label)
        return x

    def add_reference(self, touch: Touch) -> None:
        touch = self._described(touch)
        self._references.append(touch)
        for learner in self.active:
            learner.add_reference(touch)

    def heldout_proba(self, x) -> np.ndarray:
        """The current rung's (C,) probabilities of the touch just added (counted for the
        held-back test)."""
        p = self.inner.heldout_proba(x)
        self._heldout.append(bool(int(np.argmax(p)) == self._last_label))
        return p

    def train_round(self) -> TrainStats | None:
        """Escalate first when the evidence says so, then train the current rung one round;
        None when the round did neither (a descriptor rung that stays: its round has no
        detail, as the descriptor's)."""
        reason = self.escalation()
        extra = self._escalate() if reason else 0.0
        self._decisions += 1
        stats = train_round(self.inner)
        if stats is None and reason is None:
            return None                 # a descriptor rung that stayed: nothing trained
        stats = stats or TrainStats(0.0, 0, float("nan"))
        stats.seconds += extra
        if reason is not None:
            self.evidence = reason
        stats.escalation = (None if reason is None else
                            f"{self.rungs[self.stage - 1]} -> {self.rung}: {reason}")
        return stats

    # ------------------------------------------------------------------ checkpoint
    def save_state(self) -> bytes:
        """The state after a round (``StatefulLearner``): the rung, this rung's evidence so far
        and the current rung's learner state when it has one (a CNN rung's; a descriptor rung
        is rebuilt from the touches). Layout: 4-byte big-endian length, that many bytes of
        JSON, then the rung learner's own bytes. The raw touches are not written: the same
        touches are added again before ``load_state``."""
        inner = self.inner.save_state() if can_checkpoint(self.inner) else None
        head = {"rungs": self.rungs, "stage": self.stage, "decisions": self._decisions,
                "beliefs": [b.tolist() for b in self._beliefs], "heldout": self._heldout,
                "last_label": self._last_label, "touches": len(self._touches),
                "references": len(self._references), "inner": inner is not None,
                "evidence": None if self.evidence is None else asdict(self.evidence)}
        blob = json.dumps(head).encode()
        return struct.pack(">I", len(blob)) + blob + (inner or b"")

    def load_state(self, data: bytes) -> None:
        """Continue from ``save_state``'s bytes: the rungs up to the saved one are built again
        from the touches added since this ladder was made, then the rung learner's state is
        loaded (InputError, named, when the bytes do not fit)."""
        try:
            (n,) = struct.unpack(">I", data[:4])
            st = json.loads(data[4:4 + n].decode())
            inner, stage = data[4 + n:], int(st["stage"])
            beliefs = [np.asarray(b, dtype=np.float64) for b in st["beliefs"]]
            heldout = [bool(x) for x in st["heldout"]]
            ev = None if st["evidence"] is None else Evidence(**st["evidence"])
        except (struct.error, UnicodeDecodeError, ValueError, KeyError, TypeError) as exc:
            raise InputError(f"ladder state unreadable ({type(exc).__name__}: {exc})") from None
        if st["rungs"] != self.rungs or not 0 <= stage < len(self.rungs) or \
                st["touches"] != len(self._touches) or \
                st["references"] != len(self._references) or self.stage != 0:
            raise InputError("ladder state of another ladder or other touches")
        while self.stage < stage:
            self.stage += 1
            learner = self._build(self.stage)
            for label, touch in self._touches:
                learner.add_touch(touch, label)
            for touch in self._references:
                learner.add_reference(touch)
            self.active.append(learner)
        if st["inner"]:
            if not can_checkpoint(self.inner):
                raise InputError(f"ladder state: rung {self.rung!r} cannot load a state")
            self.inner.load_state(inner)
        elif self.rung not in DESCRIPTOR_RUNGS:
            raise InputError(f"ladder state: rung {self.rung!r} saved no state")
        self._decisions = int(st["decisions"])
        self._beliefs, self._heldout, self.evidence = beliefs, heldout, ev
        self._last_label = st["last_label"]

    def escalation(self) -> Evidence | None:
        """Why to climb now (None: stay, or no rung above)."""
        if self.stage + 1 >= len(self.rungs):
            return None
        return escalation_reason(self._beliefs, self._heldout, self.rule)

    def reference_probs(self) -> np.ndarray:
        return self.inner.reference_probs()

    def belief(self, probs: np.ndarray) -> np.ndarray:
        b = self.inner.belief(probs)
        self._beliefs.append(np.asarray(b, dtype=np.float64))
        return b

    def info_gain(self, rng: np.random.Generator) -> np.ndarray:
        """(C + 1,) expected entropy drop per platform, from the highest descriptor rung in use
        (strategy ``infogain``)."""
        for rung, learner in zip(reversed(self.rungs[:len(self.active)]), reversed(self.active)):
            if rung in DESCRIPTOR_RUNGS:
                return learner.info_gain(rng)
        raise InputError("strategy 'infogain' needs a descriptor rung in the ladder")

    def _escalate(self) -> float:
        """Climb one rung; returns the seconds spent (re-adding touches, catch-up training)."""
        t0 = time.perf_counter()
        below = self.inner
        self.stage += 1
        learner = self._build(self.stage)
        transfer = getattr(learner, "transfer_from", None)
        if transfer is not None and type(below) is type(learner):
            transfer(below)
        for label, touch in self._touches:
            learner.add_touch(touch, label)
        for touch in self._references:
            learner.add_reference(touch)
        self.active.append(learner)
        if self.rung not in DESCRIPTOR_RUNGS:
            for _ in range(min(self.base_cfg.ladder_catchup, self._decisions)):
                train_round(learner)
        self._beliefs, self._heldout = [], []
        return time.perf_counter() - t0

    def _described(self, touch: Touch) -> Touch:
        """``touch`` with its plain descriptor attached, described once per trial (a trained
        rung ignores it)."""
        if touch.descriptor is not None or not any(r in DESCRIPTOR_RUNGS for r in self.rungs):
            return touch
        return replace(touch, descriptor=raw_descriptor(touch, self.base_cfg))
