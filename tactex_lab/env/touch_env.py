"""``TouchEnv``: active texture matching as a Gymnasium environment, on a touch source.

An episode is one trial: a scene of 1 reference + C comparison platforms drawn from the
source's classes exactly as ``tactex experiment real`` draws the scene of seed ``s``
(``sources.assign_platforms`` over the sorted classes; for a ``replay:DIR`` source the same
scene as ``tactex trial --seed s``), and the presses of that trial's touch function
(``source.trial(classes, s)``: recorded presses drawn without repetition, seeded).

The interface is ap_gym's active-perception environment's (``ActivePerceptionEnv``, ap_gym
0.7): ``inner_action_space`` (the platform to press, or STOP, which ap_gym's environments
lack), ``prediction_space`` (logits over the comparisons), ``action_space`` the dict of the two,
``prediction_target_space`` (the match, 0..C-1, a numpy integer as ap_gym's loss functions
take it), ``loss_fn`` (the cross-entropy of the logits
at the match over log C: 1 for a uniform guess; ap_gym's ``CrossEntropyLossFn(C).normalized``
where the program has imported ap_gym, whose torch and jax forms its agents train with), and
every step's reward ``info["base_reward"] - info["prediction"]["loss"]``. An environment made
after ``import ap_gym`` registers the class as an ap_gym ``BaseActivePerceptionEnv``, so ap_gym's
wrappers and agents take it as an active-perception task (``ap_gym.ensure_active_perception_env``
returns it as it is). This module never imports ap_gym itself (it loads datasets, and torch
where installed).

- ``reset(seed=s)`` presses the reference (platform 0) and returns its observation.
- ``action = {"action": a, "prediction": logits}``: ``a`` in 0..C presses that platform
  (0 = the reference again); ``a = C + 1`` is STOP. ``logits`` (C,) over the comparisons: at
  STOP the predicted match is ``argmax(logits) + 1``.
- Observation (dict): ``image`` the contact frame (240, 320, 3) uint8 RGB, ``no_contact``
  its no-contact frame (``has_no_contact``), ``extra`` up to ``EXTRA`` more in-contact frames of
  the same press (``extra_count`` of them valid), ``platform`` the platform pressed, ``ok`` 0
  when the press gave no touch (a failed press; the frames are zeros), ``touches`` presses per
  platform so far, ``budget_left`` presses left.
- Budget: ``C + 1 + budget`` presses in all (the baseline, every platform once, then
  ``budget`` more, as ``experiment real --budget``). Once spent, any action ends the episode
  (``truncated``) scored on its prediction.
- Base reward (``info["base_reward"]``): ``-touch_cost`` per press; at the end 1 for the right
  match, 0 otherwise. The reward is the base reward minus the prediction's loss
  (``info["prediction"]``: ``target``, ``loss``, ``metrics``; ``reset``'s info: ``target``).
- At the end ``info``: ``correct``, ``presses``, ``touches_after_baseline`` (presses - (C+1),
  the touches ``experiment real`` reports), ``truth`` (1..C), ``classes``.
- Every observation is new arrays: changing one changes no later observation.
"""

from __future__ import annotations

import sys
from typing import Any

import gymnasium as gym
import numpy as np

from tactex_ros.core.engine import TouchFailed
from tactex_ros.core.errors import InputError
from tactex_ros.core.touch import as_touch

H, W = 240, 320
EXTRA = 3                    # in-contact frames per press besides the strongest (replay's)
MAX_SEED = 2**31 - 1


def scene_of(classes: list[str], comparisons: int, seed: int) -> tuple[list[str], int]:
    """The scene of seed ``seed``: classes [reference, comparisons...] and the match (1..C),
    ``experiment real``'s draw (``curves.draw_scenes``: ``assign_platforms`` over the sorted
    classes)."""
    from tactex_ros.sources import assign_platforms
    return assign_platforms(sorted(classes), comparisons, None, None, seed)


def parse_seeds(text: str) -> list[int]:
    """``'0-9'`` or ``'0,3,7'`` (or a mix, ``'0-4,10'``) -> the seeds, in order."""
    out: list[int] = []
    for part in text.split(","):
        a, sep, b = part.strip().partition("-")
        try:
            lo, hi = int(a), int(b) if sep else int(a)
        except ValueError:
            raise InputError(f"--seeds {text!r}: expected e.g. 0-9 or 0,3,7") from None
        if not 0 <= lo <= hi <= MAX_SEED:
            raise InputError(f"--seeds {text!r}: a range lo-hi with 0 <= lo <= hi <= {MAX_SEED}")
        out += range(lo, hi + 1)
    return out


