"""The trial engine: baseline touches, then rounds of train -> score -> choose -> touch.

The engine does not know where touches come from. Platform indices: 0 is the reference, 1..C
are the comparison platforms (class c-1 of the learner). Every reference touch is a test sample
(the decision uses all of them); every comparison touch is data for its platform's class.

Learners (``learner.model``, the tag of ``LearnerSettings``; ``core/learners.py``):
``descriptor`` (``core/descriptor.py``:
texture descriptors and a closed-form belief over the matching comparison; nothing is trained) or
a plug-in such as the thesis CNN (``tactex_lab/cnn/learner.py``, loaded only when named). Both give ``reference_probs()`` (T, C) and ``belief(probs)`` (C,); a
strategy with ``includes_reference`` (``infogain``) may choose platform 0, the reference again.

One contract for every caller: ``TrialSpec`` (what decides the outcome besides the touches,
including what a learner is given in memory: a fabric library, a prepared representation, a
fixed belief temperature) -> ``run_trial(spec, touch_fn)`` -> ``TrialOutcome`` (typed, platform
indices; ``to_dict`` is the JSON at the file edge). The command line and experiments pass a
simulated or replayed touch, the ROS explorer node its press over the graph (in its trial
thread, off the executor). ``TrialSpec.engine`` is the one place a trial's engine is built and
``TrialEngine.run`` the one loop (``run_trial`` is ``spec.engine().run``): a caller that
continues an engine restored from a checkpoint (``trial/run.py``) or reads its learner as the
trial goes (calibration's evidence, a failed trial's decisions) holds the engine and calls its
``run``; ``add_touch`` / ``decide`` / ``done`` are the steps ``run`` takes, for callers that
need them one by one (the latency bench).

A round (``decide``): train one round (CNN), the (T, C) table of the reference and the belief,
the strategy's per-platform scores, the choice of the next platform (or none). At most
``rounds`` decisions that request a touch, then a final decision whose belief gives the
prediction; the stop rule ends earlier when the belief in one platform reaches
``stop_confidence`` (``stop_reason``: ``confident``, ``rounds`` or ``max_touches``), unless the
two best comparisons are still as alike as repeated touches of one platform
(``stop_separation``, ``separated``): then it touches on and, if the budget ends so, ends not
sure.

Model ``auto`` (``LadderSettings``, ``core/ladder.py``) climbs a ladder (descriptor, the
prepared representation, a CNN plug-in) on evidence from the trial itself; ``cnn_auto``
(``AutoSettings``, the same ladder) does the same over CNN sizes. The round
records the model and input size it used (``RoundRecord.model``, ``TrainingDetail.input_size``)
and why it escalated (``TrainingDetail.escalation``); ``TrialOutcome.notes`` says which rungs
were skipped. A round's ``detail`` is its learner's: ``TrainingDetail`` for a learner that
trains (and a ladder round that climbed or ran a CNN rung), None for the descriptor (nothing
trained, nothing to report).

Guards (``learner.guards``, see ``core/guards.py``): ``add_touch`` raises ``TouchRejected`` (a
run-time state, ``TrialError``) for a blank or no-contact frame; ``run`` records it as a failed
touch and repeats it at once (``TrialConfig.touch_retries``), as it does a frame from
``touch_fn`` that fails validation. Rounds whose strategy scores are all equal are flagged
``degenerate`` (the choice then falls to the least-touched platform, ``strategies.break_ties``).
"""

from __future__ import annotations

import time
from dataclasses import asdict, dataclass, field, replace
from typing import TYPE_CHECKING
from collections.abc import Callable

import numpy as np

from .config import DescriptorSettings, LearnerSettings, TrialConfig, trial_preset  # noqa: F401
from .errors import InputError, TrialError
from .evidence import EProcess, EvidenceModel, shipped_evidence
from .guards import ContactGuard
from .build import make_learner
from .descriptor import DescriptorLearner
from .learners import Learner, TrainStats, can_checkpoint, train_round
from .strategies import make_strategy, predictive_entropy
from .touch import Touch, as_touch, validate_frame

if TYPE_CHECKING:
    from .library import FabricLibrary
    from .representation import Representation


class TouchFailed(RuntimeError):
    """A touch could not be made (no contact, no image, arm fault); the trial goes on.

    ``retry=False`` when the thrower already retried (the ROS motion node retries a press
    ``press.retries`` times): the engine then does not repeat it."""

    def __init__(self, reason: str, retry: bool = True) -> None:
        super().__init__(reason)
        self.retry = retry


