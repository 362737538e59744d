"""Issue 21 through `tactex graph run` (real node processes): a node's refusal reaches the
console with the thing it refused and exit status 2, with no resume hint; the run's status is
its own (a result already on disk never makes a run succeed); the nodes do not import from the
current folder."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest
import yaml

from tactex_ros.core.paths import config_dir
from tactex_ros.ros.devrun.launcher import ros_env

pytestmark = [pytest.mark.ros, pytest.mark.slow]


def _run(args: list[str], domain_id: int, cwd: Path,
         timeout_s: float = 240, sim: bool = True) -> subprocess.CompletedProcess:
    script = Path(sys.executable).parent / "tactex"      # the console script users run
    entry = [str(script)] if script.is_file() else [sys.executable, "-P", "-m",
                                                    "tactex_ros.cli.main"]
    cmd = entry + ["graph", "run"] + (["--sim"] if sim else []) + [
           "--domain-id", str(domain_id), "--timeout", "180"] + args
    return subprocess.run(cmd, env=ros_env(domain_id), capture_output=True, text=True,
                          timeout=timeout_s, cwd=cwd)


@pytest.mark.parametrize("case", ["source", "fabric"])
def test_node_refusal_reaches_the_console(tmp_path: Path, domain_id: int, case: str) -> None:
    args = ["--record-dir", str(tmp_path / "rec"), "--trial-id", "t",
            "--log-dir", str(tmp_path / "logs")]
    if case == "source":
        args += ["--source", "sim:7"]
        named = "sim:7"
    else:
        scene = yaml.safe_load((config_dir() / "scene_sim.yaml").read_text())
        scene["platforms"][1]["sim_fabric"] = "no_such_fabric"
        bad = tmp_path / "scene.yaml"
        bad.write_text(yaml.safe_dump(scene))
        args += ["--scene", str(bad)]
        named = "no_such_fabric"
    r = _run(args, domain_id, tmp_path)
    assert r.returncode == 2, r.stderr
    assert named in r.stderr and "mock_image" in r.stderr
    assert "--resume" not in r.stderr           # the same input would be refused again
    assert "Traceback" not in r.stderr


def test_no_camera_is_a_run_time_failure(tmp_path: Path, domain_id: int) -> None:
    """The hardware graph without its camera: exit status 1 (a device absent at run time,
    docs/robustness.md "Exit status"), not 2; gelsight's reason with the device named on the
    console; no touch recorded; a resume is offered (it works once the camera is there)."""
    dev = tmp_path / "no_camera"
    r = _run(["--device", str(dev), "--record-dir", str(tmp_path / "rec"), "--trial-id", "t",
              "--log-dir", str(tmp_path / "logs")], domain_id, tmp_path, sim=False)
    assert r.returncode == 1, r.stderr
    assert "gelsight" in r.stderr and str(dev) in r.stderr
    assert "Traceback" not in r.stderr and "--resume" in r.stderr
    assert not (tmp_path / "rec" / "t" / "touches.jsonl").exists()


def test_reused_trial_id_is_refused_not_reported_as_success(tmp_path: Path, domain_id: int,
                                                          small_scene: str) -> None:
    """Run 1 finishes; run 2 with the same trial id is refused up front (exit 2, the record
    named, nothing started or overwritten); resuming the finished record is refused too."""
    rec = tmp_path / "rec"
    args = ["--scene", small_scene, "--rounds", "0", "--record-dir", str(rec), "--trial-id",
            "same"]
    first = _run(args + ["--log-dir", str(tmp_path / "l1")], domain_id, tmp_path)
    assert first.returncode == 0, first.stderr
    before = (rec / "same" / "result.json").read_bytes()
    again = _run(args + ["--log-dir", str(tmp_path / "l2")], domain_id, tmp_path, 60)
    assert again.returncode == 2 and str(rec / "same") in again.stderr
    assert not (tmp_path / "l2").exists()      # refused before any node started
    resumed = _run(["--resume", str(rec / "same"), "--log-dir", str(tmp_path / "l3")],
                   domain_id, tmp_path, 60)
    assert resumed.returncode == 2 and "same" in resumed.stderr
    assert (rec / "same" / "result.json").read_bytes() == before
    assert json.loads(before)["prediction"]


def test_nodes_ignore_modules_in_the_current_folder(tmp_path: Path, domain_id: int,
                                                    small_scene: str) -> None:
    """A folder holding inspect.py (a standard module name) is no reason to fail."""
    (tmp_path / "inspect.py").write_text("raise SystemExit('the local inspect.py was imported')\n")
    r = _run(["--scene", small_scene, "--rounds", "0", "--record-dir", str(tmp_path / "rec"),
              "--trial-id", "t", "--log-dir", str(tmp_path / "logs")], domain_id, tmp_path)
    assert r.returncode == 0, r.stderr
    assert (tmp_path / "rec" / "t" / "result.json").is_file()


def test_shipped_replay_scene_runs_on_recorded_presses(tmp_path: Path, domain_id: int,
                                                       octopi_dir: Path) -> None:
    """`--scene scene_replay --source replay:DIR`: the graph presses recorded presses of each
    platform's replay_class and ends with a result."""
    r = _run(["--scene", "scene_replay", "--source", f"replay:{octopi_dir}", "--rounds", "1",
              "--record-dir", str(tmp_path / "rec"), "--trial-id", "t",
              "--log-dir", str(tmp_path / "logs")], domain_id, tmp_path)
    assert r.returncode == 0, r.stderr
    res = json.loads((tmp_path / "rec" / "t" / "result.json").read_text())
    assert res["prediction"] in ("c1", "c2", "c3", "c4") and res["touches"] >= 5


