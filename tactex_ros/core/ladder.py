"""The ladder: a learner that models no more than the scene needs (models ``auto`` and
``cnn_auto``).

The trial starts on the cheapest rung and climbs one rung only where the trial's own evidence
says the scene is hard. Two settings classes make a ladder (``is_ladder``), each with its rungs
and its climb rule (``rungs_of``):

``auto`` (``LadderSettings.ladder``, by default the texture descriptor, the shipped method),
rungs cheapest first, separated by commas (or ``+``):

- ``descriptor``: the descriptor learner as configured, without a representation;
- ``representation``: the descriptor learner with ``LadderSettings.representation`` (a
  ``tactex prepare`` file). Without that file the rung is skipped (``Ladder.notes`` says so);
- any other name: a preset of ``core/config.py`` whose model is a learner plug-in (``cnn``:
  the lab's small Inception at 48 px), optionally ``@px`` for its input side.

``cnn_auto`` (``AutoSettings.auto_ladder``, by default ``small_inception`` at 48 px, then
96 px): rungs ``variant@px``, each a CNN with the settings' own CNN fields at that input side.

Every rung is built through ``core/build.make_learner`` (the product imports no plug-in: a rung
whose plug-in is not installed is skipped, the note says why).

The evidence is a pure function of the current rung's history, checked at every decision
(``train_round``, called once per decision). The rule of ``auto`` (``Rule``,
``escalation_reason``), once the rung has seen ``ladder_patience`` decisions:

- *held-back touches*: fewer than ``ladder_heldout_acc`` of the last ``ladder_window``
  comparison touches were classified right by the rung before it stored them;
- *the belief does not sharpen*: the belief in the leading comparison rose by less than
  ``ladder_min_gain`` over the last ``ladder_patience`` decisions and is still below
  ``ladder_sure``;
- *the best two stay close*: the two largest beliefs differ by less than ``ladder_margin``.

The rule of ``cnn_auto`` (``EntropyRule``, ``entropy_reason``): the held-back test with
``auto_window`` / ``auto_heldout_acc`` (from the first full window), then, after more than
``auto_patience`` decisions, a predictive entropy of the reference that fell by less than
``auto_min_drop`` (relative) over the last ``auto_patience`` decisions and is still above
``auto_entropy`` x log C.

On escalation the next rung gets every touch of the trial (the raw touches are kept; a
descriptor rung reuses the descriptor of the rung below, nothing is described twice; a CNN
starts from the weights of the CNN below where its ``transfer_from`` finds them fitting) and a
training rung gets ``ladder_catchup`` (``auto_catchup``) rounds at once (their time counts in
the round's ``TrainStats.seconds``; ``TrainStats.escalation`` says why, the round record keeps
it). A trained rung below is let go on the climb; a descriptor rung stays, since the strategy
``infogain`` is served by the highest descriptor rung in use, so the touches keep being chosen
by expected information while a CNN decides the belief.
"""

from __future__ import annotations

import json
import logging
import math
import re
import struct
import time
from dataclasses import asdict, dataclass, field, replace
from collections.abc import Callable

import numpy as np

from .descriptor import DescriptorLearner, raw_descriptor
from .config import (CNN_MODELS, PRESETS, AutoSettings, LadderSettings, LearnerSettings,
                     learner_class, learner_settings, preset)
from .errors import InputError
from .learners import Learner, TrainStats, can_checkpoint, train_round
from .plugins import LEARNERS, available
from .strategies import predictive_entropy
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
    def of(cfg: LadderSettings) -> Rule:
        return Rule(cfg.ladder_patience, cfg.ladder_min_gain, cfg.ladder_sure,
                    cfg.ladder_margin, cfg.ladder_window, cfg.ladder_heldout_acc)

    def reason(self, history: History) -> Evidence | None:
        """``escalation_reason`` on a rung's history."""
        return escalation_reason(history.beliefs, history.heldout, self)

    def describe(self, ev: Evidence, below: str, above: str) -> str:
        """The round record's ``escalation`` of a climb from rung ``below`` to ``above``."""
        return f"{below} -> {above}: {ev}"


