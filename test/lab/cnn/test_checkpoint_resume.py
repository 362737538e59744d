"""A CNN trial resumed from its learner checkpoint (written after each round into the record)
continues exactly as the uninterrupted trial: same next decision, same result, without
re-training the rounds before the checkpoint. A checkpoint that is corrupt, missing or does
not fit the record is not used: the resume re-trains on the recorded touches (same result)."""

from __future__ import annotations

import hashlib
import json
import shutil
from pathlib import Path

import numpy as np
import pytest

from tactex_ros.core.config import preset
from tactex_ros.core.engine import TrialEngine, trial_preset
from tactex_ros.core.errors import InputError
from tactex_ros.core.touch import Touch, as_touch
from tactex_ros.trial.record import CHECKPOINT, TrialRecord, read_checkpoint, read_record
from tactex_ros.trial.resume import load_replay, restore_engine
from tactex_ros.sources import open_source

IDS = ["reference", "c1", "c2", "c3", "c4"]
ROUNDS = 5


class Cut(Exception):
    """The process dies here."""


def _engine(seed: int = 3) -> TrialEngine:
    cfg = preset("cnn").replace(input_size=32, steps=3, mc_passes=6, augment=2)
    return TrialEngine(4, cfg, trial_preset("cnn", rounds=ROUNDS), seed=seed,
                       platform_ids=IDS)


def _spec(seed: int = 3):
    eng = _engine(seed)
    from tactex_ros.core.engine import TrialSpec
    return TrialSpec(4, eng.learner_cfg, eng.trial_cfg, seed=seed, platform_ids=tuple(IDS))


def _source():
    src = open_source("sim:0.5")
    comps = src.draw_scene(4, 3)
    return src.trial([comps[1]] + comps, 3)


def _presses(rec: TrialRecord, src_fn, cut_after: int | None = None, start: int = 0):
    """The explorer's press: the touch on disk before it is used; ``Cut`` after
    ``cut_after`` presses."""
    n = [start]

    def touch(platform: int) -> Touch:
        if cut_after is not None and n[0] >= cut_after:
            raise Cut()
        n[0] += 1
        img = as_touch(src_fn(platform)).frame
        rec.add_touch(img, {"platform_id": IDS[platform], "platform_index": platform,
                            "accepted": True})
        return Touch(frame=img)
    return touch


def _checkpointing(eng: TrialEngine, rec: TrialRecord, cut_round: int | None = None,
                   after=None):
    """``on_round`` as the explorer's: a checkpoint after each round (``Cut`` before the
    checkpoint of ``cut_round``)."""
    def on_round(r) -> None:
        if cut_round is not None and r.round == cut_round:
            raise Cut()
        ck = eng.checkpoint()
        if ck is not None:
            rec.write_checkpoint(*ck, after() if after else rec.n_touches)
    return on_round


def _run(tmp: Path, name: str, cut_after: int | None = None, cut_round: int | None = None):
    src_fn = _source()
    rec = TrialRecord(tmp, name)
    rec.save_inputs(None, {})
    eng = _engine()
    try:
        return eng.run(_presses(rec, src_fn, cut_after),
                       on_round=_checkpointing(eng, rec, cut_round))
    except Cut:
        return None


@pytest.fixture(scope="module")
def runs(tmp_path_factory) -> Path:
    """The uninterrupted trial ('full', its outcome) and two cut ones: while asking for touch
    8 ('cut7', checkpoint of round 3 over touches 1..7) and after touch 7 was written but
    before round 3's checkpoint ('cut_round3', checkpoint of round 2 over 1..6)."""
    tmp = tmp_path_factory.mktemp("runs")
    full = _run(tmp, "full")
    assert _run(tmp, "cut7", cut_after=7) is None
    assert _run(tmp, "cut_round3", cut_round=3) is None
    return tmp, full


def _copy(runs, name: str, tmp: Path) -> Path:
    shutil.copytree(runs[0] / name, tmp / name)
    return tmp / name


def _advanced_source(folder: Path):
    """The simulated presses after the ones on disk (the source draws in order)."""
    src_fn = _source()
    for t in read_record(folder, images=False)["touches"]:
        src_fn(int(t["platform_index"]))
    return src_fn


def _resume(tmp: Path, name: str, start: int):
    src_fn = _advanced_source(tmp / name)
    rec = TrialRecord(tmp, name, resume=True)
    replay, _ = load_replay(tmp / name, _presses(rec, src_fn, start=start), IDS)
    eng, after, how = restore_engine(_spec(), tmp / name, replay.recorded)
    replay.recorded = [r for r in replay.recorded if r.seq > after]
    trained = []
    inner = eng.learner.train_round

    def counted():
        trained.append(1)
        return inner()
    eng.learner.train_round = counted
    out = eng.run(replay, on_round=_checkpointing(eng, rec))
    return out, after, how, len(trained)


def _same(a, b) -> None:
    da, db = a.to_dict(), b.to_dict()
    for d in (da, db):
        for r in d["rounds"] + [d["final"]]:
            for k in ("train_s", "score_s", "choose_s", "decision_s", "cpu_s"):
                r.pop(k, None)
                (r.get("detail") or {}).pop(k, None)
    assert json.dumps(db, sort_keys=True) == json.dumps(da, sort_keys=True)


