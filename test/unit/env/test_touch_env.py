"""``TouchEnv`` on a small library of recorded presses (image files): the spaces hold every
observation, STOP ends the episode scored on its prediction, the budget truncates, bad actions
are refused, the same seed gives the same episode, and tactex's engine plays it as an agent."""

from pathlib import Path

import cv2
import numpy as np
import pytest

gym = pytest.importorskip("gymnasium")

from tactex_ros.core.config import preset  # noqa: E402
from tactex_ros.core.errors import InputError  # noqa: E402
from tactex_ros.env.agents import EngineAgent, evaluate, run_episode  # noqa: E402
from tactex_ros.env.touch_env import TouchEnv, parse_seeds, scene_of  # noqa: E402


def _library(root: Path, classes: int = 5, presses: int = 3) -> str:
    """Image presses: class k is a stripe texture of period 4 + 3k, with noise."""
    rng = np.random.default_rng(0)
    for k in range(classes):
        d = root / f"fabric{k}"
        d.mkdir(parents=True)
        x = np.arange(320)
        stripe = (127 + 100 * np.sin(2 * np.pi * x / (4 + 3 * k)))[None, :, None]
        for i in range(presses):
            img = np.clip(stripe + rng.normal(0, 8, (240, 320, 3)), 0, 255).astype(np.uint8)
            cv2.imwrite(str(d / f"{i}.png"), img)
    return f"replay:{root}"


def test_random_agent_episode_and_the_rules(tmp_path):
    env = TouchEnv(_library(tmp_path), comparisons=4, budget=2, touch_cost=0.01)
    obs, info = env.reset(seed=3)
    assert env.observation_space.contains(obs) and obs["platform"] == 0 and obs["ok"] == 1
    assert (env.classes, env.truth) == scene_of(env.src.classes, 4, 3)
    rng = np.random.default_rng(0)
    n = 0
    while True:        # random presses; the budget (5 + 2 presses) ends the episode
        obs, reward, terminated, truncated, info = env.step(
            {"action": int(rng.integers(0, 5)), "prediction": rng.normal(size=4)})
        n += 1
        if terminated or truncated:
            break
        assert env.observation_space.contains(obs) and reward == -0.01
    assert truncated and not terminated and info["presses"] == 7 and n == 7
    assert info["touches_after_baseline"] == 2 and reward == float(info["correct"])
    with pytest.raises(InputError):
        env.step({"action": 5, "prediction": np.zeros(4)})       # over: reset first
    env.reset(seed=3)
    with pytest.raises(InputError):
        env.step({"action": 6, "prediction": np.zeros(4)})       # 0..4 press, 5 = STOP
    logits = np.zeros(4)
    logits[env.truth - 1] = 1.0
    _, reward, terminated, truncated, info = env.step({"action": 5, "prediction": logits})
    assert terminated and not truncated and info["correct"] and reward == 1.0
    assert info["touches_after_baseline"] == -4 and info["prediction"]["target"] == env.truth - 1


def test_engine_agent_is_seeded_and_stops(tmp_path):
    env = TouchEnv(_library(tmp_path), comparisons=4, budget=6)
    make = lambda: EngineAgent(4, preset("default"), "infogain", 0.9, 6)   # noqa: E731
    a, b = run_episode(env, make(), 5), run_episode(env, make(), 5)
    assert a == b and 0 <= a["touches_after_baseline"] <= 6
    assert not a["truncated"]                                    # the agent STOPs itself
    out = evaluate(env, {"default": make}, parse_seeds("0-2,5"))["default"]
    assert [e["seed"] for e in out["episodes"]] == [0, 1, 2, 5]
    assert out["accuracy"] == np.mean([e["correct"] for e in out["episodes"]])


def test_parse_seeds_and_bad_settings(tmp_path):
    assert parse_seeds("0-3,7") == [0, 1, 2, 3, 7]
    for bad in ("3-1", "a", "-1", ""):
        with pytest.raises(InputError):
            parse_seeds(bad)
    with pytest.raises(InputError):
        TouchEnv(_library(tmp_path, classes=3), comparisons=4)