@dataclass(frozen=True)
class Evidence:
    """Why a rung is not enough: which ``test`` (``heldout``, ``not_sharpening``, ``close``;
    ``entropy`` of ``EntropyRule``), the ``value`` measured (share right, rise of the leading
    belief, gap of the best two; the reference's predictive entropy [nats]) and the
    ``threshold`` it fell below (``entropy``: stayed above, the floor), after ``decisions``
    decisions on the rung; ``before``: ``entropy``'s value ``patience`` decisions earlier."""

    test: str
    value: float
    threshold: float
    decisions: int
    before: float | None = None

    def __str__(self) -> str:
        if self.test == "entropy":
            return (f"entropy: predictive entropy of the reference {self.before:.3f} -> "
                    f"{self.value:.3f} nats > {self.threshold:.3f} after {self.decisions} "
                    "decisions")
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


@dataclass(frozen=True)
class EntropyRule:
    """The climb rule of ``cnn_auto`` (``AutoSettings.auto_*``), on the ladder's tests
    ``heldout`` and ``entropy`` (``entropy_reason``)."""

    patience: int = 2          # decisions before the entropy test (it spans this many)
    min_drop: float = 0.7      # relative fall of the entropy over ``patience`` decisions
    entropy: float = 0.2       # ... while above this fraction of log C
    window: int = 3            # held-back touches judged together
    heldout_acc: float = 0.5   # share of them right below which the rung is not enough
    num_classes: int = 2       # C, for the entropy floor

    @staticmethod
    def of(cfg: AutoSettings, num_classes: int) -> EntropyRule:
        return EntropyRule(cfg.auto_patience, cfg.auto_min_drop, cfg.auto_entropy,
                           cfg.auto_window, cfg.auto_heldout_acc, num_classes)

    def reason(self, history: History) -> Evidence | None:
        """``entropy_reason`` on a rung's history."""
        return entropy_reason(history.entropies, history.heldout, self)

    def describe(self, ev: Evidence, below: str, above: str) -> str:
        """The round record's ``escalation`` (the wording ``cnn_auto`` records have had)."""
        if ev.test == "heldout":
            return (f"held-back touches: {ev.value:.2f} of the last {self.window} classified "
                    f"right < {ev.threshold:g}")
        return (f"entropy not falling: {ev.before:.3f} -> {ev.value:.3f} nats over "
                f"{self.patience} rounds, above {ev.threshold:.3f}")


def entropy_reason(entropies: list[float], heldout: list[bool],
                   rule: EntropyRule) -> Evidence | None:
    """Why the current rung is not enough under ``EntropyRule``, or None to stay.

    ``entropies``: the predictive entropy of the reference [nats] at every decision on this
    rung, oldest first; ``heldout`` as for ``escalation_reason``. In order: held-back touches
    (once ``rule.window`` of them), then, with more than ``rule.patience`` decisions, an
    entropy above ``rule.entropy`` x log C that fell by less than ``rule.min_drop`` of its
    value ``rule.patience`` decisions earlier."""
    n = len(entropies)
    if len(heldout) >= rule.window:
        acc = float(np.mean(heldout[-rule.window:]))
        if acc < rule.heldout_acc:
            return Evidence("heldout", acc, rule.heldout_acc, n)
    k = rule.patience
    if n > k:
        h_now, h_then = entropies[-1], entropies[-1 - k]
        floor = rule.entropy * math.log(rule.num_classes)
        if h_now > floor and h_now > (1.0 - rule.min_drop) * h_then:
            return Evidence("entropy", h_now, floor, n, before=h_then)
    return None


@dataclass
class History:
    """The current rung's evidence (reset on a climb): per decision its (C,) belief and the
    predictive entropy of the reference [nats]; per held-back comparison touch whether the
    rung classified it right before storing it."""

    beliefs: list[np.ndarray] = field(default_factory=list)
    entropies: list[float] = field(default_factory=list)
    heldout: list[bool] = field(default_factory=list)


