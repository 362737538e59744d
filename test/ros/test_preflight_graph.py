"""Pre-flight against real processes: the motion node refuses to start (the check named)
without robot state and with state slower than ``min_state_rate_hz`` (a real mock-arm process
standing in for the state broadcaster; both exit 1, a run-time state), and (exit 2) with a
collision-threshold service it cannot call (franka_msgs is not installable here: the refusal
carries the `ros2 service call`);
it starts when the lab says it set them by hand. The probe's service call against real stand-in
services (another process: ros2_control's order rule). The GelSight node refuses a recording
that starts in contact (octopi-dev frames, read in place) and starts on one that does not.
``tactex robot check-wrench`` against a wrench published by a real node: the sign, a wrong
profile sign and no push."""

from __future__ import annotations

import subprocess
import sys
import threading
import time
from pathlib import Path

import cv2
import pytest
import yaml
from geometry_msgs.msg import WrenchStamped

from tactex_ros.core.contact import strongest_contact
from tactex_ros.core.errors import InputError, TrialError
from tactex_ros.core.paths import config_dir
from tactex_ros.ros.graph import SIM_MIN_STATE_RATE_HZ, NodeSpec
from tactex_ros.ros.devrun.launcher import Graph, ros_env

pytestmark = [pytest.mark.ros, pytest.mark.slow]
SCENE = str(config_dir() / "scene_sim.yaml")


def _arm(**p) -> NodeSpec:
    return NodeSpec("mock_arm_node", "mock_arm", {"scene_file": SCENE, **p})


def _motion(**p) -> NodeSpec:
    # the sim graph's state-rate floor (a loaded machine slows the mock arm's 100 Hz to ~40 Hz,
    # measured); the test of the rate check sets its own
    return NodeSpec("motion_node", "motion", {"scene_file": SCENE, "robot": "sim",
                                              "preflight_deadline_s": 15.0,
                                              "min_state_rate_hz": SIM_MIN_STATE_RATE_HZ, **p})


def _log(tmp_path: Path, name: str) -> str:
    return (tmp_path / "logs" / f"{name}.log").read_text(errors="replace")


def test_no_robot_state_refuses_the_start(tmp_path: Path, domain_id) -> None:
    """No robot (its state topic silent): a device absent at run time, exit status 1."""
    t0 = time.monotonic()
    with Graph([_motion(preflight_deadline_s=2.0)], tmp_path / "logs", domain_id) as g:
        assert g.wait("motion", 60.0) == 1
    assert time.monotonic() - t0 < 60.0
    assert "pre-flight state:" in _log(tmp_path, "motion")


def test_slow_robot_state_refuses_the_start(tmp_path: Path, domain_id) -> None:
    """A measured rate is what the machine did: exit status 1 (a run-time failure), not 2
    (bad input), with the stream named slow and, on the simulated robot, the simulation
    behind (issue 49)."""
    with Graph([_arm(rate_hz=20.0), _motion(min_state_rate_hz=50.0)], tmp_path / "logs",
               domain_id) as g:
        assert g.wait("motion", 90.0) == 1
        assert g.wait("mock_arm", 0.1) is None          # the stand-in was still publishing
    log = _log(tmp_path, "motion")
    assert "pre-flight state_rate:" in log and "state stream was slow" in log
    assert "simulation is behind" in log


def _collision_profile(tmp_path: Path) -> Path:
    prof = yaml.safe_load((config_dir() / "robots" / "sim.yaml").read_text())
    prof["name"] = "sim_with_collision"
    prof["collision"] = {"service": "/service_server/set_force_torque_collision_behavior",
                         "type": "franka_msgs/srv/SetForceTorqueCollisionBehavior",
                         "request_file": "bringup/collision_thresholds.yaml"}
    out = tmp_path / "sim_with_collision.yaml"
    out.write_text(yaml.safe_dump(prof))
    return out


def test_collision_thresholds_unsettable_refuse_with_the_command(tmp_path: Path,
                                                                 domain_id) -> None:
    try:
        import franka_msgs  # noqa: F401
        pytest.skip("franka_msgs is installed: the service would be called")
    except ImportError:
        pass
    prof = str(_collision_profile(tmp_path))
    with Graph([_arm(), _motion(robot=prof)], tmp_path / "logs", domain_id) as g:
        assert g.wait("motion", 90.0) == 2
    log = _log(tmp_path, "motion")
    assert "pre-flight collision:" in log
    assert ("ros2 service call /service_server/set_force_torque_collision_behavior "
            "franka_msgs/srv/SetForceTorqueCollisionBehavior") in log


def test_collision_thresholds_set_by_hand_let_the_start_go_on(tmp_path: Path, listener,
                                                              active) -> None:
    prof = str(_collision_profile(tmp_path))
    with Graph([_arm(), _motion(robot=prof, collision_set_by_hand=True)], tmp_path / "logs",
               listener.domain_id) as g:
        assert active("motion", 90.0)
        assert g.wait("motion", 0.1) is None