class TouchRejected(TrialError):
    """A touch frame was refused (the contact guard: blank or no contact; or, in ``run``, a
    frame that fails validation); not stored. A run-time state of the sensor, not bad input:
    ``run`` records it and touches again."""


def confident(belief_max: float, stop_confidence: float) -> bool:
    """The stop rule: the belief in one comparison reached ``stop_confidence`` (0 = never)."""
    return stop_confidence > 0 and belief_max >= stop_confidence


def separated(separation: float | None, stop_separation: float) -> bool:
    """The "not sure" rule: the two best comparisons are told apart (their ``separation``,
    ``core/match.py``, exceeds ``stop_separation``; 0 = off; None: a learner without it)."""
    return bool(stop_separation <= 0 or separation is None or separation > stop_separation)


def stop_reason(belief_max: float, stop_confidence: float, decisions: int, rounds: int,
                budget_left: bool = True, sure_allowed: bool = True) -> str | None:
    """Why a trial ends at a decision after ``decisions`` earlier ones: 'confident' (the stop
    rule, only where ``sure_allowed``: ``separated``), 'rounds' (all ``rounds`` used),
    'max_touches' (no budget left), or None to go on. The offline evaluation of recorded
    belief curves applies the same rule (``tactex_lab/experiments/curves.py``, ``at_stop``)."""
    if sure_allowed and confident(belief_max, stop_confidence):
        return "confident"
    if decisions >= rounds:
        return "rounds"
    if not budget_left:
        return "max_touches"
    return None


def default_platform_ids(comparisons: int) -> list[str]:
    """The platforms' names when a scene gives none: ``reference, c1..cC``."""
    return ["reference"] + [f"c{i}" for i in range(1, comparisons + 1)]


@dataclass
class TrainingDetail:
    """What a round's training did, for a learner that trains (the lab's CNNs, ``cnn_auto``, a
    round of ``auto`` that climbed or ran a CNN rung);
    ``RoundRecord.detail`` of such a learner. JSON: ``{"kind": "training", ...}``."""

    input_size: int               # model input side [px] used this round
    train_s: float                # wall time of the round's training [s]
    train_loss: float             # mean training loss
    skipped_steps: int = 0        # training steps skipped (non-finite loss/gradient, guards)
    restored: bool = False        # training round rolled back, learning rate halved (guards)
    grad_norm: float = float("nan")  # median gradient norm this round
    escalation: str | None = None  # models 'auto' / 'cnn_auto': why the model climbed before
    #                                this round
    kind: str = "training"

    @classmethod
    def of(cls, stats: TrainStats, input_size: int) -> TrainingDetail:
        """The detail of one ``train_round`` (``core/learners.TrainStats``)."""
        return cls(input_size=input_size, train_s=stats.seconds, train_loss=stats.mean_loss,
                   skipped_steps=stats.skipped, restored=stats.restored,
                   grad_norm=stats.grad_norm, escalation=stats.escalation)


#: A round's learner-typed detail: ``TrainingDetail`` for a learner that trains; None for one
#: that trains nothing (the descriptor: its round is the common fields alone).
RoundDetail = TrainingDetail
TRAINING_FIELDS = tuple(f for f in TrainingDetail.__dataclass_fields__ if f != "kind")


def training_of(round_json: dict) -> dict:
    """The training detail of one round of a trial JSON (``TrialOutcome.to_dict``) as a dict,
    {} for a learner that trains nothing. Also reads the flat shape of files written before
    the detail existed (``train_loss`` etc. beside the common fields; a descriptor's there
    were placeholders, nothing trained)."""
    if "detail" in round_json:
        return dict(round_json["detail"] or {})
    if round_json.get("model", "descriptor") == "descriptor":
        return {}
    return {k: round_json.get(k) for k in TRAINING_FIELDS}