@pytest.mark.slow
def test_resume_from_checkpoint_equals_uninterrupted(runs, tmp_path: Path) -> None:
    full = runs[1]
    assert full is not None and len(full.rounds) == ROUNDS
    d = _copy(runs, "cut7", tmp_path)
    state, after, blob = read_checkpoint(d)
    assert state["round"] == 3 and after == 7 and len(blob) > 1000
    assert [f.name for f in d.glob("learner_*.state")] == ["learner_0003.state"]  # older gone
    res, after, how, trained = _resume(tmp_path, "cut7", start=7)
    assert after == 7 and "round 3" in how
    assert trained == ROUNDS + 1 - 3                 # rounds 4, 5 and the final decision only
    _same(full, res)
    # the first decision after the resume is the uninterrupted run's round 4
    assert res.rounds[3].platform == full.rounds[3].platform
    assert res.rounds[3].probs == full.rounds[3].probs


@pytest.mark.slow
def test_touches_after_the_checkpoint_are_replayed(runs, tmp_path: Path) -> None:
    """Cut after touch 7 is on disk but before round 3's checkpoint: round 2's checkpoint
    (touches 1..6) is restored and touch 7 replayed from the record."""
    d = _copy(runs, "cut_round3", tmp_path)
    assert read_checkpoint(d)[1] == 6
    assert len(read_record(d, images=False)["touches"]) == 7
    res, after, how, trained = _resume(tmp_path, "cut_round3", start=7)
    assert after == 6 and trained == ROUNDS + 1 - 2
    _same(runs[1], res)


def _corrupt(d: Path) -> None:
    f = next(d.glob("learner_*.state"))
    data = bytearray(f.read_bytes())
    data[len(data) // 2] ^= 0xFF
    f.write_bytes(bytes(data))


def _torn(d: Path) -> None:
    (d / CHECKPOINT).write_text((d / CHECKPOINT).read_text()[:40])


def _missing(d: Path) -> None:
    next(d.glob("learner_*.state")).unlink()


def _other_touches(d: Path) -> None:
    """A checkpoint that claims more comparison touches than the record holds."""
    head = json.loads((d / CHECKPOINT).read_text())
    head["state"]["touches"][0] += 1
    (d / CHECKPOINT).write_text(json.dumps(head))


def _other_learner(d: Path) -> None:
    """A whole, consistent checkpoint whose learner bytes are another seed's learner."""
    blob = _engine(seed=4).learner.save_state()
    head = json.loads((d / CHECKPOINT).read_text())
    (d / head["learner_file"]).write_bytes(blob)
    head.update(learner_bytes=len(blob), learner_sha256=hashlib.sha256(blob).hexdigest())
    (d / CHECKPOINT).write_text(json.dumps(head))


def _state(**damage):
    """A checkpoint whose engine state has a damaged field (wrong type or missing)."""
    def spoil(d: Path) -> None:
        head = json.loads((d / CHECKPOINT).read_text())
        for k, v in damage.items():
            if v is None:
                del head["state"][k]
            else:
                head["state"][k] = v
        (d / CHECKPOINT).write_text(json.dumps(head))
    return spoil


@pytest.mark.slow
@pytest.mark.parametrize("spoil,why", [(_corrupt, "SHA-256"), (_torn, "unreadable"),
                                       (_state(rng="x"), "does not fit"),
                                       (_state(failed=None), "does not fit"),
                                       (_state(records="abc"), "does not fit"),
                                       (_missing, "cannot be read"),
                                       (_other_touches, "does not fit"),
                                       (_other_learner, "another model, setting or seed"),
                                       (lambda d: (d / CHECKPOINT).unlink(), "no learner")])
def test_unusable_checkpoint_falls_back_to_retraining(runs, tmp_path: Path, spoil,
                                                      why) -> None:
    spoil(_copy(runs, "cut7", tmp_path))
    res, after, how, trained = _resume(tmp_path, "cut7", start=7)
    assert after == 0 and why in how
    assert trained == ROUNDS + 1                     # every round trained again
    _same(runs[1], res)


def test_restore_refuses_a_used_engine_and_other_versions() -> None:
    eng = _engine()
    with pytest.raises(InputError, match="version"):
        eng.restore({"version": 99}, [], b"")
    frame = np.full((240, 320, 3), 120, np.uint8)
    frame[::8] = 30
    eng.add_touch(0, frame)
    with pytest.raises(Exception, match="fresh engine"):
        eng.restore({"version": 1}, [], b"")


@pytest.mark.slow
def test_auto_model_resumes_on_its_escalated_stage(tmp_path: Path, monkeypatch) -> None:
    """Model ``cnn_auto`` escalated before the cut: its checkpoint restores the second
    stage."""
    cfg = preset("cnn", model="cnn_auto", auto_ladder="small_inception@32,small_inception@40",
                 steps=2, mc_passes=4, augment=2, auto_window=1, auto_heldout_acc=1.0,
                 auto_catchup=1)

    def engine(seed: int = 3) -> TrialEngine:
        return TrialEngine(4, cfg, trial_preset("cnn", rounds=ROUNDS), seed=seed,
                           platform_ids=IDS)
    monkeypatch.setitem(globals(), "_engine", engine)
    full = _run(tmp_path, "full")
    assert _run(tmp_path, "cut7", cut_after=7) is None
    state, _, blob = read_checkpoint(tmp_path / "cut7")
    res, after, how, trained = _resume(tmp_path, "cut7", start=7)
    assert after == 7 and "round 3" in how
    assert any(r.detail.escalation for r in full.rounds[:3])   # escalated before the cut
    _same(full, res)