def test_collision_thresholds_below_the_press_refuse(tmp_path: Path, domain_id) -> None:
    """The profile's request (upper force 25 N) against a scene whose max_force 22 N plus the
    tare's largest offset 5 N exceeds it: refused before any state is read."""
    scene = yaml.safe_load((config_dir() / "scene_sim.yaml").read_text())
    scene["press"]["max_force"] = 22.0
    path = tmp_path / "scene.yaml"
    path.write_text(yaml.safe_dump(scene))
    prof = str(_collision_profile(tmp_path))
    with Graph([_motion(robot=prof, scene_file=str(path), collision_set_by_hand=True)],
               tmp_path / "logs", domain_id) as g:
        assert g.wait("motion", 60.0) == 2
    assert "pre-flight collision:" in _log(tmp_path, "motion")


def test_probe_calls_stand_in_services(tmp_path: Path, listener) -> None:
    """The pre-flight's service call against real stand-in servers in another process
    (std_srvs SetBool; the controller refuses before the hardware is active, as
    ros2_control does)."""
    from std_srvs.srv import SetBool

    from tactex_ros.ros.preflight import Probe
    with Graph([_arm(recovery_standin="service")], tmp_path / "logs", listener.domain_id):
        probe = Probe(listener.ctx, "test_probe")
        try:
            assert probe.call(SetBool, "/tactex_test/set_hardware_active", {"data": False},
                              "success", 90.0).success      # the stand-in's start-up
            with pytest.raises(TrialError, match="success = false"):
                probe.call(SetBool, "/tactex_test/activate_controller", {"data": True},
                           "success", 5.0)
            assert probe.call(SetBool, "/tactex_test/set_hardware_active", {"data": True},
                              "success", 5.0).success
            assert probe.call(SetBool, "/tactex_test/activate_controller", {"data": True},
                              "success", 5.0).success
            t0 = time.monotonic()
            with pytest.raises(TrialError, match="not offered"):
                probe.call(SetBool, "/tactex_test/nothing_here", {"data": True}, "success",
                           1.0)
            assert 1.0 <= time.monotonic() - t0 < 15.0     # the deadline, not a hang
            with pytest.raises(InputError, match="no field"):
                probe.call(SetBool, "/tactex_test/set_hardware_active",
                           {"lower_force_thresholds_nominal": [1.0]}, "success", 5.0)
        finally:
            probe.close()


def _frames_folder(folder: Path, frames) -> Path:
    folder.mkdir()
    for i, f in enumerate(frames):
        cv2.imwrite(str(folder / f"frame_{i}.png"), f[:, :, ::-1])
    return folder


@pytest.mark.parametrize("start", ["contact", "no_contact"])
def test_gelsight_refuses_a_start_in_contact(octopi_press, tmp_path: Path, listener, active,
                                             start: str) -> None:
    frames = octopi_press("steel_wool", 1)
    i, _ = strongest_contact(frames)
    chosen = frames[i - 3:i + 3] if start == "contact" else frames[:6]
    rec = _frames_folder(tmp_path / "rec", chosen)
    node = NodeSpec("gelsight_node", "gelsight", {"device": str(rec), "fps": 20.0,
                                                  "warmup_frames": 0, "reference_frames": 5,
                                                  "crop_fraction": 0.0})
    with Graph([node], tmp_path / "logs", listener.domain_id) as g:
        if start == "contact":
            assert g.wait("gelsight", 60.0) == 2
            assert "pre-flight contact:" in _log(tmp_path, "gelsight")
        else:
            assert active("gelsight", 60.0)


def _check_wrench(listener, push_fz: float | None, extra: list[str], robot: str = "sim",
                  topic: str = "/check_wrench_test/wrench",
                  rate_hz: float = 200.0) -> tuple[int, str]:
    """Run `tactex robot check-wrench --robot <robot>` against a wrench the test's node
    publishes on ``topic`` with the profile's wrench QoS (its upstream publisher's: franka's
    QoS(1).best_effort()) at ``rate_hz``: 0.4 N until the command prompts, then ``push_fz``
    (None: no push). A topic other than the profile's is passed with --topic."""
    from tactex_ros.robot.robots import load_profile
    from tactex_ros.ros.adapter import qos_profile
    prof = load_profile(robot)
    pub = listener.node.create_publisher(WrenchStamped, topic, qos_profile(prof.wrench_qos))
    value = [0.4]
    stop = threading.Event()

    def publish() -> None:
        period, due = 1.0 / rate_hz, time.monotonic()
        while not stop.is_set():
            m = WrenchStamped()
            m.wrench.force.z = value[0]
            pub.publish(m)
            due += period
            time.sleep(max(0.0, due - time.monotonic()))
    th = threading.Thread(target=publish, daemon=True)
    th.start()
    where = [] if topic == prof.wrench_topic else ["--topic", topic]
    cmd = [sys.executable, "-c", "import sys; from tactex_ros.cli.main import main; "
           "sys.exit(main())", "robot", "check-wrench", "--robot", robot, *where,
           "--baseline-s", "1.0", "--deadline-s", "8.0"] + extra
    proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            env=ros_env(listener.domain_id))
    seen = []
    try:
        for line in proc.stderr:
            seen.append(line)
            if line.startswith("now push"):
                if push_fz is not None:
                    value[0] = push_fz
                break
        out, err = proc.communicate(timeout=60)
        assert out.strip().startswith("{"), f"no result; stderr: {''.join(seen)}{err}"
    finally:
        stop.set()
        th.join(timeout=2.0)
        if proc.poll() is None:
            proc.kill()
        listener.node.destroy_publisher(pub)
    return proc.returncode, out


