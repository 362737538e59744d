"""``TouchEnv`` on a small library of recorded presses (image files): the spaces hold every
observation, STOP ends the episode scored on its prediction, the budget truncates, bad actions
are refused, the same seed gives the same episode, and tactex's engine plays it as an agent.
Gymnasium's own checker passes, observations are the caller's to change, and the ap_gym
interface (prediction space, target, loss) holds; ap_gym's random agent plays an episode where
ap_gym is installed."""

from pathlib import Path

import cv2
import numpy as np
import pytest

gym = pytest.importorskip("gymnasium")

from tactex_ros.core.config import preset  # noqa: E402
from tactex_ros.core.errors import InputError  # noqa: E402
from tactex_lab.env.agents import EngineAgent, evaluate, run_episode  # noqa: E402
from tactex_lab.env.touch_env import TouchEnv, parse_seeds, scene_of  # noqa: E402


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
        logits = rng.normal(size=4)
        obs, reward, terminated, truncated, info = env.step(
            {"action": int(rng.integers(0, 5)), "prediction": logits})
        n += 1
        loss = -np.log(np.exp(logits[env.truth - 1]) / np.exp(logits).sum()) / np.log(4)
        assert info["prediction"]["loss"] == pytest.approx(loss, rel=1e-12)
        assert reward == pytest.approx(info["base_reward"] - loss, rel=1e-12)
        if terminated or truncated:
            break
        assert env.observation_space.contains(obs) and info["base_reward"] == -0.01
    assert truncated and not terminated and info["presses"] == 7 and n == 7
    assert info["touches_after_baseline"] == 2 and info["base_reward"] == float(info["correct"])
    with pytest.raises(InputError):
        env.step({"action": 5, "prediction": np.zeros(4)})       # over: reset first
    env.reset(seed=3)
    with pytest.raises(InputError):
        env.step({"action": 6, "prediction": np.zeros(4)})       # 0..4 press, 5 = STOP
    logits = np.zeros(4)
    logits[env.truth - 1] = 1.0
    _, reward, terminated, truncated, info = env.step({"action": 5, "prediction": logits})
    assert terminated and not truncated and info["correct"] and info["base_reward"] == 1.0
    # the right match at 1 against 0: cross-entropy log(1 + 3/e) over log 4
    assert info["prediction"]["loss"] == pytest.approx(np.log1p(3 / np.e) / np.log(4))
    assert reward == pytest.approx(1.0 - np.log1p(3 / np.e) / np.log(4))
    assert info["touches_after_baseline"] == -4 and info["prediction"]["target"] == env.truth - 1


def test_engine_agent_is_seeded_and_stops(tmp_path):
    env = TouchEnv(_library(tmp_path), comparisons=4, budget=6)
    make = lambda: EngineAgent(4, preset("default"), "infogain", 0.9, 6)   # noqa: E731
    a, b = run_episode(env, make(), 5), run_episode(env, make(), 5)
    assert a == b and 0 <= a["touches_after_baseline"] <= 6
    assert not a["truncated"]                                    # the agent STOPs itself
    assert a["reward"] == float(a["correct"])                    # no touch cost here
    envs = []

    def make_env():
        envs.append(TouchEnv(env.source_spec, comparisons=4, budget=6))
        return envs[-1]
    out = evaluate(make_env, {"default": make, "again": make}, parse_seeds("0-2,5"))
    assert len(envs) == 2 and envs[0] is not envs[1]           # an environment per agent
    assert out["default"]["episodes"] == out["again"]["episodes"]
    out = out["default"]
    assert [e["seed"] for e in out["episodes"]] == [0, 1, 2, 5]
    assert out["accuracy"] == np.mean([e["correct"] for e in out["episodes"]])


