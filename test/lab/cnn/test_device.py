"""``learner.device``: the form checked by the product, the device checked by the lab before the
trial, checkpoints that move between devices, and (``gpu`` mark, on a CUDA machine) the GPU
path against the CPU."""

from __future__ import annotations

import json

import numpy as np
import pytest
import torch

from tactex_lab.cnn import device as device_mod
from tactex_lab.cnn.learner import OnlineLearner
from tactex_ros.cli.main import main
from tactex_ros.core.config import (AutoSettings, CnnSettings, LadderSettings, preset,
                                    trial_preset)
from tactex_ros.core.engine import TrialEngine
from tactex_ros.core.errors import InputError
from stripes import stripe_frames

FAST = dict(input_size=48, steps=3, batch_size=8, mc_passes=6, augment=2)


def _frame(frames: list[np.ndarray], k: int, rng: np.random.Generator) -> np.ndarray:
    """A touch of stripe class ``k``: its frame plus a little noise."""
    noise = rng.integers(-6, 7, (240, 320, 3))
    return np.clip(frames[k].astype(int) + noise, 0, 255).astype(np.uint8)


@pytest.fixture
def no_cuda(monkeypatch):
    """torch reports no CUDA (as on this CPU wheel), whatever the machine has."""
    monkeypatch.setattr(torch.cuda, "is_available", lambda: False)
    monkeypatch.setattr(torch.cuda, "device_count", lambda: 0)


@pytest.mark.parametrize("text", ["cpu", "cuda", "cuda:0", "cuda:12", "auto"])
def test_device_forms_accepted(text):
    assert CnnSettings(device=text).device == text
    assert AutoSettings(device=text).device == text
    assert LadderSettings(device=text).device == text       # the ladder's CNN rung


@pytest.mark.parametrize("text", ["gpu", "cuda:", "cuda:x", "CUDA", "cuda0", "mps", ""])
def test_device_other_forms_refused_naming_the_field(text):
    with pytest.raises(InputError, match=r"device.*cpu\|cuda\|cuda:\[0-9\]\+\|auto"):
        CnnSettings(device=text)


@pytest.mark.parametrize("text", ["cuda", "cuda:0", "cuda:3"])
def test_absent_cuda_refused_before_the_trial(no_cuda, text):
    cfg = preset("cnn", device=text, **FAST)
    with pytest.raises(InputError) as err:
        TrialEngine(4, cfg, trial_preset("cnn", rounds=2), seed=0)
    msg = str(err.value)
    assert repr(text) in msg and "torch.cuda.is_available() = False" in msg
    assert "0 CUDA device(s)" in msg


def test_cuda_index_beyond_the_count_refused(monkeypatch):
    monkeypatch.setattr(torch.cuda, "is_available", lambda: True)
    monkeypatch.setattr(torch.cuda, "device_count", lambda: 1)
    with pytest.raises(InputError, match=r"'cuda:1'.*1 CUDA device"):
        device_mod.resolve_device("cuda:1")


def test_trial_command_refuses_absent_gpu_with_status_2(no_cuda, tmp_path, capsys):
    out = tmp_path / "t.json"
    rc = main(["trial", "--source", "sim:0.5", "--config", "cnn", "--device", "cuda",
               "--rounds", "1", "--json", str(out), "--quiet"])
    assert rc == 2 and not out.exists()
    assert "torch.cuda.is_available() = False" in capsys.readouterr().err


def test_auto_without_cuda_runs_on_the_cpu_as_cpu_does(no_cuda, capsys):
    """'auto' falls back to the CPU (a console line says so) and gives the CPU's numbers."""
    device_mod._SAID.clear()
    frames = stripe_frames(1, 4)

    def run(dev: str) -> list:
        rng = np.random.default_rng(0)
        eng = TrialEngine(4, preset("cnn", device=dev, **FAST),
                          trial_preset("cnn", strategy="variance", rounds=2), seed=5)
        eng.add_touch(0, _frame(frames, 2, rng))
        for c in range(4):
            eng.add_touch(c + 1, _frame(frames, c, rng))
        rec = eng.decide()
        return [rec.platform, list(rec.probs)]

    auto = run("auto")
    assert device_mod.resolve_device("auto").type == "cpu"
    assert "cpu" in capsys.readouterr().err.lower()
    assert auto == run("cpu")


