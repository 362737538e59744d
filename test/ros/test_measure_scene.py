"""``tactex robot measure-scene`` against the mock arm node (real processes over DDS): the
mock's surfaces lie 4 mm below the scene's, its wrench has a bias, a cable's lift and noise;
the command finds each surface with a light press and writes the corrected scene. Before the
arm moves it runs the motion node's pre-flight (issue 46): a silent or slow state stream, a
second publisher of the target, or an unwritable ``--out`` refuse the start before any target
is published."""

from __future__ import annotations

import json
import subprocess
import sys
import time
from pathlib import Path

import pytest
import yaml

from tactex_ros.robot.scene import load_scene
from tactex_ros.ros.graph import SIM_MIN_STATE_RATE_HZ, describe
from tactex_ros.ros.devrun.launcher import Graph, ros_env

pytestmark = pytest.mark.ros

SHIFT = -0.004
#: the mock arm's state-rate floor, as the sim graph's motion pre-flight asks (a loaded machine
#: slows its 100 Hz; the sim profile's own floor is 50 Hz)
SIM_RATE = ["--min-state-rate-hz", str(SIM_MIN_STATE_RATE_HZ)]


def _measure(scene_file: str, out: Path, *extra: str) -> list[str]:
    """The ``tactex robot measure-scene`` command line on the sim profile."""
    return [sys.executable, "-c", "import sys; from tactex_ros.cli.main import main; "
            "sys.exit(main())", "robot", "measure-scene", "--robot", "sim", "--scene",
            str(scene_file), "--out", str(out), *extra]


def test_measure_scene_finds_a_shifted_surface(tmp_path: Path, listener) -> None:
    nodes = [n for n in describe(True, mock_arm={
        "surface_offset": SHIFT, "wrench_offset_z": -2.0, "static_force_z": 1.5,
        "wrench_noise": 0.05, "world_seed": 3}) if n.name == "mock_arm"]
    scene_file = nodes[0].parameters["scene_file"]
    scene = load_scene(scene_file)
    out = tmp_path / "measured.yaml"
    cmd = _measure(scene_file, out, "--platforms", "reference,c3", "--state-deadline-s", "30",
                   *SIM_RATE)
    with Graph(nodes, tmp_path / "logs", listener.domain_id):
        proc = subprocess.run(cmd, capture_output=True, text=True, timeout=300,
                              env=ros_env(listener.domain_id))
    assert proc.returncode == 0, proc.stdout + proc.stderr
    report = json.loads(proc.stdout)
    assert set(report["platforms"]) == {"reference", "c3"}
    got = load_scene(out)
    for p, q in zip(scene.platforms, got.platforms, strict=True):
        assert p.id == q.id and q.position[:2] == p.position[:2]
        if p.id in ("reference", "c3"):
            assert abs(q.position[2] - (p.position[2] + SHIFT)) < 0.0005, (p.id, q.position)
            assert report["platforms"][p.id]["moved_mm"] == pytest.approx(SHIFT * 1000, abs=0.5)
        else:
            assert q.position == p.position        # not measured: kept
    # everything else in the file is as it was
    before, after = yaml.safe_load(Path(scene_file).read_text()), yaml.safe_load(out.read_text())
    assert {k: v for k, v in before.items() if k != "platforms"} == \
        {k: v for k, v in after.items() if k != "platforms"}


def test_measure_scene_refuses_an_unknown_platform(tmp_path: Path) -> None:
    from tactex_ros.core.paths import config_dir
    cmd = [sys.executable, "-c", "import sys; from tactex_ros.cli.main import main; "
           "sys.exit(main())", "robot", "measure-scene", "--robot", "sim", "--scene",
           str(config_dir() / "scene_sim.yaml"), "--out", str(tmp_path / "o.yaml"),
           "--platforms", "nope"]
    proc = subprocess.run(cmd, capture_output=True, text=True, timeout=120)
    assert proc.returncode == 2 and "nope" in proc.stderr
    assert not (tmp_path / "o.yaml").exists()