@pytest.mark.parametrize("which", ["replay", "sim"])
def test_observations_are_copies_and_gymnasiums_checker_passes(tmp_path, which):
    from gymnasium.utils.env_checker import check_env
    env = TouchEnv(_library(tmp_path) if which == "replay" else "sim", comparisons=4, budget=2)
    first, _ = env.reset(seed=1)
    kept = {k: np.copy(first[k]) for k in ("image", "no_contact", "extra")}
    # the image files have no no-contact frame; the simulator's presses have one
    assert kept["image"].any() and kept["no_contact"].any() == (which == "sim")
    for k in kept:
        first[k][:] = 0
    again, _ = env.reset(seed=1)
    for k, v in kept.items():
        assert np.array_equal(again[k], v), k
    nxt, *_ = env.step({"action": 0, "prediction": np.zeros(4)})   # the reference again
    nxt["image"][:] = 0
    again, _ = env.reset(seed=1)
    assert np.array_equal(again["image"], kept["image"])
    check_env(env, skip_render_check=True)


def test_the_active_perception_interface(tmp_path):
    env = TouchEnv(_library(tmp_path), comparisons=4, budget=2)
    assert env.action_space["action"] is env.inner_action_space
    assert env.action_space["prediction"] is env.prediction_space
    assert env.inner_action_space.n == 6 and env.prediction_space.shape == (4,)
    assert env.prediction_target_space == gym.spaces.Discrete(4)
    _, info = env.reset(seed=2)
    assert info["prediction"]["target"] == env.truth - 1
    assert env.prediction_target_space.contains(info["prediction"]["target"])
    # the loss: 1 for a uniform guess, 0 in the limit of certainty on the match
    assert env.loss_fn.numpy(np.zeros(4), np.int64(1)) == pytest.approx(1.0)
    sure = np.full(4, -50.0)
    sure[1] = 50.0
    assert env.loss_fn.numpy(sure, np.int64(1)) == pytest.approx(0.0, abs=1e-12)
    with pytest.raises(InputError):                              # C logits, not C + 1
        env.step({"action": 1, "prediction": np.zeros(5)})


def test_the_loss_without_ap_gym_is_ap_gyms():
    ap_gym = pytest.importorskip("ap_gym", reason="ap_gym not installed (requirements-test.txt)")
    from tactex_lab.env.touch_env import CrossEntropyLoss
    rng = np.random.default_rng(1)
    logits, target = rng.normal(size=(50, 4)) * 3, rng.integers(0, 4, 50)
    ours = CrossEntropyLoss(4).numpy(logits, target)
    theirs = ap_gym.CrossEntropyLossFn(num_classes=4).normalized.numpy(logits, target, (50,))
    assert np.allclose(ours, theirs, rtol=1e-12)


def test_ap_gyms_random_agent_plays_an_episode(tmp_path):
    ap_gym = pytest.importorskip("ap_gym", reason="ap_gym not installed (requirements-test.txt)")
    raw = TouchEnv(_library(tmp_path), comparisons=4, budget=3)
    assert ap_gym.ensure_active_perception_env(raw) is raw       # no pseudo-task wrapper
    env = ap_gym.ActiveClassificationLogWrapper(raw)
    env.action_space.seed(0)
    obs, info = env.reset(seed=4)
    steps = 0
    while True:        # ap_gym's random agent (its examples): a random action and prediction
        action = {"action": env.inner_action_space.sample(),
                  "prediction": env.prediction_space.sample()}
        obs, reward, terminated, truncated, info = env.step(action)
        steps += 1
        loss = env.loss_fn.numpy(action["prediction"], info["prediction"]["target"])
        assert reward == pytest.approx(info["base_reward"] - loss)
        if terminated or truncated:
            break
    assert 1 <= steps <= raw.max_presses
    assert info["presses"] <= raw.max_presses and info["truth"] - 1 == raw.truth - 1
    assert "stats" in info                                       # the log wrapper's episode


def test_parse_seeds_and_bad_settings(tmp_path):
    assert parse_seeds("0-3,7") == [0, 1, 2, 3, 7]
    for bad in ("3-1", "a", "-1", ""):
        with pytest.raises(InputError):
            parse_seeds(bad)
    with pytest.raises(InputError):
        TouchEnv(_library(tmp_path, classes=3), comparisons=4)