@dataclass
class RoundRecord:
    """One decision: the fields every learner has, and its learner's ``detail``."""

    round: int
    platform: int | None          # chosen next platform (1..C), None when nothing is touched
    probs: list[float]            # (C,) belief over the comparisons
    scores: list[float] | None    # (C,) the strategy's scores, None for yoto / final
    predictive_entropy: float     # nats
    score_s: float
    choose_s: float
    touches: list[int]            # touches per comparison platform when deciding
    model: str
    heldout: list[bool] = field(default_factory=list)  # touches since the last round, classified
    #                               right before being trained on (empty before round 1)
    degenerate: bool = False      # all strategy scores equal: the choice was a tie-break
    cpu_s: float = float("nan")   # CPU time of the decision, all threads of this process [s]
    #                               (robust to other processes sharing the machine)
    reference_touches: int = 1    # touches of the reference when deciding
    detail: RoundDetail | None = None
    evalues: list[float] | None = None  # trial.stop_rule 'evalue': every comparison's e-value
    #                                     at this decision (stop at 1 / stop_alpha)

    @property
    def train_s(self) -> float:
        """Training time of the round [s] (0 for a learner that trains nothing)."""
        return self.detail.train_s if self.detail is not None else 0.0

    @property
    def decision_s(self) -> float:
        return self.train_s + self.score_s + self.choose_s

    @property
    def model_label(self) -> str:
        """``model@input_px`` for a trained model, else the model's name (a ladder's descriptor
        rung: its round's detail has input size 0)."""
        if self.detail is None or not self.detail.input_size:
            return self.model
        return f"{self.model}@{self.detail.input_size}"


@dataclass
class TrialOutcome:
    prediction: int               # 1..C
    truth: int | None             # 1..C when known
    touches: int                  # total touches incl. baseline
    rounds: list[RoundRecord]
    final: RoundRecord
    failed_touches: list[dict] = field(default_factory=list)
    platform_ids: list[str] = field(default_factory=list)
    stop_reason: str = ""         # 'confident' (belief reached stop_confidence), 'rounds'
    #                               (all rounds used) or 'max_touches' (touch cap reached)
    reference_touches: int = 1
    sure: bool | None = None      # the belief reached stop_confidence (False: the trial ended
    #                               unsure, ``prediction`` is only the best guess; None: no stop
    #                               rule, nothing to be sure against)
    notes: list[str] = field(default_factory=list)  # model 'auto': ladder rungs skipped, why
    bound: dict = field(default_factory=dict)  # the stop's promise (TrialEngine.stop_bound):
    #                               the threshold, or alpha and the final e-values

    @property
    def confidence(self) -> float:
        """The final belief in the predicted comparison."""
        return float(max(self.final.probs))

    @property
    def correct(self) -> bool | None:
        return None if self.truth is None else self.prediction == self.truth

    def to_dict(self) -> dict:
        ids = self.platform_ids

        def name(i: int | None) -> str | None:
            return None if i is None else (ids[i] if ids else str(i))

        rounds = []
        for r in self.rounds + [self.final]:
            d = asdict(r)
            d["platform"] = name(r.platform)
            d["decision_s"] = r.decision_s      # the detail holds train_s, when there is one
            rounds.append(d)
        return {
            "correct": self.correct, "prediction": name(self.prediction),
            "truth": name(self.truth), "touches": self.touches,
            "rounds": rounds[:-1], "final": rounds[-1],
            "failed_touches": self.failed_touches, "stop_reason": self.stop_reason,
            "sure": self.sure, "confidence": self.confidence,
            "reference_touches": self.reference_touches,
            "models": sorted({r.model_label for r in self.rounds + [self.final]}),
            "notes": list(self.notes), "bound": dict(self.bound),
            "escalations": [{"round": r.round, "reason": r.detail.escalation,
                             "model": r.model_label}
                            for r in self.rounds + [self.final]
                            if r.detail is not None and r.detail.escalation],
        }