def test_measure_scene_holds_the_target_on_stale_state_then_stops(tmp_path: Path, listener,
                                                                   force_trace) -> None:
    """The robot state stops at the light press's approach point (mock arm SIGSTOP, 4 s): from
    ``--state-hold-s`` on the command publishes the same target; after ``--state-timeout-s``
    (2 s) it ends with exit 1, nothing written."""
    import os
    import signal
    import time
    nodes = [n for n in describe(True) if n.name == "mock_arm"]
    scene_file = nodes[0].parameters["scene_file"]
    scene = load_scene(scene_file)
    # at the approach point (its tare, before the descent: the lab scene's press then takes
    # about 0.3 s to reach the surface, too fast to catch inside the descent)
    descending = scene.platform("c3").position[2] + scene.press.approach_height + 0.0005
    out = tmp_path / "measured.yaml"
    cmd = _measure(scene_file, out, "--platforms", "c3", "--state-deadline-s", "30",
                   "--state-timeout-s", "2.0", *SIM_RATE)
    with Graph(nodes, tmp_path / "logs", listener.domain_id) as g:
        proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                                env=ros_env(listener.domain_id))
        end = time.monotonic() + 200.0
        while time.monotonic() < end and proc.poll() is None and not any(
                k == "target" and v < descending for _, k, v in list(force_trace.rows)):
            time.sleep(0.01)
        assert proc.poll() is None, proc.communicate()
        pid = g.procs["mock_arm"].pid
        os.kill(pid, signal.SIGSTOP)
        t_stop = time.monotonic()
        time.sleep(4.0)
        os.kill(pid, signal.SIGCONT)
        stdout, stderr = proc.communicate(timeout=120)
    assert proc.returncode == 1, stdout + stderr
    report = json.loads(stdout)
    assert report["platforms"]["c3"]["success"] is False
    assert not out.exists()
    held = [v for t, k, v in list(force_trace.rows)
            if k == "target" and t_stop + 0.5 <= t <= t_stop + 1.5]
    assert held and max(held) == min(held), (min(held, default=None), max(held, default=None))
    # nothing commanded once the state was older than the timeout (2 s, plus delivery)
    assert not [t for t, k, _ in list(force_trace.rows) if k == "target" and t > t_stop + 3.0]


def _wait_for_state(force_trace, deadline_s: float = 120.0) -> None:
    """Until the listener hears the mock arm's wrench (the arm is up), or fail at the
    deadline."""
    end = time.monotonic() + deadline_s
    while not force_trace.forces() and time.monotonic() < end:
        time.sleep(0.02)
    assert force_trace.forces(), f"no robot state from the mock arm within {deadline_s} s"


def _targets(force_trace) -> list[float]:
    """[m] every target height the listener received."""
    return [v for _, k, v in list(force_trace.rows) if k == "target"]


@pytest.mark.parametrize("case, arm, extra, status, named", [
    # no robot: the state silent, a device absent at run time (DeviceError)
    ("silent", None, ["--state-deadline-s", "2"], 1, "pre-flight state:"),
    # the state at 20 Hz against the sim profile's floor of 50 Hz (DeviceNotReady)
    ("slow", {"rate_hz": 20.0}, ["--state-deadline-s", "30"], 1, "pre-flight state_rate:"),
    # a second publisher of the arm's target: another graph drives the arm (InputError)
    ("second publisher", {}, ["--state-deadline-s", "30", *SIM_RATE], 2,
     "/cartesian_impedance_controller/equilibrium_pose"),
])
def test_measure_scene_preflight_refuses_before_any_target(tmp_path: Path, listener,
                                                           force_trace, case, arm, extra,
                                                           status, named) -> None:
    """The motion node's pre-flight refuses the start with its exit status and the problem
    named; the listener (which hears the mock arm's state) receives no target at all."""
    from geometry_msgs.msg import PoseStamped

    from tactex_ros.ros.settings import TARGET_TOPIC
    nodes = ([n for n in describe(True, mock_arm=arm) if n.name == "mock_arm"]
             if arm is not None else [])
    scene_file = describe(True)[0].parameters["scene_file"]
    if case == "second publisher":
        listener.node.create_publisher(PoseStamped, TARGET_TOPIC, 10)
    out = tmp_path / "measured.yaml"
    with Graph(nodes, tmp_path / "logs", listener.domain_id) as g:
        if arm is not None:
            _wait_for_state(force_trace)
        proc = subprocess.run(_measure(scene_file, out, *extra), capture_output=True,
                              text=True, timeout=300, env=ros_env(listener.domain_id))
        if arm is not None:
            assert g.wait("mock_arm", 0.1) is None      # its state was there throughout
    assert proc.returncode == status, (case, proc.returncode, proc.stderr)
    assert named in proc.stderr, proc.stderr
    assert _targets(force_trace) == []
    assert not out.exists()


def test_measure_scene_refuses_an_unwritable_out_before_any_target(tmp_path: Path, listener,
                                                                  force_trace) -> None:
    """``--out`` under a file: exit 2 with the option named, before the pre-flight and the
    first press (cli.main.check_outputs); the mock arm was there to be moved."""
    nodes = [n for n in describe(True) if n.name == "mock_arm"]
    scene_file = nodes[0].parameters["scene_file"]
    blocker = tmp_path / "a_file"
    blocker.write_text("x")
    with Graph(nodes, tmp_path / "logs", listener.domain_id) as g:
        _wait_for_state(force_trace)
        proc = subprocess.run(_measure(scene_file, blocker / "measured.yaml",
                                       "--state-deadline-s", "30", *SIM_RATE),
                              capture_output=True, text=True, timeout=120,
                              env=ros_env(listener.domain_id))
        assert g.wait("mock_arm", 0.1) is None
    assert proc.returncode == 2, proc.stdout + proc.stderr
    assert "--out" in proc.stderr
    assert _targets(force_trace) == []