def _trained_preset(name: str) -> bool:
    """Whether preset ``name``'s model is a learner plug-in (a trained model)."""
    return learner_class(PRESETS[name].get("model", "descriptor")).plugin


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
        if name not in PRESETS or not _trained_preset(name):
            cands = [p for p in PRESETS if _trained_preset(p)]
            raise InputError(f"ladder rung {r!r}: one of {', '.join(DESCRIPTOR_RUNGS)} or a "
                             f"preset with a trained model ({', '.join(cands)})[@px]")
        if px and not (px.isdigit() and 32 <= int(px) <= 512):
            raise InputError(f"ladder rung {r!r}: input size must be 32..512 px")
    _no_repeat(rungs, f"ladder {text!r}")
    return rungs


def _no_repeat(rungs: list[str], what: str) -> None:
    """InputError naming ``what`` and the rung given twice: a rung is climbed once."""
    seen = set()
    for r in rungs:
        if r in seen:
            raise InputError(f"{what}: rung {r!r} given twice; each rung once, cheapest "
                             "first")
        seen.add(r)


def parse_cnn_rungs(text: str, default_size: int) -> list[str]:
    """``AutoSettings.auto_ladder`` (``'small_inception@32,inception_v3_random@96'``; a variant
    alone takes ``default_size`` px) -> the rungs as ``variant@px``, checked (InputError)."""
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
        out.append(f"{name}@{px}")
    if not out:
        raise InputError("auto_ladder is empty")
    _no_repeat(out, f"auto_ladder {text!r}")
    return out


def _plugin_missing(model: str) -> str | None:
    if model not in available(LEARNERS):
        return f"the learner plug-in {model!r} is not installed"
    return None


class ModelRungs:
    """The rungs of model ``auto`` (``LadderSettings``): descriptor rungs and presets."""

    def __init__(self, cfg: LadderSettings, num_classes: int) -> None:
        self.cfg = cfg
        self.text = cfg.ladder
        self.names = parse_rungs(cfg.ladder)
        self.rule = Rule.of(cfg)
        self.catchup = cfg.ladder_catchup

    def missing(self, rung: str) -> str | None:
        """Why ``rung`` cannot run here (None: it can)."""
        name = rung.partition("@")[0]
        if name == "representation" and not self.cfg.representation:
            return "no representation file (LadderSettings.representation, --representation)"
        if name not in DESCRIPTOR_RUNGS:
            return _plugin_missing(PRESETS[name]["model"])
        return None

    def config(self, rung: str) -> LearnerSettings:
        """A descriptor rung: the ladder's descriptor settings (``DescriptorSettings``); a CNN
        rung: its preset's (``CnnSettings``) with the ladder's guards, threads and device."""
        name, _, px = rung.partition("@")
        if name in DESCRIPTOR_RUNGS:
            mine = self.cfg.as_model("descriptor").model_dump()
            if name == "descriptor":
                mine["representation"] = ""
            return learner_settings(mine, f"ladder rung {name!r}")
        over = {"guards": self.cfg.guards, "threads": self.cfg.threads,
                "device": self.cfg.device}
        if px:
            over["input_size"] = int(px)
        return preset(name, **over)


class CnnRungs:
    """The rungs of model ``cnn_auto`` (``AutoSettings``): CNN variants at input sizes."""

    def __init__(self, cfg: AutoSettings, num_classes: int) -> None:
        self.cfg = cfg
        self.text = cfg.auto_ladder
        self.names = parse_cnn_rungs(cfg.auto_ladder, cfg.input_size)
        self.rule = EntropyRule.of(cfg, num_classes)
        self.catchup = cfg.auto_catchup

    def missing(self, rung: str) -> str | None:
        return _plugin_missing(rung.partition("@")[0])

    def config(self, rung: str) -> LearnerSettings:
        """The settings' CNN fields (``CnnSettings``) with the rung's variant and input side."""
        name, _, px = rung.partition("@")
        return self.cfg.as_model(name, input_size=int(px))


