"""Issue 49, items 1 and 6, without ROS: the writes that complete a trial or a session besides
its result are checked. A full disk (``os.write`` failing with ENOSPC for one file) at a
trial's report.html leaves the result on disk and names the file among the trial's
``write_failures`` (the explorer then ends with exit status 1); at the fabric library or the
session's report.html it ends the session with exit status 1, the file named on its log; a
continued session files the library again once the disk has room."""

from __future__ import annotations

import errno
import logging
import os
from pathlib import Path

import pytest

from tactex_ros.core import library as flib
from tactex_ros.core import outputs
from tactex_ros.core.config import preset
from tactex_ros.trial import session as sess
from tactex_ros.trial.library import LibraryKeeper
from tactex_ros.trial.run import TrialRun
from tactex_ros.trial.session_run import SessionRun, trial_outcome

from test_session_library import IDS, SHORT, Operator, _inputs, _press, _spec  # noqa: E402


@pytest.fixture
def full_disk(monkeypatch):
    """The names of the full disk: every write to a file whose path holds one of them fails
    with ENOSPC, the others go through (append a name, clear the list)."""
    real = os.write
    names: list[str] = []

    def write(fd: int, data) -> int:
        try:
            path = os.readlink(f"/proc/self/fd/{fd}")
        except OSError:
            path = ""
        if any(n in path for n in names):
            raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))
        return real(fd, data)
    monkeypatch.setattr(outputs.os, "write", write)
    return names


def _session(tmp_path: Path, keeper: LibraryKeeper | None):
    lines: list[tuple[int, str]] = []
    session = sess.load_session(SHORT, IDS, seed=3)
    run = SessionRun(session, tmp_path / "sess", {"seed": 3}, 1.0, library=keeper,
                     log=lambda level, text: lines.append((level, text)))

    def run_trial(trial: sess.SessionTrial, resume: str | None) -> dict:
        spec = _spec(trial.seed, run.current_library())
        tr = TrialRun(spec, run.dir, trial.record_name, inputs=_inputs(spec),
                      press=_press(list(trial.placement.values()), trial.seed), resume=resume)
        return tr.run(extra=lambda r: trial_outcome(trial, r))
    return run, run_trial, lines


def test_a_report_that_cannot_be_written_is_a_write_failure_of_the_trial(tmp_path, full_disk):
    full_disk.append("report.html")
    spec = _spec(5, None)
    tr = TrialRun(spec, tmp_path, "t", inputs=_inputs(spec),
                  press=_press(["denim", "linen", "denim", "cotton_lawn", "cotton_canvas"], 5))
    res = tr.run()
    assert "error" not in res and (tmp_path / "t" / "result.json").is_file()
    assert len(tr.write_failures) == 1
    assert str(tmp_path / "t" / "report.html") in tr.write_failures[0]
    assert "No space left on device" in tr.write_failures[0]
    assert not (tmp_path / "t" / "report.html").exists()


def test_a_fabric_library_that_cannot_be_written_ends_the_session(tmp_path, full_disk):
    lib_path = tmp_path / "sess" / flib.LIBRARY_FILE
    full_disk.append(flib.LIBRARY_FILE)
    run, run_trial, lines = _session(tmp_path, LibraryKeeper(lib_path, preset("default")))
    assert run.run(Operator(), run_trial, lambda: False) == 1      # was 0: success
    errors = [t for lv, t in lines if lv >= logging.ERROR]
    assert errors and str(lib_path) in errors[-1] and "No space left" in errors[-1], lines
    ended = [e for e in sess.events(run.dir) if e["event"] == "session_ended"]
    assert ended and str(lib_path) in ended[-1]["reason"]
    assert not (run.dir / sess.RESULT_FILE).exists()              # the session is not done
    assert not lib_path.exists()
    # room again: the continued session files the trial that was left out, then goes on
    full_disk.clear()
    again, run_trial2, _ = _session(tmp_path, LibraryKeeper(lib_path, preset("default")))
    assert again.run(Operator(), run_trial2, lambda: False) == 0
    assert flib.load(lib_path).presses > 0 and (run.dir / sess.RESULT_FILE).is_file()


def test_a_session_report_that_cannot_be_written_ends_the_session_with_exit_1(tmp_path,
                                                                           full_disk):
    full_disk.append(str(tmp_path / "sess" / ".report.html"))       # its temporary file (atomic)
    run, run_trial, lines = _session(tmp_path, None)
    assert run.run(Operator(), run_trial, lambda: False) == 1      # was 0: success
    errors = [t for lv, t in lines if lv >= logging.ERROR]
    assert errors and str(run.dir / "report.html") in errors[-1], lines
    assert (run.dir / sess.RESULT_FILE).is_file()                 # every trial is done
