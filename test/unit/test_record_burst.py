"""A touch's burst of in-contact frames in the trial record: written lossless beside the
strongest frame, read back byte for byte, handed to a resumed trial; a record made before the
burst was kept (no ``extra``) still loads and resumes."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from tactex_ros.core.config import preset
from tactex_ros.core.engine import TrialSpec, trial_preset
from tactex_ros.core.errors import InputError
from tactex_ros.core.touch import Touch
from tactex_ros.sources import open_source
from tactex_ros.trial.record import TrialRecord, check_resumable, read_record
from tactex_ros.trial.resume import recorded_touches
from tactex_ros.trial.run import TrialRun

IDS = ("reference", "c1", "c2", "c3")


def _frames(k: int, seed: int = 0) -> np.ndarray:
    return np.random.default_rng(seed).integers(0, 256, (k, 240, 320, 3), dtype=np.uint8)


@pytest.mark.parametrize("k", [1, 3, 15])
def test_k_frames_round_trip_byte_identical(tmp_path: Path, k: int) -> None:
    rec = TrialRecord(tmp_path, "t")
    frames, nc = _frames(k + 1), _frames(1, 1)[0]
    rec.add_touch(frames[0], {"platform_id": "c2", "platform_index": 2, "accepted": True},
                  no_contact=nc, extra=frames[1:])
    line = read_record(tmp_path / "t")["touches"][0]
    assert line["extra"] == [f"extra_0001_c2_{i}.png" for i in range(1, k + 1)]
    got = recorded_touches(read_record(tmp_path / "t"))[0].touch
    assert got.frame.tobytes() == frames[0].tobytes()
    assert got.extra.shape == (k, 240, 320, 3) and got.extra.tobytes() == frames[1:].tobytes()
    assert got.no_contact.tobytes() == nc.tobytes()


def test_a_missing_extra_frame_refuses_the_resume(tmp_path: Path) -> None:
    rec = TrialRecord(tmp_path, "t")
    rec.save_inputs(None, {})
    f = _frames(3)
    rec.add_touch(f[0], {"platform_id": "c1", "platform_index": 1, "accepted": True},
                  extra=f[1:])
    (tmp_path / "t" / "extra_0001_c1_2.png").unlink()
    with pytest.raises(InputError, match="extra_0001_c1_2.png"):
        check_resumable(tmp_path / "t")
    with pytest.raises(InputError, match="extra frame"):
        recorded_touches(read_record(tmp_path / "t"))


class Cut(Exception):
    """The process dies here."""


class BurstPress:
    """The simulator's presses as the explorer hands them over: the strongest frame and
    ``extra`` more of the same press (each rendered at its own depth); ``cut``: the process
    dies before that press."""

    def __init__(self, extra: int, cut: int | None = None) -> None:
        src = open_source("sim:0.5")
        comps = src.draw_scene(3, 5)
        self.classes = [comps[0]] + comps
        self.src, self.extra, self.cut, self.n = src, extra, cut, 0
        self.rng = np.random.default_rng(7)
        self.nc = src.no_contact(5)

    def __call__(self, platform: int, meta: dict) -> Touch:
        if self.cut is not None and self.n >= self.cut:
            raise Cut()
        self.n += 1
        name = self.classes[platform]
        seed = int(self.rng.integers(1 << 30))
        frames = [self.src.press(name, np.random.default_rng(seed), depth_mm=0.4 + 0.05 * j)
                  for j in range(1 + self.extra)]
        return Touch(frame=frames[0], no_contact=self.nc,
                     extra=np.stack(frames[1:]) if self.extra else None)


def _spec(frames: int) -> TrialSpec:
    return TrialSpec(3, preset("default", descriptor_frames=frames),
                     trial_preset("default", rounds=4, stop_confidence=0.0), seed=1,
                     platform_ids=IDS)


def _inputs(spec: TrialSpec) -> dict:
    return {"explorer": {"seed": spec.seed}, "learner": spec.learner.model_dump(),
            "trial": spec.trial.model_dump()}


def _beliefs(folder: Path) -> list[list[float]]:
    return [d["belief"] for d in read_record(folder, images=False)["decisions"]]


@pytest.mark.parametrize("extra, frames", [(3, 4), (0, 4)])
def test_a_resumed_trial_replays_its_burst(tmp_path: Path, extra: int, frames: int) -> None:
    """extra 3: the recorded bursts are replayed (without them the beliefs would differ);
    extra 0: a record made before bursts were kept (no ``extra`` field) resumes as it ran."""
    spec = _spec(frames)
    full = TrialRun(spec, tmp_path, "full", press=BurstPress(extra), inputs=_inputs(spec)).run()
    press = BurstPress(extra, cut=5)
    with pytest.raises(Cut):
        TrialRun(spec, tmp_path, "cut", press=press, inputs=_inputs(spec)).run()
    lines = read_record(tmp_path / "cut", images=False)["touches"]
    assert [len(t.get("extra", [])) for t in lines] == [extra] * 5
    assert all("extra" not in t for t in lines) == (extra == 0)
    press.cut = None
    res = TrialRun(spec, tmp_path, "", press=press, inputs=_inputs(spec),
                   resume=tmp_path / "cut").run()
    assert res["prediction"] == full["prediction"] and res["touches"] == full["touches"]
    np.testing.assert_allclose(_beliefs(tmp_path / "cut"), _beliefs(tmp_path / "full"),
                               atol=1e-9, rtol=0)
    events = read_record(tmp_path / "cut", images=False)["events"]
    assert not [e for e in events if e.get("event") == "replay_differs"]
    assert json.loads((tmp_path / "cut" / "config.json").read_text())["learner"][
        "descriptor_frames"] == frames