def _trained(dev: str = "cpu", seed: int = 2, **over) -> tuple[OnlineLearner, list]:
    frames = stripe_frames(2, 4)
    lr = _again(dev, frames, seed, **over)
    lr.train_round()
    return lr, frames


def _again(dev: str, frames, seed: int = 2, **over) -> OnlineLearner:
    """A learner on ``dev`` with the same touches (views and reference) as ``_trained``."""
    rng = np.random.default_rng(seed)
    lr = OnlineLearner(4, preset("cnn", device=dev, **{**FAST, **over}), seed=seed)
    for c in range(4):
        lr.add_touch(_frame(frames, c, rng), c)
    lr.add_reference(_frame(frames, 1, rng))
    return lr


def test_checkpoint_loads_under_another_device_setting():
    """The device is not part of a state's identity: a state saved with 'cpu' continues under
    'auto' (here the CPU) exactly as the uninterrupted learner."""
    a, frames = _trained("cpu")
    data = a.save_state()
    b = _again("auto", frames)
    b.load_state(data)
    a.train_round()
    b.train_round()
    np.testing.assert_array_equal(a.reference_probs(), b.reference_probs())


def test_checkpoint_bytes_hold_cpu_tensors_only():
    a, _ = _trained("cpu", uncertainty="laplace")
    st = torch.load(__import__("io").BytesIO(a.save_state()), weights_only=True)
    tensors = [v for v in _leaves(st) if isinstance(v, torch.Tensor)]
    assert tensors and all(t.device.type == "cpu" for t in tensors)


def _leaves(obj):
    if isinstance(obj, dict):
        for v in obj.values():
            yield from _leaves(v)
    elif isinstance(obj, (list, tuple)):
        for v in obj:
            yield from _leaves(v)
    else:
        yield obj


def test_to_cpu_keeps_structure():
    obj = {"a": torch.ones(2), "b": [torch.zeros(1), 3], "c": (torch.ones(1), "x")}
    out = device_mod.to_cpu(obj)
    assert out["b"][1] == 3 and out["c"][1] == "x" and torch.equal(out["a"], obj["a"])


def test_cnn_auto_stage_learners_take_the_device(no_cuda):
    from tactex_ros.core.build import make_learner
    lr = make_learner(4, AutoSettings(device="auto", input_size=48, steps=2, augment=2))
    assert lr.inner.device.type == "cpu" and lr.cfg.device == "auto"
    with pytest.raises(InputError, match="torch.cuda.is_available"):
        make_learner(4, AutoSettings(device="cuda", input_size=48))


def test_ladder_cnn_rung_runs_with_the_ladder_device():
    from tactex_ros.core.build import make_learner
    lad = make_learner(4, LadderSettings(device="cuda:1", ladder="descriptor,cnn"), seed=0)
    assert lad.rung_config("cnn").device == "cuda:1"
    assert lad.rung_config("cnn@64").input_size == 64


def test_weights_inspect_maps_to_the_chosen_device(tmp_path, no_cuda, capsys):
    from tactex_lab.cnn.models import build_model
    m, _ = build_model("small_inception", 4)
    path = tmp_path / "w.pth"
    torch.save(m.state_dict(), path)
    out = tmp_path / "r.json"
    assert main(["weights", "inspect", str(path), "--model", "small_inception",
                 "--device", "auto", "--json", str(out)]) == 0
    assert json.loads(out.read_text())["loaded"] == len(m.state_dict()) - 2   # fc re-made
    assert main(["weights", "inspect", str(path), "--model", "small_inception",
                 "--device", "cuda"]) == 2
    assert "torch.cuda.is_available() = False" in capsys.readouterr().err


