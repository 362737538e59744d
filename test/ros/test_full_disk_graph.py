"""Issue 31, the whole graph on a full disk: the explorer's files get a size limit
(RLIMIT_FSIZE, set on the running process with ``prlimit``) below one touch image once the
trial has pressed twice. ``tactex graph run`` ends within seconds (not at its idle deadline)
with exit status 1 and the reason (the file that could not be written) on the console, reports
no success, and ``--resume`` of the record (no limit) finishes the trial. The write sites one
by one: test/unit/test_full_disk.py."""

from __future__ import annotations

import json
import resource
import subprocess
import sys
import time
from pathlib import Path

import pytest

from tactex_ros.ros.devrun.launcher import ros_env
from tactex_ros.trial.record import read_record

pytestmark = [pytest.mark.ros, pytest.mark.slow]

LIMIT = 40_000          # [bytes] below a simulated touch image (a PNG of 80-100 kB)
DEADLINE_S = 600.0      # one command, at load 10 on 2 cores


def _tactex(*args: str) -> list[str]:
    script = Path(sys.executable).parent / "tactex"
    entry = [str(script)] if script.is_file() else [sys.executable, "-P", "-m",
                                                    "tactex_ros.cli.main"]
    return entry + ["graph", "run", *args]


def _explorer_pid(tag: str) -> int | None:
    """The explorer process whose command line holds ``tag`` (this test's log folder)."""
    import re
    found = subprocess.run(["pgrep", "-f", f"explorer_node.*{re.escape(tag)}"],
                           capture_output=True, text=True).stdout.split()
    return int(found[0]) if found else None


def _lines(p: Path) -> int:
    try:
        return len(p.read_text().splitlines())
    except OSError:
        return 0


def test_a_disk_that_fills_mid_trial_ends_it_named_and_the_record_resumes(
        tmp_path: Path, domain_id: int, small_scene: str) -> None:
    rec, logs = tmp_path / "t", tmp_path / "logs"
    proc = subprocess.Popen(_tactex("--sim", "--scene", small_scene, "--rounds", "1",
                                    "--record-dir", str(tmp_path),
                                    "--trial-id", "t", "--log-dir", str(logs),
                                    "--set", "trial.stop_confidence=0.0"),
                            env=ros_env(domain_id), stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True)
    t_limit = None
    try:
        end = time.monotonic() + DEADLINE_S
        while time.monotonic() < end and proc.poll() is None:
            pid = _explorer_pid(str(logs))
            if pid is not None and _lines(rec / "touches.jsonl") >= 2:
                hard = resource.prlimit(pid, resource.RLIMIT_FSIZE)[1]
                resource.prlimit(pid, resource.RLIMIT_FSIZE, (LIMIT, hard))
                t_limit = time.monotonic()
                break
            time.sleep(0.05)
        out, err = proc.communicate(timeout=DEADLINE_S)
        t_end = time.monotonic()
    finally:
        if proc.poll() is None:
            proc.kill()
    assert t_limit is not None, err[-3000:]
    n = len(read_record(rec, images=False)["touches"])
    assert proc.returncode == 1, (out, err[-3000:])
    assert "reference matches" not in out                       # no success reported
    # the reason on the console: the file of the record that could not be written, and why
    assert str(rec) in err and "File too large" in err, err[-3000:]
    took = t_end - t_limit
    assert took < 60.0, took                    # the idle deadline is 600 s
    res = rec / "result.json"
    assert not res.is_file() or "error" in json.loads(res.read_text())
    print(f"\nfile-size limit -> tactex graph run ended (exit 1) after {took:.1f} s; "
          f"{n} touches on disk")

    again = subprocess.run(_tactex("--resume", str(rec), "--log-dir", str(tmp_path / "logs2")),
                           env=ros_env(domain_id), capture_output=True, text=True,
                           timeout=DEADLINE_S)
    assert again.returncode == 0, again.stderr[-3000:]
    res = json.loads((rec / "result.json").read_text())
    assert "error" not in res and res["touches"] == 3 + 1
    assert len(read_record(rec, images=False)["touches"]) >= n