class CrossEntropyLoss:
    """The prediction loss without ap_gym (its ``LossFn``'s numpy side): the cross-entropy of
    logits (..., C) at the targets (...,) (ints 0..C-1), over log C."""

    def __init__(self, num_classes: int) -> None:
        self.num_classes = num_classes

    def numpy(self, prediction: np.ndarray, target: np.ndarray, batch_shape: tuple = (),
              rng: np.random.Generator | None = None) -> np.ndarray:
        from scipy.special import log_softmax
        logp = log_softmax(np.asarray(prediction, np.float64), axis=-1)
        picked = np.take_along_axis(logp, np.asarray(target)[..., None], axis=-1)[..., 0]
        return -picked / np.log(self.num_classes)

    __call__ = numpy

    def numpy_loss_and_metrics(self, prediction: np.ndarray, target: np.ndarray,
                               batch_shape: tuple = (), rng: np.random.Generator | None = None
                               ) -> tuple[np.ndarray, dict]:
        return self.numpy(prediction, target, batch_shape, rng), {}


def _ap_gym():
    """ap_gym where the program has imported it, else None. Never imported here: it loads
    datasets (and torch, where installed) on import, which the product does not."""
    return sys.modules.get("ap_gym")


def loss_fn(num_classes: int):
    """The prediction loss of ``num_classes`` comparisons: ap_gym's normalized cross-entropy
    where ap_gym is imported, else ``CrossEntropyLoss`` (the same numbers)."""
    ap_gym = _ap_gym()
    if ap_gym is not None:
        return ap_gym.CrossEntropyLossFn(num_classes=num_classes).normalized
    return CrossEntropyLoss(num_classes)


