"""Issue 29: ``resume:=RECORD`` needs no other argument. The explorer node, given only its
``resume`` parameter (``ros2 run tactex explorer_node --ros-args -p resume:=RECORD``), takes
the record's settings itself (``run_settings.resolve_run``, as the launch file and ``tactex
graph run`` resolve a resume: seed, strategy, rounds, stop rule, record folder) and finishes
the interrupted trial; a parameter set to another value than the record's ends the node with
exit status 2 before it presses, the setting and both values named."""

from __future__ import annotations

import json
import os
import signal
import threading
import time
from pathlib import Path

import pytest

from tactex_ros.ros.graph import describe
from tactex_ros.ros.devrun.launcher import run_graph
from tactex_ros.trial.record import read_record

pytestmark = [pytest.mark.ros, pytest.mark.slow]      # about 80 s

DEADLINE_S = 300.0          # per graph run, at load 10 on 2 cores


def _touches(record: Path) -> int:
    try:
        return len((record / "touches.jsonl").read_text().splitlines())
    except OSError:
        return 0


def test_the_explorer_resumes_from_its_record_alone(tmp_path: Path, domain_id: int,
                                                    small_scene: str) -> None:
    rec = tmp_path / "t"

    def kill_after_3_touches(graph) -> None:
        def watch() -> None:
            end = time.monotonic() + DEADLINE_S
            while time.monotonic() < end and graph.procs["explorer"].poll() is None:
                if _touches(rec) >= 3:
                    os.kill(graph.procs["explorer"].pid, signal.SIGKILL)
                    return
                time.sleep(0.05)
        threading.Thread(target=watch, daemon=True).start()

    first = describe(True, small_scene, explorer={"trial": {"rounds": 2, "strategy": "random",
                                               "stop_confidence": 0.0},
                                     "seed": 5, "record_dir": str(tmp_path), "trial_id": "t"})
    run = run_graph(first, tmp_path / "logs1", timeout_s=DEADLINE_S, domain_id=domain_id,
                    on_start=kill_after_3_touches)
    assert run.result is None and run.failed_node == "explorer", run.failure
    n = len(read_record(rec, images=False)["touches"])
    assert n >= 3
    config = (rec / "config.json").read_bytes()

    # a parameter that contradicts the record: refused at configure, exit status 2
    bad = describe(True, small_scene, explorer={"resume": str(rec), "seed": 6})
    run = run_graph(bad, tmp_path / "logs2", timeout_s=DEADLINE_S, domain_id=domain_id)
    assert run.result is None and run.node_exit["explorer"] == 2, run.failure
    assert "seed = 6" in (run.reason or "") and "seed = 5" in (run.reason or ""), run.reason
    assert len(read_record(rec, images=False)["touches"]) == n      # nothing pressed

    # only `resume` (as `ros2 run tactex explorer_node --ros-args -p resume:=RECORD`): the
    # record's settings, the trial finished in its own folder
    only = describe(True, small_scene)
    next(x for x in only if x.name == "explorer").parameters = {"resume": str(rec)}
    run = run_graph(only, tmp_path / "logs3", timeout_s=DEADLINE_S, domain_id=domain_id)
    res = run.result
    assert res is not None and "error" not in res, (run.failure, run.reason)
    assert res["strategy"] == "random" and res["stop_reason"] == "rounds"
    assert res["touches"] == 3 + 2 and res["resumed"]
    assert (rec / "config.json").read_bytes() == config        # the record's settings kept
    assert json.loads(config)["explorer"]["seed"] == 5