def test_check_wrench_reads_frankas_wrench(listener) -> None:
    """The FR3 profile's wrench topic as franka_robot_state_broadcaster publishes it: best
    effort, keep last 1, 1 kHz (franka_ros2 v3.4.0 franka_robot_state_broadcaster.cpp:125,
    140-142; convenience_publish_rate 1000). A reliable reader would get nothing (issue 28);
    libfranka's counterforce reads an upward push as -z: force_sign -1 confirmed."""
    import json

    from tactex_ros.robot.robots import load_profile
    prof = load_profile("fr3_crisp")
    code, out = _check_wrench(listener, -7.6, [], robot="fr3_crisp", topic=prof.wrench_topic,
                              rate_hz=1000.0)
    res = json.loads(out)
    assert code == 0, out
    assert res["measured_force_sign"] == -1 and res["profile_force_sign"] == -1
    assert res["push_delta_fz_n"] == pytest.approx(-8.0, abs=0.01)
    assert res["samples"][0] >= 100          # the hands-off second, even at a fraction of 1 kHz


def test_check_wrench_reports_the_sign(listener) -> None:
    import json
    code, out = _check_wrench(listener, 8.4, [])
    res = json.loads(out)
    assert code == 0 and res["measured_force_sign"] == 1 and res["profile_force_sign"] == 1
    assert res["push_delta_fz_n"] == pytest.approx(8.0, abs=0.01)
    assert res["baseline_fz_n"] == pytest.approx(0.4, abs=0.01)
    code, out = _check_wrench(listener, -7.6, [])           # the other convention
    assert code == 1 and json.loads(out)["measured_force_sign"] == -1
    code, out = _check_wrench(listener, -7.6, ["--force-sign", "-1"])
    assert code == 0
    code, out = _check_wrench(listener, None, [])            # nobody pushed
    assert code == 1 and json.loads(out)["measured_force_sign"] == 0


@pytest.mark.parametrize("rate_hz,ok", [(200.0, True), (30.0, False)])
def test_panda_state_rate_through_the_probe(listener, rate_hz: float, ok: bool) -> None:
    """The pre-flight's sampling of the Panda profile's state topic, read with the profile's
    QoS, against a stand-in publishing with multipanda's QoS (SystemDefaultsQoS,
    franka_robot_state_broadcaster.cpp:45-46) at the bring-up's effective rate (frequency 250
    at a 1 kHz update: 200 Hz) and at multipanda's default 30 Hz. franka_msgs is not
    installable here, so the stand-in publishes std_msgs/Header on that topic: the rate and
    QoS are what is tested, not the message."""
    from rclpy.qos import QoSProfile
    from std_msgs.msg import Header

    from tactex_ros.robot import preflight as pf
    from tactex_ros.robot.robots import load_profile
    from tactex_ros.ros.adapter import qos_profile
    from tactex_ros.ros.preflight import Probe
    prof = load_profile("panda_crisp")
    pub = listener.node.create_publisher(Header, prof.state_topic, QoSProfile(depth=10))
    stop = threading.Event()

    def publish() -> None:
        period, due = 1.0 / rate_hz, time.monotonic()
        while not stop.is_set():
            pub.publish(Header())
            due += period
            time.sleep(max(0.0, due - time.monotonic()))
    th = threading.Thread(target=publish, daemon=True)
    th.start()
    probe = Probe(listener.ctx, "test_panda_probe")
    try:
        stamps, last = probe.sample(Header, prof.state_topic, qos_profile(prof.state_qos), 1.0,
                                    30.0)
    finally:
        probe.close()
        stop.set()
        th.join(timeout=2.0)
        listener.node.destroy_publisher(pub)
    assert last is not None
    problem = pf.state_problem(stamps, prof.min_state_rate_hz, 1.0, prof.state_topic)
    assert (problem is None) == ok, (pf.rate_hz(stamps), problem)
