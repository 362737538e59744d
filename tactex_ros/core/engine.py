"""The trial engine: baseline touches, then rounds of train -> score -> choose -> touch.

The engine does not know where touches come from. Platform indices: 0 is the reference, 1..C
are the comparison platforms (class c-1 of the learner). The first reference touch is the test
sample; every comparison touch is training data for its platform's class.

Two ways to drive it:

- ``run(touch_fn)``: synchronous loop for the command line and experiments.
- ``add_touch`` / ``decide`` / ``done``: step by step, for the ROS explorer node, which presses
  asynchronously and calls ``decide`` off its executor thread.

A round (``decide``): train one round, T Monte-Carlo passes on the reference, the strategy's
per-platform scores, the choice of the next platform (or none). Fixed ``rounds`` decisions that
request a touch, then a final decision whose mean softmax gives the prediction; an optional stop
rule ends earlier when the mean probability of the best platform reaches ``stop_confidence``.
"""

from __future__ import annotations

import time
from dataclasses import asdict, dataclass, field
from typing import Callable

import numpy as np

from .config import LearnerConfig, param, validate
from .errors import TactexError
from .learner import OnlineLearner
from .strategies import STRATEGIES, make_strategy
from .uncertainty import predictive_entropy


class TouchFailed(RuntimeError):
    """A touch could not be made (no contact, no image, arm fault); the trial goes on."""


@dataclass
class TrialConfig:
    """What a trial does (the learner's settings live in LearnerConfig)."""

    strategy: str = param("variance", "exploration strategy", choices=tuple(STRATEGIES))
    rounds: int = param(20, "decisions that request a touch after the baseline", 0, 1000)
    stop_confidence: float = param(0.0, "stop early when max mean probability >= this "
                                        "(0 = fixed rounds)", 0.0, 1.0)
    max_touches: int = param(0, "cap on total touches incl. baseline (0 = no cap)", 0, 100000)


@dataclass
class RoundRecord:
    round: int
    platform: int | None          # chosen next platform (1..C), None when nothing is touched
    probs: list[float]            # (C,) mean softmax of the reference
    scores: list[float] | None    # (C,) the strategy's scores, None for yoto / final
    predictive_entropy: float     # nats
    train_s: float
    score_s: float
    choose_s: float
    train_loss: float
    touches: list[int]            # touches per comparison platform when deciding
    model: str

    @property
    def decision_s(self) -> float:
        return self.train_s + self.score_s + self.choose_s


@dataclass
class TrialResult:
    prediction: int               # 1..C
    truth: int | None             # 1..C when known
    touches: int                  # total touches incl. baseline
    rounds: list[RoundRecord]
    final: RoundRecord
    failed_touches: list[dict] = field(default_factory=list)
    platform_ids: list[str] = field(default_factory=list)

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
            d["decision_s"] = r.decision_s
            rounds.append(d)
        return {
            "correct": self.correct, "prediction": name(self.prediction),
            "truth": name(self.truth), "touches": self.touches,
            "rounds": rounds[:-1], "final": rounds[-1],
            "failed_touches": self.failed_touches,
        }


