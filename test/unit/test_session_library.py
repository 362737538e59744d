"""The fabric library in a study session (trial/library.py, trial/session_run.py), without ROS:
a session trial (placement known) files its presses under their fabrics and the next trial's
belief asks the library; a trial without a placement leaves it as it was; every record says
whether the library was used and which state it saw."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from tactex_ros.core import library as flib
from tactex_ros.core.config import preset
from tactex_ros.core.engine import TrialSpec, trial_preset
from tactex_ros.core.touch import Touch, as_touch
from tactex_ros.sources import open_source
from tactex_ros.trial import session as sess
from tactex_ros.trial.library import LibraryKeeper
from tactex_ros.trial.record import read_record
from tactex_ros.trial.run import TrialRun
from tactex_ros.trial.session_run import SessionRun, trial_outcome

SHORT = Path(__file__).parents[1] / "data" / "session_short.yaml"
IDS = ["reference", "c1", "c2", "c3", "c4"]
NC = np.random.default_rng(0).integers(60, 120, (240, 320, 3)).astype(np.uint8)


class Operator:
    """Confirms every placement at once."""

    def expect(self, trial_id: str) -> None: ...
    def tell(self, text: str) -> None: ...
    def wait(self) -> tuple[str, str]: return ("auto_confirm", "test")
    def place(self, trial) -> None: ...


def _press(fabrics: list[str], seed: int):
    """The simulator's presses of ``fabrics`` (reference first) as a live press."""
    fn = open_source("sim:0.5").trial(fabrics, seed)

    def press(platform: int, meta: dict) -> Touch:
        meta["attempts"] = 1
        return Touch(frame=as_touch(fn(platform)).frame, no_contact=NC)
    return press


def _spec(seed: int, library) -> TrialSpec:
    return TrialSpec(4, preset("default"), trial_preset("default", rounds=2, stop_confidence=0),
                     seed=seed, platform_ids=tuple(IDS), library=library)


def _inputs(spec: TrialSpec) -> dict:
    return {"learner": spec.learner.model_dump(), "trial": spec.trial.model_dump()}


def test_session_trials_teach_the_library_and_the_record_says_what_they_saw(tmp_path):
    lib_path = tmp_path / flib.LIBRARY_FILE
    keeper = LibraryKeeper(lib_path, preset("default"))
    session = sess.load_session(SHORT, IDS, seed=3)
    run = SessionRun(session, tmp_path / "sess", {"seed": 3}, 1.0, library=keeper)
    seen: list[dict] = []

    def run_trial(trial: sess.SessionTrial, resume: str | None) -> dict:
        spec = _spec(trial.seed, run.current_library())
        seen.append(spec.library.state())
        tr = TrialRun(spec, run.dir, trial.record_name, inputs=_inputs(spec),
                      press=_press(list(trial.placement.values()), trial.seed))
        return tr.run(extra=lambda r: trial_outcome(trial, r))

    assert run.run(Operator(), run_trial, lambda: False) == 0
    lib = keeper.current()                       # the last trial's update, waited for
    # trial 1 saw the empty library; trial 2 the presses of trial 1, under its fabrics
    t1, t2 = session.trials
    n1 = sum(t["accepted"] for t in read_record(run.dir / t1.record_name, False)["touches"])
    n2 = sum(t["accepted"] for t in read_record(run.dir / t2.record_name, False)["touches"])
    assert seen[0]["presses"] == 0 and seen[1]["presses"] == n1 == 4 + 1 + 2
    assert seen[1]["fabrics"] == len(set(t1.placement.values())) == 4
    assert lib.presses == n1 + n2 and set(lib.fabrics) == (set(t1.placement.values())
                                                           | set(t2.placement.values()))
    # each press under the fabric its platform held
    rec = read_record(run.dir / t1.record_name, False)["touches"]
    sid = sess.load_started(run.dir)["session_id"]
    for t in rec:
        i = lib.sources.index(f"{sid}/{t1.id}/touch {t['seq']}")
        assert lib.names[i] == t1.placement[t["platform_id"]]
    # the file holds it; each record states the library it saw
    assert flib.load(lib_path).sha256() == lib.sha256()
    for t, state in zip(session.trials, seen, strict=True):
        res = json.loads((run.dir / t.record_name / "result.json").read_text())
        assert res["fabric_library"] == {"used": True, **state}
    # a session continued: the finished trials are filed once, not twice
    again = LibraryKeeper(lib_path, preset("default"))
    run2 = SessionRun(session, tmp_path / "sess", {"seed": 3}, 1.0, library=again)
    assert run2.run(Operator(), run_trial, lambda: False) == 0
    assert again.current().sha256() == lib.sha256()


def test_a_trial_without_a_placement_leaves_the_library_as_it_was(tmp_path):
    lib_path = tmp_path / flib.LIBRARY_FILE
    before = flib.FabricLibrary().add("denim", np.ones((2, 106)), ["x/1", "x/2"])
    flib.save(before, lib_path)
    data = lib_path.read_bytes()
    spec = _spec(5, None)                      # a single trial: no session, no placement
    tr = TrialRun(spec, tmp_path, "single", inputs=_inputs(spec),
                  press=_press(["denim", "linen", "denim", "cotton_lawn", "cotton_canvas"], 5))
    res = tr.run()
    assert res["fabric_library"] == {"used": False}
    assert lib_path.read_bytes() == data


def test_the_library_files_a_touch_with_its_further_frames(tmp_path):
    """With learner.descriptor_frames = 4 a filed press is described from its recorded burst,
    exactly as the trial's learner described it (not from its strongest frame alone)."""
    from tactex_ros.core.descriptor import raw_descriptor
    from tactex_ros.trial.library import trial_presses
    fabrics = ["denim", "linen", "denim", "cotton_lawn", "cotton_canvas"]
    fn = open_source("sim:0.5").trial(fabrics, 7)

    def press(platform: int, meta: dict) -> Touch:
        meta["attempts"] = 1
        frames = [as_touch(fn(platform)).frame for _ in range(4)]
        return Touch(frame=frames[0], no_contact=NC, extra=np.stack(frames[1:]))
    cfg = preset("default", descriptor_frames=4)
    spec = TrialSpec(4, cfg, trial_preset("default", rounds=1, stop_confidence=0), seed=7,
                     platform_ids=tuple(IDS))
    TrialRun(spec, tmp_path, "burst", inputs=_inputs(spec), press=press).run()
    placement = dict(zip(IDS, fabrics, strict=True))
    filed = trial_presses(tmp_path / "burst", placement, cfg, "t")
    touches = [t for t in read_record(tmp_path / "burst")["touches"] if t["accepted"]]
    first = touches[0]
    assert len(first["extra_arrays"]) == 3
    want = raw_descriptor(Touch(first["array"], first["no_contact_array"],
                                np.stack(first["extra_arrays"])), cfg)
    alone = raw_descriptor(Touch(first["array"], first["no_contact_array"]), cfg)
    got = filed[placement[first["platform_id"]]][0][0]
    assert np.array_equal(got, want) and not np.allclose(got, alone)