class TrialEngine:
    """One active-exploration trial over C comparison platforms."""

    def __init__(self, n_comparisons: int, learner_cfg: LearnerSettings,
                 trial_cfg: TrialConfig | None = None, seed: int = 0,
                 platform_ids: list[str] | None = None,
                 evidence: EvidenceModel | None = None) -> None:
        if n_comparisons < 2:
            raise InputError(f"comparisons must be >= 2, got {n_comparisons}")
        self.C = n_comparisons
        self.trial_cfg = trial_cfg or TrialConfig()     # settings: validated at the edge
        self.learner_cfg = learner_cfg
        self.seed = seed
        self.strategy = make_strategy(self.trial_cfg.strategy, self.trial_cfg.stop_confidence)
        self.platform_ids = platform_ids or default_platform_ids(n_comparisons)
        if len(self.platform_ids) != n_comparisons + 1:
            raise InputError(f"platform_ids needs {n_comparisons + 1} names, "
                             f"got {len(self.platform_ids)}")
        if self.strategy.includes_reference and not self.learner_cfg.scores_reference:
            raise InputError(f"strategy {self.trial_cfg.strategy!r} needs model 'descriptor' "
                             f"(got {self.learner_cfg.model!r}); with a CNN model choose "
                             "another strategy, e.g. variance")
        self.learner: Learner = make_learner(n_comparisons, self.learner_cfg, seed=seed)
        self.rng = np.random.default_rng([seed, 7])
        self.touches = np.zeros(n_comparisons, dtype=np.int64)
        self.reference_touches = 0
        self.stop_reason = ""
        self.records: list[RoundRecord] = []
        self.final: RoundRecord | None = None
        self.failed: list[dict] = []
        self.next_platform: int | None = None
        g = self.learner_cfg
        self.guard = (ContactGuard(g.contact_flat_min, g.contact_min,     # descriptor only:
                                   getattr(g, "contact_region_min", 0.0),
                                   getattr(g, "descriptor_height_map", False))
                      if g.guards else None)
        self._pending_heldout: list[bool] = []             # since the last decision
        self._separated = True           # the last decision's "not sure" rule (separated)
        self._touch_due = False          # restored from a checkpoint: next_platform not touched
        self.eprocess: EProcess | None = None   # stop_rule 'evalue' (core/evidence.py)
        if self.trial_cfg.stop_rule == "evalue":
            if not isinstance(self.learner, DescriptorLearner):
                raise InputError("trial.stop_rule 'evalue' needs model 'descriptor', got "
                                 f"{self.learner_cfg.model!r}")
            if evidence is None:      # the shipped one, fitted on the simulator's fabrics
                rep = self.learner.representation
                evidence = shipped_evidence(self.learner_cfg,
                                            prepared=rep.evidence if rep is not None else None)
            self.eprocess = EProcess(n_comparisons, evidence, self.trial_cfg.stop_alpha,
                                     null=self.trial_cfg.stop_null)

    def set_no_contact_reference(self, frame: np.ndarray | None) -> None:
        """A no-contact frame of this sensor session: enables the guard's contact test."""
        if self.guard is not None:
            self.guard.set_reference(None if frame is None else validate_frame(frame, "no-contact "
                                                                                     "reference"))

    # ------------------------------------------------------------------ state
    @property
    def total_touches(self) -> int:
        return int(self.touches.sum()) + self.reference_touches

    def baseline_platforms(self) -> list[int]:
        """Platforms still needing their baseline touch (0 = reference first)."""
        need = [] if self.reference_touches else [0]
        return need + [i + 1 for i in range(self.C) if self.touches[i] == 0]

    @property
    def done(self) -> bool:
        return self.final is not None

    def add_touch(self, platform: int, touch: Touch | np.ndarray) -> None:
        """Store a touch of ``platform`` (0 = reference, 1..C = comparison).

        ``touch``: a ``Touch`` (contact frame, optional no-contact frame and more contact
        frames) or a bare (240, 320, 3) uint8 frame. Every reference touch counts for the
        decision. Raises TouchRejected (a TrialError) when the guard finds a blank or
        no-contact frame; nothing is stored then and the platform still counts as untouched.
        """
        if not 0 <= platform <= self.C:
            raise InputError(f"platform {platform} outside 0..{self.C}")
        touch = as_touch(touch)
        frame = validate_frame(touch.frame, f"touch of platform {platform}")
        if self.guard is not None:
            ok, reason, touch = self.guard.inspect(replace(touch, frame=frame))
            if not ok:
                raise TouchRejected(f"touch of {self.platform_ids[platform]} rejected: {reason}")
        before = self._samples_before()
        if platform == 0:
            self.learner.add_reference(touch)
            self.reference_touches += 1
            self._observe(platform, before)
        else:
            x = self.learner.add_touch(touch, platform - 1)
            self._observe(platform, before)
            self.touches[platform - 1] += 1
            if self.records or self.final is not None:   # after the first decision
                p = self.learner.heldout_proba(x)
                self._pending_heldout.append(bool(int(np.argmax(p)) == platform - 1))

    def _samples_before(self) -> list[list[np.ndarray]] | None:
        """stop_rule 'evalue': the descriptors of every platform's touches so far (copies)."""
        if self.eprocess is None:
            return None
        return [list(s) for s in self.learner.match.samples_by_platform]  # type: ignore[attr-defined]

    def _observe(self, platform: int, before: list[list[np.ndarray]] | None) -> None:
        """stop_rule 'evalue': the new touch's evidence into the e-process."""
        if self.eprocess is None or before is None:
            return
        x = self.learner.match.samples_by_platform[platform][-1]  # type: ignore[attr-defined]
        self.eprocess.add_touch(platform, x, before)

    def record_failure(self, platform: int, reason: str) -> None:
        self.failed.append({"platform": self.platform_ids[platform], "reason": reason,
                            "after_round": len(self.records)})

    def _budget_left(self) -> bool:
        cap = self.trial_cfg.max_touches
        return cap == 0 or self.total_touches < cap

    def decide(self) -> RoundRecord:
        """Train, score, choose. Sets ``next_platform`` (0 = the reference again, 1..C, or
        None) and maybe ``done`` (``stop_reason`` says why)."""
        if self.done:
            raise TrialError("trial already finished")
        if self.reference_touches == 0 or np.any(self.touches == 0):
            raise TrialError("decide() before every platform has its baseline touch: "
                              f"missing {[self.platform_ids[p] for p in self.baseline_platforms()]}")
        c0 = time.process_time()
        stats = train_round(self.learner)                 # None: a learner that trains nothing
        t0 = time.perf_counter()
        probs = self.learner.reference_probs()
        pbar = self.learner.belief(probs)
        t1 = time.perf_counter()
        sep = getattr(self.learner, "separation", None)
        self._separated = separated(sep() if sep is not None and
                                    self.trial_cfg.stop_separation > 0 else None,
                                    self.trial_cfg.stop_separation)
        stop = self._stop_reason(pbar)
        final = stop is not None
        choice, scores = (None, None) if final else self.strategy.choose(
            probs, self.touches, self.rng, tie_break=self.learner_cfg.guards,
            model=self.learner, reference_touches=self.reference_touches)
        if choice is not None and not self.strategy.includes_reference:
            choice += 1                                   # comparison index -> platform
        t2 = time.perf_counter()
        degenerate = bool(scores is not None and np.ptp(np.asarray(scores, float)) <=
                          1e-9 * max(1.0, float(np.max(np.abs(scores)))))
        rec = RoundRecord(
            round=len(self.records) + 1, platform=choice,
            probs=pbar.tolist(), scores=None if scores is None else np.asarray(scores).tolist(),
            predictive_entropy=predictive_entropy(probs),
            score_s=t1 - t0, choose_s=t2 - t1,
            touches=self.touches.tolist(), reference_touches=self.reference_touches,
            model=self.learner.model_name,
            heldout=list(self._pending_heldout), degenerate=degenerate,
            cpu_s=time.process_time() - c0,
            detail=(None if stats is None
                    else TrainingDetail.of(stats, getattr(self.learner.cfg, "input_size", 0))),
            evalues=None if self.eprocess is None else self.eprocess.evalues.tolist())
        self._pending_heldout = []
        if final:
            self.final = rec
            self.stop_reason = stop
        else:
            self.records.append(rec)
        self.next_platform = rec.platform
        return rec

    def _stop_reason(self, belief: np.ndarray) -> str | None:
        """Why the trial ends at this decision, or None to go on."""
        if self.eprocess is not None:      # e-value rule: sure at E_c >= 1 / alpha
            return stop_reason(1.0 if self.eprocess.sure() is not None else 0.0, 1.0,
                               len(self.records), self.trial_cfg.rounds, self._budget_left())
        return stop_reason(float(belief.max()), self.trial_cfg.stop_confidence,
                           len(self.records), self.trial_cfg.rounds, self._budget_left(),
                           self._separated)

    @property
    def sure(self) -> bool | None:
        """Once done: did the final belief reach ``stop_confidence``? (None before the end or
        without a stop rule.) An unsure end gives the best guess and its belief, not an
        answer."""
        th = self.trial_cfg.stop_confidence
        if self.final is not None and self.eprocess is not None:
            return self.eprocess.sure() is not None
        if self.final is None or th <= 0:
            return None
        return self._separated and confident(float(max(self.final.probs)), th)

    def stop_bound(self) -> dict:
        """What the stop promises: ``{"rule": "threshold", "stop_confidence": theta}`` or the
        e-process's state (alpha, 1 / alpha, the e-values; ``EProcess.state``)."""
        if self.eprocess is not None:
            return self.eprocess.state()
        return {"rule": "threshold", "stop_confidence": self.trial_cfg.stop_confidence}

    def result(self, truth: int | None = None) -> TrialOutcome:
        if self.final is None:
            raise TrialError("trial not finished")
        pred = int(np.argmax(self.final.probs)) + 1
        named = self.eprocess.sure() if self.eprocess is not None else None
        if named is not None:
            pred = named + 1                  # the comparison whose e-value reached 1 / alpha
        return TrialOutcome(prediction=pred, truth=truth, touches=self.total_touches,
                           rounds=list(self.records), final=self.final,
                           failed_touches=list(self.failed), platform_ids=self.platform_ids,
                           stop_reason=self.stop_reason,
                           reference_touches=self.reference_touches, sure=self.sure,
                           notes=list(getattr(self.learner, "notes", [])),
                           bound=self.stop_bound())

    # ------------------------------------------------------------------ checkpoint
    def checkpoint(self) -> tuple[dict, bytes] | None:
        """The trial's state right after a decision that asked for a touch: (engine state as
        JSON-able dict, the learner's opaque bytes); None when the learner cannot save its
        state (the descriptor: a resume re-adds the touches, nothing is trained) or the trial
        is done. Written by the caller after each round (``record.TrialRecord``)."""
        if self.done or not self.records or not can_checkpoint(self.learner):
            return None
        state = {"version": CHECKPOINT_VERSION, "round": len(self.records),
                 "model": self.learner_cfg.model, "seed": self.seed,
                 "platform_ids": self.platform_ids, "touches": self.touches.tolist(),
                 "reference_touches": self.reference_touches,
                 "next_platform": self.next_platform, "failed": self.failed,
                 "records": [asdict(r) for r in self.records],
                 "rng": self.rng.bit_generator.state}
        return state, self.learner.save_state()   # type: ignore[attr-defined]

    def restore(self, state: dict, stored: list[tuple[int, Touch]], learner_state: bytes) -> None:
        """Continue a fresh engine from ``checkpoint()``'s state: ``stored`` are the touches
        the learner held then, (platform 0..C, touch) in their order (accepted ones only); they
        are added to the learner again (no training), then the learner's bytes are loaded. The
        next ``run`` makes the touch the restored decision asked for. InputError (named) when
        the state does not belong to this trial or to these touches; the engine is then
        unusable (build a new one)."""
        if self.records or self.total_touches:
            raise TrialError("restore() needs a fresh engine")
        if not can_checkpoint(self.learner):
            raise InputError(f"checkpoint: learner {self.learner_cfg.model!r} cannot load a "
                             "state")
        try:
            if state.get("version") != CHECKPOINT_VERSION:
                raise InputError(f"version {state.get('version')!r}, this code reads "
                                 f"{CHECKPOINT_VERSION}")
            for key, now in (("model", self.learner_cfg.model), ("seed", self.seed),
                             ("platform_ids", self.platform_ids)):
                if state.get(key) != now:
                    raise InputError(f"{key} is {state.get(key)!r}, the trial's {now!r}")
            counts = np.bincount([p for p, _ in stored], minlength=self.C + 1)
            if counts[0] != state["reference_touches"] or \
                    counts[1:].tolist() != list(state["touches"]):
                raise InputError(f"it holds {state['reference_touches']} reference and "
                                 f"{list(state['touches'])} comparison touches, the record "
                                 f"{int(counts[0])} and {counts[1:].tolist()}")
            records = [_round_record(r) for r in state["records"]]
            nxt = state["next_platform"]
            if len(records) != state["round"] or nxt is None or not 0 <= int(nxt) <= self.C:
                raise InputError("its rounds or next platform do not fit together")
        except InputError:
            raise
        except (KeyError, TypeError, ValueError) as exc:
            raise InputError(f"checkpoint state is incomplete ({type(exc).__name__}: {exc})") \
                from None
        for platform, touch in stored:
            if platform == 0:
                self.learner.add_reference(touch)
            else:
                self.learner.add_touch(touch, platform - 1)
        self.learner.load_state(learner_state)           # type: ignore[attr-defined]
        self.touches = np.asarray(state["touches"], dtype=np.int64)
        self.reference_touches = int(state["reference_touches"])
        self.records = records
        self.failed = list(state["failed"])
        self.next_platform = int(nxt)
        self.rng.bit_generator.state = state["rng"]
        self._touch_due = True

    # ------------------------------------------------------------------ loop
    def run(self, touch_fn: Callable[[int], Touch | np.ndarray], truth: int | None = None,
            on_round: Callable[[RoundRecord], None] | None = None,
            on_rejected: Callable[[int, TouchRejected], None] | None = None) -> TrialOutcome:
        """Baseline, then rounds until done. ``touch_fn(platform)`` returns a ``Touch`` or a
        (240, 320, 3) uint8 frame.

        A TouchFailed from ``touch_fn`` (unless ``retry=False``) or a frame ``add_touch``
        refuses (guard or validation; ``on_rejected(platform, error)`` is told) is recorded and
        repeated at once up to ``TrialConfig.touch_retries`` times; then the round is lost and
        the trial goes on (a baseline touch is tried again on the next pass over the missing
        platforms, up to ``TrialConfig.baseline_passes`` passes). ``on_round`` sees every
        decision before its touch is made.
        """
        for _ in range(self.trial_cfg.baseline_passes):
            for p in self.baseline_platforms():
                self._touch(p, touch_fn, on_rejected)
            if not self.baseline_platforms():
                break
        else:
            missing = [self.platform_ids[p] for p in self.baseline_platforms()]
            raise TrialError(f"baseline touches failed {self.trial_cfg.baseline_passes} times "
                              f"for {missing}")
        if self._touch_due and self.next_platform is not None:     # restored: its touch
            self._touch_due = False
            self._touch(self.next_platform, touch_fn, on_rejected)
        while not self.done:
            rec = self.decide()
            if on_round:
                on_round(rec)
            if rec.platform is not None:
                self._touch(rec.platform, touch_fn, on_rejected)
        return self.result(truth)

    def _touch(self, platform: int, touch_fn: Callable[[int], Touch | np.ndarray],
               on_rejected: Callable[[int, TouchRejected], None] | None) -> bool:
        """Touch ``platform``, repeating a failed or rejected touch up to ``touch_retries``
        times (each failure recorded); True once a touch is stored."""
        for _ in range(1 + self.trial_cfg.touch_retries):
            try:
                img = touch_fn(platform)
            except TouchFailed as exc:
                self.record_failure(platform, str(exc))
                if not exc.retry:
                    return False
                continue
            try:
                validate_frame(as_touch(img).frame, f"touch of platform {platform}")
            except InputError as exc:   # a frame the sensor spoiled: refused like the guard's
                rejected = TouchRejected(str(exc))
            else:
                try:
                    self.add_touch(platform, img)
                    return True
                except TouchRejected as exc:          # the contact guard
                    rejected = exc
            self.record_failure(platform, str(rejected))
            if on_rejected is not None:
                on_rejected(platform, rejected)
        return False