_RUNGS = {LadderSettings: ModelRungs, AutoSettings: CnnRungs}


def rungs_of(cfg: LadderSettings | AutoSettings, num_classes: int = 2) -> ModelRungs | CnnRungs:
    """The rungs, climb rule and catch-up of a ladder's settings (``cfg.is_ladder``)."""
    return _RUNGS[type(cfg)](cfg, num_classes)


class Ladder:
    """The learner of the current rung plus what escalation needs (raw touches, the rung's
    history). A ``core.learners.Learner`` with ``train_round``."""

    def __init__(self, num_classes: int, cfg: LadderSettings | AutoSettings, seed: int = 0, *,
                 make: Callable[[int, LearnerSettings, int], Learner]) -> None:
        """``make``: builds a rung's learner from its settings (``core/build.make_learner``)."""
        self.make = make
        self.base_cfg = cfg
        self.num_classes = num_classes
        self.seed = seed
        self.plan = rungs_of(self.base_cfg, num_classes)
        self.rule = self.plan.rule
        self.notes: list[str] = []                      # rungs skipped, and why
        self.rungs: list[str] = []
        for r in self.plan.names:
            why = self.plan.missing(r)
            if why:
                self.notes.append(f"ladder rung {r!r} skipped: {why}")
                log.warning(self.notes[-1])
            else:
                self.rungs.append(r)
        if not self.rungs:
            raise InputError(f"ladder {self.plan.text!r}: no usable rung "
                             f"({'; '.join(self.notes)})")
        self.stage = 0
        self.active: list[Learner] = [self._build(0)]   # the current rung, descriptor rungs below
        self._active_rungs = [self.rungs[0]]            # their rungs
        self._touches: list[tuple[int, Touch]] = []
        self._references: list[Touch] = []
        self.history = History()                        # this rung's
        self._last_label: int | None = None
        self._decisions = 0
        self.evidence: Evidence | None = None           # of the last climb

    # ------------------------------------------------------------------ rungs
    def rung_config(self, rung: str) -> LearnerSettings:
        """The learner settings one rung runs with (``ModelRungs.config``,
        ``CnnRungs.config``)."""
        return self.plan.config(rung)

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
        """Store a comparison touch in every rung in use; returns the current rung's sample
        (for ``heldout_proba``)."""
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
        self.history.heldout.append(bool(int(np.argmax(p)) == self._last_label))
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
                            self.rule.describe(reason, self.rungs[self.stage - 1], self.rung))
        return stats

    # ------------------------------------------------------------------ checkpoint
    def save_state(self) -> bytes:
        """The state after a round (``StatefulLearner``): the rung, this rung's evidence so far
        and the current rung's learner state when it has one (a CNN rung's; a descriptor rung
        is rebuilt from the touches). Layout: 4-byte big-endian length, that many bytes of
        JSON, then the rung learner's own bytes. The raw touches are not written: the same
        touches are added again before ``load_state``."""
        inner = self.inner.save_state() if can_checkpoint(self.inner) else None
        h = self.history
        head = {"rungs": self.rungs, "stage": self.stage, "decisions": self._decisions,
                "beliefs": [b.tolist() for b in h.beliefs], "entropies": h.entropies,
                "heldout": h.heldout, "last_label": self._last_label,
                "touches": len(self._touches), "references": len(self._references),
                "inner": inner is not None,
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
            history = History([np.asarray(b, dtype=np.float64) for b in st["beliefs"]],
                              [float(x) for x in st.get("entropies", [])],
                              [bool(x) for x in st["heldout"]])
            ev = None if st["evidence"] is None else Evidence(**st["evidence"])
        except (struct.error, UnicodeDecodeError, ValueError, KeyError, TypeError) as exc:
            raise InputError(f"ladder state unreadable ({type(exc).__name__}: {exc})") from None
        if st["rungs"] != self.rungs or not 0 <= stage < len(self.rungs) or \
                st["touches"] != len(self._touches) or \
                st["references"] != len(self._references) or self.stage != 0:
            raise InputError("ladder state of another ladder or other touches")
        while self.stage < stage:
            self._climb(transfer=False)
        if st["inner"]:
            if not can_checkpoint(self.inner):
                raise InputError(f"ladder state: rung {self.rung!r} cannot load a state")
            self.inner.load_state(inner)
        elif self.rung not in DESCRIPTOR_RUNGS:
            raise InputError(f"ladder state: rung {self.rung!r} saved no state")
        self._decisions = int(st["decisions"])
        self.history, self.evidence = history, ev
        self._last_label = st["last_label"]

    def escalation(self) -> Evidence | None:
        """Why to climb now (None: stay, or no rung above)."""
        if self.stage + 1 >= len(self.rungs):
            return None
        return self.rule.reason(self.history)

    def reference_probs(self) -> np.ndarray:
        probs = self.inner.reference_probs()
        self.history.entropies.append(predictive_entropy(probs))
        return probs

    def belief(self, probs: np.ndarray) -> np.ndarray:
        b = self.inner.belief(probs)
        self.history.beliefs.append(np.asarray(b, dtype=np.float64))
        return b

    def info_gain(self, rng: np.random.Generator) -> np.ndarray:
        """(C + 1,) expected entropy drop per platform, from the highest descriptor rung in use
        (strategy ``infogain``)."""
        for rung, learner in zip(reversed(self._active_rungs), reversed(self.active), strict=True):
            if rung in DESCRIPTOR_RUNGS:
                return learner.info_gain(rng)
        raise InputError("strategy 'infogain' needs a descriptor rung in the ladder")

    def stop_chance(self, rng: np.random.Generator, theta: float) -> np.ndarray:
        """(2, C + 1) stop chances (strategy ``lookahead``) from the highest descriptor rung in
        use."""
        for rung, learner in zip(reversed(self._active_rungs), reversed(self.active), strict=True):
            if rung in DESCRIPTOR_RUNGS and isinstance(learner, DescriptorLearner):
                return np.asarray(learner.stop_chance(rng, theta), dtype=np.float64)
        raise InputError("strategy 'lookahead' needs a descriptor rung in the ladder")

    def _climb(self, transfer: bool) -> Learner:
        """Build the next rung's learner from every touch so far (from the weights of the
        rung below where ``transfer``); the rung below stays in use only if it is a
        descriptor rung."""
        below = self.inner
        self.stage += 1
        learner = self._build(self.stage)
        move = getattr(learner, "transfer_from", None)
        if transfer and move is not None and type(below) is type(learner):
            move(below)
        for label, touch in self._touches:
            learner.add_touch(touch, label)
        for touch in self._references:
            learner.add_reference(touch)
        if self.rungs[self.stage - 1] not in DESCRIPTOR_RUNGS:
            self.active.pop()               # a trained rung below serves nothing more
            self._active_rungs.pop()
        self.active.append(learner)
        self._active_rungs.append(self.rung)
        return learner

    def _escalate(self) -> float:
        """Climb one rung; returns the seconds spent (re-adding touches, catch-up training)."""
        t0 = time.perf_counter()
        learner = self._climb(transfer=True)
        if self.rung not in DESCRIPTOR_RUNGS:
            for _ in range(min(self.plan.catchup, self._decisions)):
                train_round(learner)
        self.history = History()
        return time.perf_counter() - t0

    def _described(self, touch: Touch) -> Touch:
        """``touch`` with its plain descriptor attached, described once per trial (a trained
        rung ignores it)."""
        if touch.descriptor is not None or not any(r in DESCRIPTOR_RUNGS for r in self.rungs):
            return touch
        return replace(touch, descriptor=raw_descriptor(touch, self.base_cfg))
