"""Agents of ``TouchEnv``: tactex's own trial engine as a policy (``EngineAgent``: a strategy
and the stop rule), and ``evaluate``, the seeded evaluation of any agent.

An agent is an object with ``reset(obs, info)`` and ``act(obs) -> action`` (the env's action
dict). Each agent plays in its own environment (``evaluate`` takes a factory): nothing one
agent's episodes leave in an environment reaches another's. ``EngineAgent`` feeds every touch it observes to a ``TrialEngine`` built as
``experiment real`` builds it (``TrialSpec(C, learner, TrialConfig(strategy, rounds=budget,
stop_confidence=theta), seed)``): it presses the platforms still missing their baseline touch
in order, then whatever the engine's decision chooses, and STOPs when the engine is done,
predicting the engine's final belief. A touch the engine refuses (its contact guard) or a
failed press is repeated up to ``TrialConfig.touch_retries`` times, as ``TrialEngine.run``
does. The stop rule's decisions do not change the choices before the stop, so this agent
scores on a scene what ``experiment real`` reads off its belief curve at ``theta``.
"""

from __future__ import annotations

import statistics
from typing import Any, Protocol
from collections.abc import Callable

import numpy as np

from tactex_ros.core.config import SHIPPED_STOP, TrialConfig
from tactex_ros.core.engine import TrialSpec
from tactex_ros.core.errors import InputError
from tactex_ros.core.touch import Touch
from .touch_env import TouchEnv


class Agent(Protocol):
    def reset(self, obs: dict, info: dict) -> None: ...

    def act(self, obs: dict) -> dict: ...


def touch_of(obs: dict) -> Touch | None:
    """The ``Touch`` an observation carries (None for a failed press)."""
    if not obs["ok"]:
        return None
    k = int(obs["extra_count"])
    return Touch(frame=obs["image"],
                 no_contact=obs["no_contact"] if obs["has_no_contact"] else None,
                 extra=obs["extra"][:k] if k else None)


class EngineAgent:
    """tactex's trial engine as an agent: learner settings ``learner`` (a preset's, e.g.
    ``core.config.preset('default')``), ``strategy``, stop threshold ``stop`` (0 = never: the
    budget ends the episode), ``budget`` touches after the baseline (the env's)."""

    def __init__(self, comparisons: int, learner: Any, strategy: str,
                 stop: float = SHIPPED_STOP, budget: int = 15) -> None:
        self.C, self.learner, self.strategy = comparisons, learner, strategy
        self.tcfg = TrialConfig(strategy=strategy, rounds=budget, stop_confidence=stop)

    def reset(self, obs: dict, info: dict) -> None:
        self.engine = TrialSpec(self.C, self.learner, self.tcfg, seed=int(info["seed"])).engine()
        self.pressed = 0
        self.tries = 0

    def act(self, obs: dict) -> dict:
        eng, platform = self.engine, int(obs["platform"])
        stored = False
        touch = touch_of(obs)
        if touch is None:
            eng.record_failure(platform, "press failed")
        else:
            try:
                eng.add_touch(platform, touch)
                stored = True
            except InputError as exc:       # the contact guard refused the frame
                eng.record_failure(platform, str(exc))
        if not stored and self.tries < self.tcfg.touch_retries:
            self.tries += 1
            return self._press(platform)            # repeated at once, as TrialEngine.run
        self.tries = 0
        missing = eng.baseline_platforms()
        if missing:
            return self._press(missing[0])
        rec = eng.decide()
        if eng.done:
            return {"action": self.C + 1, "prediction": np.log(np.maximum(
                np.asarray(eng.final.probs, np.float64), 1e-300))}
        return self._press(rec.platform)

    def _press(self, platform: int) -> dict:
        return {"action": int(platform), "prediction": np.zeros(self.C)}


def run_episode(env: TouchEnv, agent: Agent, seed: int) -> dict[str, Any]:
    """One seeded episode: the end's ``info`` plus the summed base reward (``reward``: the
    touch costs and the end's 1 for the right match, the prediction losses left out) and the
    summed prediction loss (``prediction_loss``)."""
    obs, info = env.reset(seed=seed)
    agent.reset(obs, info)
    total = loss = 0.0
    while True:
        obs, _, terminated, truncated, info = env.step(agent.act(obs))
        total += info["base_reward"]
        loss += info["prediction"]["loss"]
        if terminated or truncated:
            return dict(info, reward=total, prediction_loss=loss, truncated=bool(truncated))


def evaluate(make_env: Callable[[], TouchEnv], agents: dict[str, Callable[[], Agent]],
             seeds: list[int]) -> dict[str, dict[str, Any]]:
    """Every agent (a factory: a fresh agent per call) on the episodes of ``seeds``, each
    agent in its own environment (``make_env()``): {label: {accuracy, touches (mean touches
    after the baseline), presses (mean), reward (mean summed base reward), episodes: [per
    seed]}}."""
    if not seeds:
        raise InputError("evaluate: no seeds")
    out = {}
    for label, make in agents.items():
        env = make_env()
        eps = []
        for s in seeds:
            r = run_episode(env, make(), s)
            eps.append({"seed": s, "correct": bool(r["correct"]),
                        "touches": int(r["touches_after_baseline"]),
                        "presses": int(r["presses"]), "reward": float(r["reward"]),
                        "truncated": r["truncated"], "classes": r["classes"]})
        out[label] = {"accuracy": statistics.fmean(e["correct"] for e in eps),
                      "touches": statistics.fmean(e["touches"] for e in eps),
                      "presses": statistics.fmean(e["presses"] for e in eps),
                      "reward": statistics.fmean(e["reward"] for e in eps),
                      "episodes": eps}
    return out