def refusing_no_contact(touch_fn: Callable[[int], Touch | np.ndarray],
                        cfg: LearnerSettings) -> Callable[[int], Touch]:
    """``touch_fn`` whose touches the learner's contact guard judges against the no-contact
    frame each one carries (``guards.press_verdict``; ``cfg.guards`` off: ``touch_fn`` as
    is): a touch without contact raises ``TouchFailed`` and the engine presses again. For
    touches recorded in separate sensor sessions (a replay), where the trial's one no-contact
    reference would not be theirs; on the robot every touch carries the camera's one."""
    if not getattr(cfg, "guards", False):
        return touch_fn
    from .guards import press_verdict

    def judged(platform: int) -> Touch:
        t = as_touch(touch_fn(platform))
        ok, reason = press_verdict(t, cfg.contact_flat_min, cfg.contact_min)
        if not ok:
            raise TouchFailed(f"touch of platform {platform} refused: {reason}")
        return t

    return judged


#: Layout of ``TrialEngine.checkpoint``'s state (a reader refuses another one).
CHECKPOINT_VERSION = 1


def _round_record(d: dict) -> RoundRecord:
    """A ``RoundRecord`` from its JSON form (strict JSON wrote NaN as null: back to NaN)."""
    from dataclasses import fields
    known = {f.name: f for f in fields(RoundRecord)}
    if set(d) - set(known):
        raise InputError(f"unknown round fields {sorted(set(d) - set(known))}")
    out = dict(d)
    for name, f in known.items():
        if out.get(name) is None and f.type == "float":
            out[name] = float("nan")
    for name in ("probs", "scores"):
        if out.get(name) is not None:
            out[name] = [float("nan") if v is None else float(v) for v in out[name]]
    if isinstance(out.get("detail"), dict):
        out["detail"] = _training_detail(out["detail"])
    return RoundRecord(**out)


