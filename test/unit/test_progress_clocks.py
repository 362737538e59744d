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


def test_a_resumed_trial_does_not_count_its_interruption(tmp_path: Path) -> None:
    rec = TrialRecord(tmp_path, "t")
    (rec.dir / "config.json").write_text('{"trial": {"rounds": 4}}')
    t0 = 1_000_000.0
    for k in range(3):                      # 3 presses 10 s apart, then decision 1
        rec.add_touch(None, {"platform_id": "c1", "accepted": False, "reason": "x",
                             "requested": t0 + 10 * k, "stamp": t0 + 10 * k + 3})
    rec.add_decision({"round": 1, "belief": [0.5, 0.5], "next": "c1", "done": False,
                      "time": t0 + 30.0})
    append_event(rec.dir, {"event": "resumed", "after_touch": 3, "decisions_on_disk": 1,
                           "time": t0 + 630.0})           # stopped for 600 s
    rec.add_touch(None, {"platform_id": "c1", "accepted": False, "reason": "x",
                         "requested": t0 + 632.0, "stamp": t0 + 635.0})
    rec.add_decision({"round": 2, "belief": [0.6, 0.4], "next": "c2", "done": False,
                      "time": t0 + 640.0})
    lines: list[str] = []
    p = Progress(lambda text, kind: lines.append(text) if kind == "decision" else None)
    p.follow(rec.dir)
    p.poll()
    # 40 s of trial (640 - 600 interrupted): 40 / 3 rounds x 2 left = 27 s at most
    assert "0:40 elapsed, at most about 0:27 left" in lines[1], lines
    assert "0:30 elapsed" in lines[0]
