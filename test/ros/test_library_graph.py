"""Issue 51 through the operator's entrance, in the simulated graph: ``tactex graph library
--sim --materials denim,satin --presses 2 --out D --yes`` cut off with Ctrl-C (SIGINT to the
command) once its first press is saved keeps that press and names the command that continues;
the same command again presses only what is missing (asking for the placement of the material
it continues with, the mock camera told each material in turn), 2 materials x 2 presses in
all; then ``tactex prepare`` takes the folder. Two graph starts; every wait is for an
event of the library or the command's exit."""

from __future__ import annotations

import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest

from tactex_ros.ros.devrun.launcher import ros_env
from tactex_ros.trial import press_library as plib

pytestmark = [pytest.mark.ros, pytest.mark.slow]

DEADLINE_S = 600.0            # one command, at load 10 on 2 cores
MATERIALS = ["denim", "satin"]


def _tactex(*args: str) -> list[str]:
    script = Path(sys.executable).parent / "tactex"
    entry = [str(script)] if script.is_file() else [sys.executable, "-P", "-m",
                                                    "tactex_ros.cli.main"]
    return entry + list(args)


def _saved(d: Path) -> list[dict]:
    return [e for e in plib.events(d) if e.get("event") == "press_saved"]


def _when(cond, deadline_s: float, then) -> dict:
    """Watch ``cond()`` in a thread (every 50 ms, up to ``deadline_s``); once it holds,
    ``then()``; the time under ``"t"``."""
    got: dict = {}

    def watch() -> None:
        end = time.monotonic() + deadline_s
        while time.monotonic() < end:
            if cond():
                got["t"] = time.monotonic()
                then()
                return
            time.sleep(0.05)
    threading.Thread(target=watch, daemon=True).start()
    return got


def test_ctrl_c_then_the_same_command_presses_only_what_is_missing(
        tmp_path: Path, domain_id: int, small_scene: str) -> None:
    d = tmp_path / "lib"
    args = ["graph", "library", "--sim", "--scene", small_scene, "--materials",
            ",".join(MATERIALS), "--presses", "2", "--out", str(d), "--yes",
            "--set", "server_timeout_s=120"]
    proc = subprocess.Popen(_tactex(*args), env=ros_env(domain_id), cwd=tmp_path,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    cut = _when(lambda: len(_saved(d)) >= 1, DEADLINE_S,
                lambda: proc.send_signal(signal.SIGINT))       # the operator's Ctrl-C
    try:
        out, err = proc.communicate(timeout=DEADLINE_S)
    finally:
        if proc.poll() is None:
            proc.kill()
    assert "t" in cut, err[-3000:]
    assert proc.returncode == 128 + signal.SIGINT, err[-3000:]
    assert "continue with: tactex graph library" in err and f"--out {d}" in err, err[-3000:]
    before = plib.counts(d, MATERIALS)
    assert before["denim"] >= 1 and sum(before.values()) < 4, before
    assert not (d / plib.RESULT_FILE).exists()
    from tactex_ros.sources.replay import ReplaySource
    assert ReplaySource(d).classes == [m for m in MATERIALS if before[m]]   # none torn

    again = subprocess.run(_tactex(*args), env=ros_env(domain_id), cwd=tmp_path,
                           capture_output=True, text=True, timeout=DEADLINE_S)
    assert again.returncode == 0, again.stderr[-3000:]
    assert plib.counts(d, MATERIALS) == {"denim": 2, "satin": 2}
    evs = plib.events(d)
    k = max(i for i, e in enumerate(evs) if e["event"] == "resumed")
    rerun = evs[k:]
    assert rerun[0]["have"] == before
    made = [(e["trial"], e["press"]) for e in rerun if e["event"] == "press_saved"]
    missing = [(m, n) for m in MATERIALS for n in (1, 2) if n > before[m]]
    assert made == missing                       # only what was missing, in order
    asked = [e["trial"] for e in rerun if e["event"] == "awaiting_confirmation"]
    assert asked == [m for m in MATERIALS if before[m] < 2]
    assert {e["by"] for e in evs if e["event"] == "confirmed"} == {"yes_flag"}
    # the mock camera was told each material on the reference platform before its presses
    assert [e["placement"] for e in evs if e["event"] == "awaiting_confirmation"][-1] == \
        {"reference": "satin"}
    assert (d / plib.RESULT_FILE).is_file() and "tactex prepare --library" in again.stdout

    npz = tmp_path / "lab.npz"
    prep = subprocess.run(_tactex("prepare", "--library", f"replay:{d}", "--out", str(npz)),
                          cwd=tmp_path, capture_output=True, text=True, timeout=DEADLINE_S)
    assert prep.returncode == 0, prep.stderr[-3000:]
    from tactex_ros.core import representation
    rep = representation.load(str(npz))
    assert (rep.classes, rep.presses) == (2, 4)