class TouchEnv(gym.Env):
    """Active texture matching on a touch source (module docstring)."""

    metadata = {"render_modes": []}

    def __init__(self, source: str, comparisons: int = 4, budget: int = 15,
                 touch_cost: float = 0.0) -> None:
        from tactex_ros.sources import open_source
        if comparisons < 2:
            raise InputError(f"comparisons must be >= 2, got {comparisons}")
        if budget < 0:
            raise InputError(f"budget must be >= 0, got {budget}")
        self.source_spec = source
        self.src = open_source(source)
        if len(self.src.classes) < comparisons:
            raise InputError(f"source {source!r} has {len(self.src.classes)} classes: too few "
                             f"for {comparisons} comparisons")
        self.C, self.budget, self.touch_cost = comparisons, budget, float(touch_cost)
        self.STOP = comparisons + 1
        frame = gym.spaces.Box(0, 255, (H, W, 3), np.uint8)
        self.observation_space = gym.spaces.Dict({
            "image": frame, "no_contact": frame, "has_no_contact": gym.spaces.Discrete(2),
            "extra": gym.spaces.Box(0, 255, (EXTRA, H, W, 3), np.uint8),
            "extra_count": gym.spaces.Discrete(EXTRA + 1),
            "platform": gym.spaces.Discrete(comparisons + 1), "ok": gym.spaces.Discrete(2),
            "touches": gym.spaces.Box(0, 10**6, (comparisons + 1,), np.int64),
            "budget_left": gym.spaces.Box(0, 10**6, (1,), np.int64)})
        self.inner_action_space = gym.spaces.Discrete(comparisons + 2)
        self.prediction_space = gym.spaces.Box(-np.inf, np.inf, (comparisons,), np.float64)
        self.action_space = gym.spaces.Dict({"action": self.inner_action_space,
                                             "prediction": self.prediction_space})
        self.prediction_target_space = gym.spaces.Discrete(comparisons)
        self.loss_fn = loss_fn(comparisons)
        ap_gym = _ap_gym()
        if ap_gym is not None:      # ap_gym's wrappers and agents take it as an AP task
            ap_gym.BaseActivePerceptionEnv.register(TouchEnv)
        self._fn = None
        self._over = True

    @property
    def max_presses(self) -> int:
        return self.C + 1 + self.budget

    def reset(self, *, seed: int | None = None, options: dict | None = None
              ) -> tuple[dict, dict]:
        if seed is not None and (isinstance(seed, bool) or not isinstance(seed, (int, np.integer))
                                 or not 0 <= int(seed) <= MAX_SEED):
            raise InputError(f"seed {seed!r}: an integer 0..{MAX_SEED} (the trial seeds of "
                             "tactex trial and experiment real)")
        super().reset(seed=seed)
        if seed is None:
            seed = int(self.np_random.integers(0, MAX_SEED))
        self.seed_ = int(seed)
        self.classes, self.truth = scene_of(self.src.classes, self.C, self.seed_)
        self._fn = self.src.trial(self.classes, self.seed_)
        self.touches = np.zeros(self.C + 1, dtype=np.int64)
        self._over = False
        return self._press(0), {"seed": self.seed_, "comparisons": self.C,
                                "budget": self.budget,
                                "prediction": {"target": np.int64(self.truth - 1)}}

    def _press(self, platform: int) -> dict[str, Any]:
        self.touches[platform] += 1
        obs = self._blank(platform)
        try:
            t = as_touch(self._fn(platform))
        except TouchFailed:
            return obs
        # copies: the source keeps its frames (a replay's cache), the caller may change these
        obs["image"][:] = t.frame
        obs["ok"] = 1
        if t.no_contact is not None:
            obs["no_contact"][:] = t.no_contact
            obs["has_no_contact"] = 1
        if t.extra is not None and len(t.extra):
            k = min(len(t.extra), EXTRA)
            obs["extra"][:k] = t.extra[:k]
            obs["extra_count"] = k
        return obs

    def step(self, action: dict) -> tuple[dict, float, bool, bool, dict]:
        if self._over:
            raise InputError("step() after the episode ended: call reset()")
        a = action["action"]
        if isinstance(a, (bool, np.bool_)) or not isinstance(a, (int, np.integer)) and not (
                isinstance(a, np.ndarray) and a.shape == () and a.dtype.kind in "iu"):
            raise InputError(f"action {a!r}: an integer 0..{self.STOP} (0..{self.C} presses a "
                             f"platform, {self.STOP} is STOP), not {type(a).__name__}")
        a = int(a)
        if not 0 <= a <= self.STOP:
            raise InputError(f"action {a}: 0..{self.C} presses a platform, {self.STOP} is STOP")
        logits = np.asarray(action["prediction"], dtype=np.float64)
        if logits.shape != (self.C,):
            raise InputError(f"prediction: {self.C} logits over the comparisons, got shape "
                             f"{logits.shape}")
        if np.isnan(logits).any():
            raise InputError(f"prediction {logits.tolist()}: NaN among the logits (its argmax "
                             "would be a guess); give numbers, -inf allowed")
        spent = int(self.touches.sum()) >= self.max_presses
        if a == self.STOP or spent:
            return self._end(logits, truncated=a != self.STOP)
        obs = self._press(a)
        return self._scored(obs, -self.touch_cost, logits, False, False, {})

    def _scored(self, obs: dict, base: float, logits: np.ndarray, terminated: bool,
                truncated: bool, info: dict) -> tuple[dict, float, bool, bool, dict]:
        """A step's result in ap_gym's terms: the reward is ``base`` minus the loss of the
        prediction ``logits`` at the match, both in ``info``."""
        target = np.int64(self.truth - 1)
        loss, metrics = self.loss_fn.numpy_loss_and_metrics(logits, target)
        info.update(base_reward=base, prediction={"target": target, "loss": float(loss),
                                                  "metrics": metrics})
        return obs, base - float(loss), terminated, truncated, info

    def _end(self, logits: np.ndarray, truncated: bool) -> tuple[dict, float, bool, bool, dict]:
        self._over = True
        pred = int(np.argmax(logits)) + 1
        presses = int(self.touches.sum())
        info = {"correct": pred == self.truth, "prediction_index": pred, "truth": self.truth,
                "presses": presses, "touches_after_baseline": presses - (self.C + 1),
                "classes": list(self.classes), "seed": self.seed_}
        return self._scored(self._blank(0), float(info["correct"]), logits, not truncated,
                            truncated, info)

    def _blank(self, platform: int) -> dict[str, Any]:
        """An observation without a touch (zero frames, ``ok`` 0): a failed press's, and the
        terminal one; the counts as they are."""
        return {"image": np.zeros((H, W, 3), np.uint8),
                "no_contact": np.zeros((H, W, 3), np.uint8), "has_no_contact": 0,
                "extra": np.zeros((EXTRA, H, W, 3), np.uint8), "extra_count": 0,
                "platform": platform, "ok": 0, "touches": self.touches.copy(),
                "budget_left": np.array([max(self.max_presses - int(self.touches.sum()), 0)],
                                        np.int64)}

