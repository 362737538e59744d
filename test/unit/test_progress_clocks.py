"""Issue 47 item 5: the terminal's clocks. After a resume the elapsed time and the time left
leave out the interruption; a decision past the rounds cap is not shown as ``5/4``."""

from __future__ import annotations

from pathlib import Path

from tactex_ros.trial.progress import Progress, decision_line, interrupted_s
from tactex_ros.trial.record import TrialRecord, append_event


def test_interruptions_are_measured_from_the_last_line_to_the_resume() -> None:
    times = [10.0, 12.0, 20.0, 25.0]
    assert interrupted_s(times, [], 100.0) == 0.0
    assert interrupted_s(times, [225.0], 300.0) == 200.0      # 25 -> 225
    assert interrupted_s(times, [225.0], 200.0) == 0.0        # not yet resumed by then
    assert interrupted_s(times + [230.0, 240.0], [225.0, 440.0], 500.0) == 400.0


def test_decision_past_the_cap_is_the_final_one() -> None:
    d = {"round": 5, "belief": [0.6, 0.4], "done": True, "prediction": "c1"}
    text = decision_line(d, ["c1", "c2"], rounds=4)
    assert "5/4" not in text and text.startswith("decision 5 (final")
    assert decision_line(dict(d, round=4), ["c1", "c2"], 4).startswith("decision 4/4:")


def _press(rec: TrialRecord, t: float, took_s: float = 2.0) -> None:
    rec.add_touch(None, {"platform_id": "c1", "accepted": False, "reason": "x",
                         "requested": t, "stamp": t + took_s})


def _decision_lines(rec: TrialRecord) -> list[str]:
    """The decision lines a terminal's Progress prints for the record as it is."""
    lines: list[str] = []
    p = Progress(lambda text, kind: lines.append(text) if kind == "decision" else None)
    p.follow(rec.dir)
    p.poll()
    return lines


def test_a_resumed_trial_does_not_count_its_interruption(tmp_path: Path) -> None:
    rec = TrialRecord(tmp_path, "t")
    (rec.dir / "config.json").write_text('{"trial": {"rounds": 4}}')
    t0 = 1_000_000.0
    for k in range(3):                      # 3 presses 10 s apart, then decision 1
        _press(rec, t0 + 10 * k, 3.0)
    rec.add_decision({"round": 1, "belief": [0.5, 0.5], "next": "c1", "done": False,
                      "time": t0 + 30.0})
    append_event(rec.dir, {"event": "resumed", "after_touch": 3, "decisions_on_disk": 1,
                           "time": t0 + 630.0})           # stopped for 600 s
    _press(rec, t0 + 632.0, 3.0)
    rec.add_decision({"round": 2, "belief": [0.6, 0.4], "next": "c2", "done": False,
                      "time": t0 + 640.0})
    lines = _decision_lines(rec)
    # 40 s of trial (640 - 600 interrupted): 40 / 3 rounds x 2 left = 27 s at most
    assert "0:40 elapsed, at most about 0:27 left" in lines[1], lines
    assert "0:30 elapsed" in lines[0]


def test_the_operator_pause_is_not_the_trial_time(tmp_path: Path) -> None:
    """A trial paused for 100 s between its first and second press: the decision line's
    elapsed time leaves the pause out, as the result's ``elapsed_s`` does (operator walk of
    issue 47: 25 s printed against 16 s recorded)."""
    rec = TrialRecord(tmp_path, "t")
    (rec.dir / "config.json").write_text('{"trial": {"rounds": 4}}')
    t0 = 1_000_000.0
    _press(rec, t0)
    append_event(rec.dir, {"event": "operator", "action": "pause", "time": t0 + 1.0})
    append_event(rec.dir, {"event": "operator", "action": "resume", "time": t0 + 101.0})
    _press(rec, t0 + 103.0)
    rec.add_decision({"round": 1, "belief": [0.5, 0.5], "next": "c1", "done": False,
                      "time": t0 + 110.0})
    lines = _decision_lines(rec)
    assert "0:10 elapsed" in lines[0], lines           # 110 s - the 100 s paused


def test_a_redone_trial_is_followed_afresh(tmp_path: Path) -> None:
    """A redo moves the trial's record away and starts a new one at the same path: the new
    record's presses are printed from its first (operator walk of issue 47: the redone
    trial's first presses were never shown)."""
    rec = TrialRecord(tmp_path, "t")
    for k in range(3):
        _press(rec, 1000.0 + k)
    lines: list[str] = []
    p = Progress(lambda text, kind: lines.append(text) if kind == "press" else None)
    p.follow(rec.dir)
    p.poll()
    assert len(lines) == 3
    rec.dir.rename(tmp_path / "t.superseded.1")
    p.poll()                                   # the folder is gone for a moment
    again = TrialRecord(tmp_path, "t")
    _press(again, 2000.0)
    _press(again, 2003.0)
    p.follow(again.dir)                        # the same path: the session's trial_started
    p.poll()
    assert [t.split(":")[0] for t in lines[3:]] == ["press 1", "press 2"], lines
