"""The console while a long decision runs (the thesis CNN: 27-98 s each) and on a resume: a
waiting line every ``every_s`` seconds without a new touch or decision, the resume's way."""

from __future__ import annotations

import json
from pathlib import Path

from tactex_ros.trial.progress import Progress


def _append(path: Path, obj: dict) -> None:
    with open(path, "a") as f:
        f.write(json.dumps(obj) + "\n")


def test_waiting_line_during_a_long_decision_and_resume_line(tmp_path: Path) -> None:
    now = [0.0]
    lines: list[tuple[str, str]] = []
    p = Progress(lambda text, kind: lines.append((kind, text)), clock=lambda: now[0],
                 every_s=30.0)
    p.follow(tmp_path)
    p.poll()
    now[0] = 100.0
    p.poll()
    assert lines == []                                   # nothing started: nothing to wait for
    _append(tmp_path / "events.jsonl", {"event": "resumed", "how": "restored round 3"})
    for i in range(5):
        _append(tmp_path / "touches.jsonl", {"seq": i + 1, "platform_id": "c1",
                                             "accepted": True})
    p.poll()
    assert lines[0] == ("info", "resume: restored round 3")
    assert len(lines) == 6
    for t in (110.0, 129.0):
        now[0] = t
        p.poll()
    assert len(lines) == 6                               # under 30 s: quiet
    now[0] = 131.0
    p.poll()
    now[0] = 150.0
    p.poll()
    now[0] = 162.0
    p.poll()
    waits = [t for k, t in lines[6:]]
    assert len(waits) == 2 and all("disk: 0)" in t for t in waits)
    assert "31 s" in waits[0] and "62 s" in waits[1]     # counted from the last touch
    _append(tmp_path / "decisions.jsonl", {"round": 1, "belief": [1.0], "next": "c1"})
    p.poll()
    now[0] = 200.0
    p.poll()
    assert "disk: 1)" in lines[-1][1]
    _append(tmp_path / "decisions.jsonl", {"round": 2, "belief": [1.0], "done": True,
                                           "prediction": "c1"})
    p.poll()
    n = len(lines)
    now[0] = 400.0
    p.poll()
    assert len(lines) == n                                # done: no more waiting lines


def test_the_start_up_line_does_not_bury_the_placement_prompt(tmp_path: Path) -> None:
    """Issue 47, item 3: while the record folder does not exist the start-up line comes once
    after 5 s, then every 30 s (16 lines by 81 s before); none once the nodes are up (the
    session's placement prompt is out)."""
    now = [0.0]
    lines: list[str] = []
    p = Progress(lambda text, kind: lines.append(text), clock=lambda: now[0])
    p.follow(tmp_path / "trial_1")                       # not there yet: the nodes start
    for t in range(0, 82):                               # polled every second, as the runner
        now[0] = float(t)
        p.poll()
    assert len(lines) == 3                               # at 5, 35 and 65 s
    p.nodes_up()
    for t in range(82, 400):
        now[0] = float(t)
        p.poll()
    assert len(lines) == 3