class TrialEngine:
    """One active-exploration trial over C comparison platforms."""

    def __init__(self, n_comparisons: int, learner_cfg: LearnerConfig,
                 trial_cfg: TrialConfig | None = None, seed: int = 0,
                 platform_ids: list[str] | None = None) -> None:
        if n_comparisons < 2:
            raise TactexError(f"comparisons must be >= 2, got {n_comparisons}")
        self.C = n_comparisons
        self.trial_cfg = validate(trial_cfg or TrialConfig())
        self.learner_cfg = validate(learner_cfg)
        self.seed = seed
        self.strategy = make_strategy(self.trial_cfg.strategy)
        self.platform_ids = platform_ids or (["reference"] +
                                             [f"c{i}" for i in range(1, n_comparisons + 1)])
        if len(self.platform_ids) != n_comparisons + 1:
            raise TactexError(f"platform_ids needs {n_comparisons + 1} names, "
                              f"got {len(self.platform_ids)}")
        self.learner = self._make_learner(self.learner_cfg.model)
        self.rng = np.random.default_rng([seed, 7])
        self.touches = np.zeros(n_comparisons, dtype=np.int64)
        self.reference_touches = 0
        self.x_test = None
        self.records: list[RoundRecord] = []
        self.final: RoundRecord | None = None
        self.failed: list[dict] = []
        self.next_platform: int | None = None

    def _make_learner(self, model: str) -> OnlineLearner:
        if model == "auto":
            model = "small_inception"
        return OnlineLearner(self.C, self.learner_cfg, seed=self.seed, model_name=model)

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

    def add_touch(self, platform: int, img: np.ndarray) -> None:
        """Store a touch of ``platform`` (0 = reference, 1..C = comparison)."""
        if not 0 <= platform <= self.C:
            raise TactexError(f"platform {platform} outside 0..{self.C}")
        if platform == 0:
            if self.x_test is None:
                self.x_test = self.learner.test_tensor(img)
            self.reference_touches += 1
        else:
            self.learner.add_touch(img, platform - 1)
            self.touches[platform - 1] += 1

    def record_failure(self, platform: int, reason: str) -> None:
        self.failed.append({"platform": self.platform_ids[platform], "reason": reason,
                            "after_round": len(self.records)})

    def _budget_left(self) -> bool:
        cap = self.trial_cfg.max_touches
        return cap == 0 or self.total_touches < cap

    def decide(self) -> RoundRecord:
        """Train, score, choose. Sets ``next_platform`` (1..C or None) and maybe ``done``."""
        if self.done:
            raise TactexError("trial already finished")
        if self.x_test is None or np.any(self.touches == 0):
            raise TactexError("decide() before every platform has its baseline touch: "
                              f"missing {[self.platform_ids[p] for p in self.baseline_platforms()]}")
        stats = self.learner.train_round()
        t0 = time.perf_counter()
        probs = self.learner.mc_probs(self.x_test)
        pbar = probs.mean(axis=0)
        t1 = time.perf_counter()
        final = (len(self.records) >= self.trial_cfg.rounds or not self._budget_left() or
                 (self.trial_cfg.stop_confidence > 0 and
                  pbar.max() >= self.trial_cfg.stop_confidence))
        choice, scores = (None, None) if final else self.strategy.choose(probs, self.touches,
                                                                         self.rng)
        t2 = time.perf_counter()
        rec = RoundRecord(
            round=len(self.records) + 1, platform=None if choice is None else choice + 1,
            probs=pbar.tolist(), scores=None if scores is None else np.asarray(scores).tolist(),
            predictive_entropy=predictive_entropy(probs), train_s=stats.seconds,
            score_s=t1 - t0, choose_s=t2 - t1, train_loss=stats.mean_loss,
            touches=self.touches.tolist(), model=self.learner.model_name)
        if final:
            self.final = rec
        else:
            self.records.append(rec)
        self.next_platform = rec.platform
        return rec

    def result(self, truth: int | None = None) -> TrialResult:
        if self.final is None:
            raise TactexError("trial not finished")
        pred = int(np.argmax(self.final.probs)) + 1
        return TrialResult(prediction=pred, truth=truth, touches=self.total_touches,
                           rounds=list(self.records), final=self.final,
                           failed_touches=list(self.failed), platform_ids=self.platform_ids)

    # ------------------------------------------------------------------ loop
    def run(self, touch_fn: Callable[[int], np.ndarray], truth: int | None = None,
            on_round: Callable[[RoundRecord], None] | None = None) -> TrialResult:
        """Baseline, then rounds until done. ``touch_fn(platform) -> (240, 320, 3) uint8``.

        A TouchFailed from ``touch_fn`` is recorded and the trial goes on (a failed baseline
        touch is retried on the next pass over the missing platforms, up to 3 passes).
        """
        for _ in range(3):
            for p in self.baseline_platforms():
                try:
                    self.add_touch(p, touch_fn(p))
                except TouchFailed as exc:
                    self.record_failure(p, str(exc))
            if not self.baseline_platforms():
                break
        else:
            missing = [self.platform_ids[p] for p in self.baseline_platforms()]
            raise TactexError(f"baseline touches failed three times for {missing}")
        while not self.done:
            rec = self.decide()
            if on_round:
                on_round(rec)
            if rec.platform is not None:
                try:
                    self.add_touch(rec.platform, touch_fn(rec.platform))
                except TouchFailed as exc:
                    self.record_failure(rec.platform, str(exc))
        return self.result(truth)