def _training_detail(d: dict) -> TrainingDetail:
    """A ``TrainingDetail`` from its JSON form (null floats back to NaN); refuses another kind."""
    from dataclasses import fields
    if d.get("kind", "training") != "training":
        raise InputError(f"unknown round detail kind {d.get('kind')!r}")
    known = {f.name for f in fields(TrainingDetail)}
    if set(d) - known:
        raise InputError(f"unknown round detail fields {sorted(set(d) - known)}")
    out = dict(d)
    for name in ("train_s", "train_loss", "grad_norm"):
        if out.get(name) is None:
            out[name] = float("nan")
    return TrainingDetail(**out)


@dataclass(frozen=True)
class TrialSpec:
    """What decides a trial's outcome besides its touches: ``comparisons`` platforms besides
    the reference, the learner and trial settings, the seed, the platforms' names (default
    ``reference, c1..cC``) and the sensor session's no-contact frame (240, 320, 3) uint8 for the
    contact guard (None: the guard's flatness test only).

    What a descriptor learner is given in memory rather than by a file: ``library``, the
    session's fabric library (used when the settings turn ``fabric_library`` on);
    ``representation``, a prepared representation (``core/representation.py``, what
    ``tactex prepare`` writes; e.g. one fitted on a class fold) in place of the settings'
    ``representation`` file; ``temperature``, the belief's temperature fixed for this trial
    (None: the representation's calibrated one or ``match_temperature``, as the settings say).
    """

    comparisons: int
    learner: LearnerSettings = field(default_factory=DescriptorSettings)
    trial: TrialConfig = field(default_factory=TrialConfig)
    seed: int = 0
    platform_ids: tuple[str, ...] | None = None
    no_contact: np.ndarray | None = None
    library: FabricLibrary | None = None
    representation: Representation | None = None
    temperature: float | None = None
    evidence: EvidenceModel | None = None   # trial.stop_rule 'evalue': its fitted null and
    #                                         alternative (core/evidence.py)

    def engine(self) -> TrialEngine:
        """The trial's engine, ready for its first touch (the one place one is built). A
        ``library`` (``core/library.py``) is given to a learner whose settings turn
        ``fabric_library`` on; ``representation`` / ``temperature`` need a descriptor learner
        (InputError otherwise)."""
        eng = TrialEngine(self.comparisons, self.learner, self.trial, seed=self.seed,
                          platform_ids=list(self.platform_ids) if self.platform_ids else None,
                          evidence=self.evidence)
        if self.representation is not None or self.temperature is not None:
            if not hasattr(eng.learner, "use_representation"):
                raise InputError("TrialSpec.representation / temperature need model "
                                 f"'descriptor', got {self.learner.model!r}")
            eng.learner.use_representation(self.representation, self.temperature)
        if self.library is not None and getattr(self.learner, "fabric_library", False) and \
                hasattr(eng.learner, "use_library"):
            eng.learner.use_library(self.library)
        if self.no_contact is not None:
            eng.set_no_contact_reference(self.no_contact)
        return eng


def run_trial(spec: TrialSpec, touch_fn: Callable[[int], Touch | np.ndarray],
              truth: int | None = None,
              on_round: Callable[[RoundRecord], None] | None = None,
              on_rejected: Callable[[int, TouchRejected], None] | None = None) -> TrialOutcome:
    """Run the trial ``spec`` describes with ``touch_fn(platform)`` (0 = reference, 1..C) until
    it ends, on a new engine: ``spec.engine().run(...)`` (``TrialEngine.run``); ``truth``
    (1..C) when known. Everything the trial is given is in ``spec``; a caller that holds the
    engine itself (to continue one restored from a checkpoint, or to read its learner while the
    trial runs) builds it with ``spec.engine()`` and calls its ``run``."""
    return spec.engine().run(touch_fn, truth=truth, on_round=on_round, on_rejected=on_rejected)
