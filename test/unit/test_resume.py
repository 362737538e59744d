"""Resume from a trial record: a trial cut off after any touch and resumed from its record
gives exactly the result of the uninterrupted trial (same touches, decisions and prediction)."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from tactex_ros.core.config import preset
from tactex_ros.core.engine import TouchFailed, TrialEngine, trial_preset
from tactex_ros.core.errors import InputError
from tactex_ros.core.touch import Touch, as_touch
from tactex_ros.trial.record import TrialRecord, read_record
from tactex_ros.trial.resume import Replay, load_replay
from tactex_ros.sources import open_source

IDS = ["reference", "c1", "c2", "c3", "c4"]
FAIL_AT = 7          # the 7th press fails (as a motion node's failed press: not retried)


class Cut(Exception):
    """The process dies here."""


def _scene():
    src = open_source("sim:0.5")
    comps = src.draw_scene(4, 3)
    return src, [comps[1]] + comps


def _engine() -> TrialEngine:
    tcfg = trial_preset("default", rounds=6, stop_confidence=0.0)
    return TrialEngine(4, preset("default"), tcfg, seed=3, platform_ids=IDS)


def _recording(rec: TrialRecord, src_fn, no_contact: np.ndarray, start: int = 0,
               cut_after: int | None = None):
    """A press as the explorer makes it: the touch is written to the record before use."""
    n = [start]

    def touch(platform: int) -> Touch:
        if cut_after is not None and n[0] >= cut_after:
            raise Cut()
        n[0] += 1
        meta = {"platform_id": IDS[platform], "platform_index": platform}
        if n[0] == FAIL_AT:
            rec.add_touch(None, dict(meta, accepted=False, reason="no contact"))
            raise TouchFailed("no contact", retry=False)
        img = as_touch(src_fn(platform)).frame          # the simulator gives a Touch
        rec.add_touch(img, dict(meta, accepted=True), no_contact=no_contact)
        return Touch(frame=img, no_contact=no_contact)
    return touch


def _run(tmp: Path, trial_id: str, cut_after: int | None):
    src, classes = _scene()
    src_fn = src.trial(classes, 3)
    nc = np.random.default_rng(0).integers(60, 120, (240, 320, 3)).astype(np.uint8)
    rec = TrialRecord(tmp, trial_id)
    rec.save_inputs(None, {"trial": trial_id})
    eng = _engine()
    fn = _recording(rec, src_fn, nc, cut_after=cut_after)
    try:
        return eng.run(fn, on_rejected=lambda p, e: rec.reject_touch(rec.n_touches, str(e))), \
            src_fn, nc
    except Cut:
        return None, src_fn, nc


@pytest.mark.slow
@pytest.mark.parametrize("cut_after", [3, 5, 8, 10])
def test_resumed_trial_equals_uninterrupted(tmp_path: Path, cut_after: int) -> None:
    full, _, _ = _run(tmp_path, "full", None)
    assert full is not None and full.touches >= 5 + 5
    part, src_fn, nc = _run(tmp_path, "cut", cut_after)
    assert part is None
    on_disk = read_record(tmp_path / "cut")["touches"]
    assert len(on_disk) == cut_after                         # every touch made is on disk

    rec = TrialRecord(tmp_path, "cut", resume=True)
    assert rec.n_touches == cut_after
    live = _recording(rec, src_fn, nc, start=cut_after)
    replay, loaded = load_replay(tmp_path / "cut", live, IDS)
    assert len(replay.recorded) == cut_after
    res = _engine().run(replay, on_rejected=lambda p, e: None)
    a, b = full.to_dict(), res.to_dict()
    for d in (a, b):
        for r in d["rounds"] + [d["final"]]:
            for k in ("train_s", "score_s", "choose_s", "decision_s", "cpu_s", "grad_norm"):
                r.pop(k, None)
    assert json.dumps(b, sort_keys=True) == json.dumps(a, sort_keys=True)   # NaN == NaN here
    # the record now holds what the uninterrupted trial's record holds, touch for touch
    t_full = read_record(tmp_path / "full")["touches"]
    t_cut = read_record(tmp_path / "cut")["touches"]
    assert [t["platform_id"] for t in t_cut] == [t["platform_id"] for t in t_full]
    for x, y in zip(t_full, t_cut, strict=True):
        assert (x.get("array") is None) == (y.get("array") is None)
        if x.get("array") is not None:
            assert np.array_equal(x["array"], y["array"])
            assert np.array_equal(y["no_contact_array"], nc)
    assert len(list((tmp_path / "cut").glob("no_contact_*.png"))) <= 2   # written once per run


def test_replay_refuses_a_record_that_diverges(tmp_path: Path) -> None:
    _run(tmp_path, "cut", 5)
    lines = (tmp_path / "cut" / "touches.jsonl").read_text().splitlines()
    first = json.loads(lines[0])
    first.update(platform_index=2, platform_id="c2")
    lines[0] = json.dumps(first)
    (tmp_path / "cut" / "touches.jsonl").write_text("\n".join(lines) + "\n")
    replay, _ = load_replay(tmp_path / "cut", lambda p: None, IDS)
    with pytest.raises(InputError, match="diverges at touch 1"):
        _engine().run(replay)


def test_resume_refuses_finished_or_missing_records(tmp_path: Path) -> None:
    with pytest.raises(InputError, match="not a trial record"):
        TrialRecord(tmp_path, "nothing", resume=True)
    rec = TrialRecord(tmp_path, "done")
    rec.save_inputs(None, {})
    rec.finish({"prediction": "c1"})
    with pytest.raises(InputError, match="already has its result"):
        TrialRecord(tmp_path, "done", resume=True)
    rec.finish({"error": "press server gone"})           # a failed trial can be resumed
    assert TrialRecord(tmp_path, "done", resume=True).n_touches == 0
    rec = read_record(tmp_path / "done")              # its error kept, the result cleared
    assert rec["result"] is None
    assert rec["events"][-1]["result"] == {"error": "press server gone"}


def test_torn_lines_and_orphan_images_survive_a_resume(tmp_path: Path) -> None:
    rec = TrialRecord(tmp_path, "t")
    rec.save_inputs(None, {})
    img = np.zeros((240, 320, 3), np.uint8)
    rec.add_touch(img, {"platform_id": "reference", "platform_index": 0, "accepted": True})
    # a crash: the next image written, its line torn half-way
    (tmp_path / "t" / "touch_0002_c1.png").write_bytes(b"partial")
    with open(tmp_path / "t" / "touches.jsonl", "a") as f:
        f.write('{"platform_id": "c1", "platf')
    again = TrialRecord(tmp_path, "t", resume=True)
    assert again.n_touches == 2                     # the orphan image is never overwritten
    again.add_touch(img, {"platform_id": "c1", "platform_index": 1, "accepted": True})
    touches = read_record(tmp_path / "t")["touches"]
    assert [t["seq"] for t in touches] == [1, 3]
    assert (tmp_path / "t" / "touch_0002_c1.png").read_bytes() == b"partial"
    replay = Replay([], lambda p: "live", IDS)
    assert replay(1) == "live" and replay.current is None