def test_bench_latency_cpu_side_by_side(capsys):
    """The bench with only the CPU: one column per configuration, train + score figures."""
    from tactex_lab.experiments.bench import latency
    out = latency.run(touch_counts=(5,), repeats=1,
                      configs=("small=cnn:learner.input_size=32,learner.steps=2", "default"))
    assert set(out["small"]) == {"5"} and out["small"]["5"] > 0
    assert out["train_s"]["small"]["5"] > 0 and out["score_s"]["small"]["5"] > 0


def test_bench_latency_refuses_absent_gpu(no_cuda):
    from tactex_lab.experiments.bench import latency
    with pytest.raises(InputError, match="--device 'cuda'"):
        latency.run(touch_counts=(3,), repeats=1, configs=("cnn",), devices=("cpu", "cuda"))


# ----------------------------------------------------------------------------- on a GPU
@pytest.mark.gpu
def test_gpu_checkpoint_moves_to_the_cpu_and_back():
    """Saved on the GPU, resumed on the CPU (and back): the same weights, so the same
    eval-mode predictions up to float rounding of the two devices."""
    g, frames = _trained("cuda")
    c = _again("cpu", frames)
    c.load_state(g.save_state())
    x = c._ref_parts[0]
    np.testing.assert_allclose(c.predict_proba(x), g.predict_proba(x), atol=1e-4)
    g2 = _again("cuda", frames)
    g2.load_state(c.save_state())
    np.testing.assert_allclose(g2.predict_proba(x), g.predict_proba(x), atol=1e-5)
    assert next(g2.model.parameters()).device.type == "cuda"
    g2.train_round()


@pytest.mark.gpu
def test_gpu_deterministic_repeats():
    """learner.deterministic (default): two seeded runs on the GPU give the same numbers."""
    a, _ = _trained("cuda", seed=4)
    b, _ = _trained("cuda", seed=4)
    np.testing.assert_array_equal(a.reference_probs(), b.reference_probs())


@pytest.mark.gpu
def test_gpu_trial_decides_like_the_cpu_in_distribution():
    """Over seeds the GPU's beliefs are close to the CPU's (same init, same minibatches; other
    dropout masks and float rounding)."""
    frames = stripe_frames(3, 4)
    gaps = []
    for seed in range(4):
        probs = {}
        for dev in ("cpu", "cuda"):
            rng = np.random.default_rng(seed)
            eng = TrialEngine(4, preset("cnn", device=dev, **FAST),
                              trial_preset("cnn", strategy="variance", rounds=2), seed=seed)
            eng.add_touch(0, _frame(frames, 2, rng))
            for c in range(4):
                eng.add_touch(c + 1, _frame(frames, c, rng))
            probs[dev] = np.asarray(eng.decide().probs)
        gaps.append(np.abs(probs["cpu"] - probs["cuda"]).max())
    assert float(np.median(gaps)) < 0.2


def test_launch_takes_the_learner_device_by_its_dotted_name():
    """``ros2 launch tactex explore.launch.py config:=seed_faithful learner.device:=cuda``: the
    explorer gets ``learner.device`` (its own parameter); a bad form is refused by name, as
    is the setting for a learner without a device."""
    import importlib.util
    from pathlib import Path
    path = Path(__file__).resolve().parents[3] / "launch" / "explore.launch.py"
    spec = importlib.util.spec_from_file_location("tactex_explore_launch_dev", path)
    launch = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(launch)
    p = launch.plan({"sim": "true", "config": "seed_faithful", "learner.device": "cuda:1"})
    ex = next(n for n in p["nodes"] if n.name == "explorer").parameters
    assert ex["learner"]["device"] == "cuda:1" and ex["config"] == "seed_faithful"
    with pytest.raises(launch.LaunchArgumentError, match="learner.device:='gpu'"):
        launch.plan({"sim": "true", "config": "seed_faithful", "learner.device": "gpu"})
    with pytest.raises(launch.LaunchArgumentError, match="device"):
        launch.plan({"sim": "true", "learner.device": "cuda"})     # the descriptor has none
