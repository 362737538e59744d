"""``TrialRun`` without ROS: a fake press (the simulator) drives a trial to its record and
result; a trial cut off mid-way (a press that never ends, a process that dies) and resumed from
its record ends with the outcome and record of the uninterrupted one."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from tactex_ros.core.config import preset
from tactex_ros.core.engine import TouchFailed, TrialSpec, trial_preset
from tactex_ros.core.errors import InputError
from tactex_ros.core.touch import Touch, as_touch
from tactex_ros.sources import open_source
from tactex_ros.trial.record import read_record, read_result
from tactex_ros.trial.run import TouchInterrupted, TrialRun

IDS = ("reference", "c1", "c2", "c3", "c4")
FAIL_AT = 7            # the 7th press fails (a motion node's failed press: not retried)
SEED = 3


class Cut(Exception):
    """The process dies here."""


def _spec(**trial) -> TrialSpec:
    return TrialSpec(4, preset("default"),
                     trial_preset("default", **{"rounds": 6, "stop_confidence": 0.0, **trial}),
                     seed=SEED, platform_ids=IDS)


def _inputs(spec: TrialSpec) -> dict:
    return {"explorer": {"seed": spec.seed}, "learner": spec.learner.model_dump(),
            "trial": spec.trial.model_dump()}


class FakePress:
    """Presses the simulator's platforms; press ``FAIL_AT`` fails; after ``cut`` presses the
    next one ends as ``how`` says ('interrupted': the press server is gone; 'died': the
    process dies without a word)."""

    def __init__(self, cut: int | None = None, how: str = "died") -> None:
        src = open_source("sim:0.5")
        comps = src.draw_scene(4, 3)
        self.fn = src.trial([comps[1]] + comps, 3)
        self.nc = np.random.default_rng(0).integers(60, 120, (240, 320, 3)).astype(np.uint8)
        self.n, self.cut, self.how = 0, cut, how

    def __call__(self, platform: int, meta: dict) -> Touch:
        if self.cut is not None and self.n >= self.cut:
            if self.how == "interrupted":
                raise TouchInterrupted("the press server left the ROS graph")
            raise Cut()
        self.n += 1
        meta["attempts"] = 1
        if self.n == FAIL_AT:
            raise TouchFailed("no contact", retry=False)
        return Touch(frame=as_touch(self.fn(platform)).frame, no_contact=self.nc)


def _outcome(res: dict) -> str:
    out = {k: v for k, v in res.items() if k not in ("elapsed_s", "record", "trial_id",
                                                    "resumed")}
    for r in out["rounds"] + [out["final"]]:
        for k in ("train_s", "score_s", "choose_s", "decision_s", "cpu_s", "grad_norm"):
            r.pop(k, None)
    return json.dumps(out, sort_keys=True)


def _decisions(folder: Path) -> list[dict]:
    return [{k: v for k, v in d.items() if k not in ("decision_s", "time")}   # wall-clock
            for d in read_record(folder, images=False)["decisions"]]


def test_a_trial_runs_to_its_record_and_result(tmp_path: Path) -> None:
    spec = _spec()
    seen = []
    run = TrialRun(spec, tmp_path, "t", press=FakePress(), inputs=_inputs(spec))
    res = run.run(on_decision=lambda rec, line: seen.append(line))
    assert res == read_result(tmp_path / "t") and res["trial_id"] == "t"
    rec = read_record(tmp_path / "t", images=False)
    assert len(rec["touches"]) == res["touches"] + 1            # + the failed one
    failed = [t for t in rec["touches"] if not t["accepted"]]
    assert [t["seq"] for t in failed] == [FAIL_AT] and failed[0]["reason"] == "no contact"
    assert failed[0]["attempts"] == 1 and failed[0]["platform_id"] in IDS
    assert len(rec["decisions"]) == len(seen) == len(res["rounds"]) + 1
    assert rec["decisions"][-1]["done"] and rec["decisions"][-1]["prediction"] == \
        res["prediction"]
    assert (tmp_path / "t" / "report.html").is_file()
    assert json.loads((tmp_path / "t" / "config.json").read_text()) == \
        json.loads(json.dumps(_inputs(spec)))


@pytest.mark.slow
@pytest.mark.parametrize("cut,how", [(3, "died"), (8, "interrupted"), (10, "died")])
def test_a_resumed_trial_ends_as_the_uninterrupted_one(tmp_path: Path, cut: int,
                                                        how: str) -> None:
    spec = _spec()
    full = TrialRun(spec, tmp_path, "full", press=FakePress(), inputs=_inputs(spec)).run()
    press = FakePress(cut=cut, how=how)
    part = TrialRun(spec, tmp_path, "cut", press=press, inputs=_inputs(spec))
    with pytest.raises(Cut if how == "died" else TouchInterrupted):
        part.run()
    lines = read_record(tmp_path / "cut", images=False)["touches"]
    assert len(lines) == cut + (how == "interrupted")          # every press made is on disk
    assert lines[-1].get("interrupted", False) == (how == "interrupted")

    press.cut = None                    # the same platforms go on giving the same frames
    again = TrialRun(spec, tmp_path, "", press=press, inputs=_inputs(spec),
                     resume=tmp_path / "cut")
    res = again.run()
    assert _outcome(res) == _outcome(full)
    assert len(res["resumed"]) == 1
    # the record holds the uninterrupted trial's touches and each decision once
    a = [t for t in read_record(tmp_path / "full")["touches"]]
    b = [t for t in read_record(tmp_path / "cut")["touches"] if not t.get("interrupted")]
    assert [t["platform_id"] for t in b] == [t["platform_id"] for t in a]
    for x, y in zip(a, b, strict=True):
        assert (x.get("array") is None) == (y.get("array") is None)
        if x.get("array") is not None:
            assert np.array_equal(x["array"], y["array"])
    assert _decisions(tmp_path / "cut") == _decisions(tmp_path / "full")
    events = read_record(tmp_path / "cut", images=False)["events"]
    assert not [e for e in events if e.get("event") == "replay_differs"]


def test_a_resume_with_other_settings_is_refused_before_a_touch(tmp_path: Path) -> None:
    spec = _spec()
    part = TrialRun(spec, tmp_path, "cut", press=FakePress(cut=4), inputs=_inputs(spec))
    with pytest.raises(Cut):
        part.run()
    other = _spec(rounds=7)
    pressed = []
    with pytest.raises(InputError, match="trial.rounds is 7 now but 6"):
        TrialRun(other, tmp_path, "", press=lambda p, m: pressed.append(p),
                 inputs=_inputs(other), resume=tmp_path / "cut")
    assert pressed == []


def test_a_failed_trial_records_its_error(tmp_path: Path) -> None:
    spec = _spec()
    run = TrialRun(spec, tmp_path, "t", press=FakePress(cut=2, how="interrupted"),
                   inputs=_inputs(spec))
    with pytest.raises(TouchInterrupted) as err:
        run.run()
    res = run.fail(err.value)
    assert res == read_result(tmp_path / "t")
    assert res["error"].startswith("TouchInterrupted")