def test_ctrl_c_then_resume_with_the_record_alone(tmp_path: Path, domain_id: int,
                                                  small_scene: str) -> None:
    """Ctrl-C in `--rounds 3 --seed 0 --yes` after two touches: exit 130 and a hint that is
    `--resume DIR` alone; run as printed (plus this test's DDS domain and log folder) the trial
    goes on with the record's options (the sim graph, 3 rounds, seed 0) to its result, exit 0."""
    import shlex
    import signal
    import time
    rec = tmp_path / "rec" / "t"
    script = Path(sys.executable).parent / "tactex"
    entry = [str(script)] if script.is_file() else [sys.executable, "-P", "-m",
                                                    "tactex_ros.cli.main"]
    p = subprocess.Popen(entry + ["graph", "run", "--sim", "--scene", small_scene,
                                  "--rounds", "3", "--seed", "0",
                                  "--yes", "--record-dir", str(rec.parent), "--trial-id", "t",
                                  "--domain-id", str(domain_id), "--log-dir",
                                  str(tmp_path / "l1")],
                         env=ros_env(domain_id), stderr=subprocess.PIPE, text=True,
                         stdout=subprocess.DEVNULL, cwd=tmp_path)
    touches = rec / "touches.jsonl"
    end = time.monotonic() + 240
    while time.monotonic() < end and p.poll() is None and not (
            touches.is_file() and len(touches.read_text().splitlines()) >= 2):
        time.sleep(0.1)
    assert p.poll() is None, p.communicate()[1]        # still running: the trial is longer
    p.send_signal(signal.SIGINT)
    err = p.communicate(timeout=120)[1]
    assert p.returncode == 128 + signal.SIGINT, err
    hint = err.split("continue with: ", 1)[1].splitlines()[0]
    assert shlex.split(hint) == ["tactex", "graph", "run", "--resume", str(rec)]
    r = _run(shlex.split(hint)[3:] + ["--log-dir", str(tmp_path / "l2")], domain_id,
             tmp_path, sim=False)
    assert r.returncode == 0, r.stderr
    res = json.loads((rec / "result.json").read_text())
    assert res["seed"] == 0 and len(res["rounds"]) <= 3 and res["resumed"]
    params = yaml.safe_load((tmp_path / "l2" / "params.yaml").read_text())
    assert "mock_arm" in params                         # the sim graph, from the record
