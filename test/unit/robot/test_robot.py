"""Robot profiles (config/robots/) and the adapters per interface, pure (no rclpy.init)."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest
import yaml

from tactex_ros.ros import adapter
from tactex_ros.core.errors import InputError
from tactex_ros.ros.graph import describe, fixed_frame
from tactex_ros.core.paths import config_dir, config_names
from tactex_ros.robot.robots import (fill_message, import_interface, load_profile, parse_profile,
                                     with_profile)


def _fr3() -> dict:
    return yaml.safe_load((config_dir() / "robots" / "fr3_crisp.yaml").read_text())


def test_shipped_profiles_load() -> None:
    assert set(config_names("robots")) == {"fr3_crisp", "panda_crisp", "sim"}
    fr3, panda = load_profile("fr3_crisp"), load_profile("panda_crisp")
    assert fr3.frame_id == "fr3_link0" and panda.frame_id == "panda_link0"
    assert fr3.recovery.kind == "action" and [c.ok_field for c in fr3.recovery.then] == \
        ["ok", "ok"]
    assert panda.recovery.kind == "service" and panda.franka_state
    for p in (fr3, panda):
        # CRISP: plugin, /target_pose PoseStamped, one publisher at most
        assert (p.controller, p.plugin, p.target_topic, p.target_type, p.max_publishers) == (
            "crisp_cartesian_impedance_controller", "crisp_controllers/CartesianController",
            "/target_pose", "geometry_msgs/msg/PoseStamped", 1)
        assert p.collision.type == "franka_msgs/srv/SetForceTorqueCollisionBehavior"
        assert len(p.collision.request["upper_force_thresholds_nominal"]) == 6
    assert fr3.collision.service == "/service_server/set_force_torque_collision_behavior"
    # multipanda's FrankaMultiHardwareInterface prefixes its service nodes with the arm's ns
    assert panda.collision.service == \
        "/panda_param_service_server/set_force_torque_collision_behavior"
    assert panda.recovery.name == "/panda_error_recovery_service_server/error_recovery"
    assert panda.recovery.hold_target and not fr3.recovery.hold_target
    # franka_ros2 on Humble keeps controllers active after a fault: deactivated first, best
    # effort (a no-op on Jazzy), exactly those the re-activation activates again
    (before,), switch = fr3.recovery.before, fr3.recovery.then[-1]
    assert before.request["strictness"] == 1 and switch.request["strictness"] == 2
    assert sorted(before.request["deactivate_controllers"]) == \
        sorted(switch.request["activate_controllers"])
    # QoS of the upstream publishers: CRISP's current_pose SystemDefaultsQoS, franka's wrench
    # QoS(1).best_effort(), franka's and multipanda's full state SystemDefaultsQoS
    assert (fr3.pose_qos.reliability, fr3.pose_qos.depth) == ("reliable", 10)
    assert (fr3.wrench_qos.reliability, fr3.wrench_qos.depth) == ("best_effort", 1)
    assert (fr3.mode_qos.reliability, panda.state_qos.reliability) == ("reliable", "reliable")
    assert fr3.min_state_rate_hz == panda.min_state_rate_hz == 100.0
    assert (fr3.pose_topic, fr3.scene, panda.scene) == ("/current_pose", "scene.yaml",
                                                        "scene_panda.yaml")
    assert fr3.mode_type == "franka_msgs/msg/FrankaRobotState" and not fr3.franka_state


@pytest.mark.parametrize("path,value,field", [
    (("controller", "stiffness"), 5.0, "controller.stiffness"),
    (("target", "type"), "geometry_msgs/msg/Pose", "target.type"),
    (("force_sign",), 0.5, "force_sign"),
    (("controller", "target_filter"), 1.0, "controller.target_filter"),
    (("controller", "error_clip"), -0.1, "controller.error_clip"),
    (("target", "max_publishers"), -1, "target.max_publishers"),
    (("collision", "type"), "SetForceTorqueCollisionBehavior", "collision.type"),
    (("collision", "request_file"), "bringup/none.yaml", "collision.request_file"),
    (("recovery", "kind"), "reboot", "recovery.kind"),
    (("recovery", "type"), "franka_msgs/srv/ErrorRecovery", "recovery.type"),
    (("recovery", "then", 0, "type"), "controller_manager_msgs/SetHardwareComponentState",
     r"recovery\.then\.0\.type"),
    (("state", "topic"), "/x", "state: give either"),
    (("state", "mode_type"), "FrankaRobotState", "state.mode_type"),
    (("state", "wrench_qos", "reliability"), "fast", "state.wrench_qos.reliability"),
    (("state", "pose_qos", "depth"), 0, "state.pose_qos.depth"),
    (("state", "min_rate_hz"), -1.0, "state.min_rate_hz"),
    (("controller", "max_stiffness"), 900.0, "controller.stiffness.*clamp"),
    (("controller", "torque_filter"), 1.0, "controller.torque_filter"),
    (("recovery", "before", 0, "type"), "SwitchController", r"recovery\.before\.0\.type"),
    (("bogus",), 1, "bogus: unknown name"),
])
def test_profile_errors_name_the_field(path, value, field) -> None:
    d = _fr3()
    target = d
    for k in path[:-1]:
        target = target[k]
    target[path[-1]] = value
    with pytest.raises(InputError, match=field):
        parse_profile(d)


def test_node_settings_take_the_profiles_values_once() -> None:
    """Empty settings ('' / 0) are the profile's, given ones stay; the profile is parsed once
    per process (the same object) and again after the file changes."""
    from tactex_ros.ros.settings import MockArmSettings, MotionSettings
    prof = load_profile("fr3_crisp")
    assert load_profile("fr3_crisp") is prof
    s = with_profile(MotionSettings(robot="fr3_crisp", stiffness=800.0), prof)
    assert (s.stiffness, s.force_sign, s.target_topic) == (800.0, prof.force_sign,
                                                           prof.target_topic)
    assert s.min_state_rate_hz == prof.min_state_rate_hz and s.state_topic == prof.state_topic
    arm = with_profile(MockArmSettings(robot="sim", pose_topic="/p"), load_profile("sim"))
    assert (arm.pose_topic, arm.wrench_sign) == ("/p", load_profile("sim").force_sign)
    given = MotionSettings(robot="fr3_crisp", stiffness=700.0, force_sign=1, state_topic="/s",
                           pose_topic="/p", wrench_topic="/w", mode_topic="/m",
                           target_topic="/t", min_state_rate_hz=10.0)
    assert with_profile(given, prof) is given


def test_hold_target_never_below_the_surface() -> None:
    """The target a recovery leaves an active controller with: the measured position, raised
    to the platform's surface where a press left it below, inside the workspace."""
    from tactex_ros.robot.robots import hold_target
    lo, hi = (0.25, -0.45, 0.0), (0.75, 0.45, 0.5)
    assert hold_target((0.5, 0.1, 0.097), 0.1, lo, hi) == pytest.approx((0.5, 0.1, 0.1))
    assert hold_target((0.5, 0.1, 0.13), 0.1, lo, hi) == pytest.approx((0.5, 0.1, 0.13))
    assert hold_target((0.9, -0.6, 0.2), 0.1, lo, hi) == pytest.approx((0.75, -0.45, 0.2))


def test_qos_profile_is_the_publishers() -> None:
    from rclpy.qos import DurabilityPolicy, HistoryPolicy, ReliabilityPolicy
    q = adapter.qos_profile(load_profile("fr3_crisp").wrench_qos)
    assert (q.reliability, q.depth, q.history, q.durability) == (
        ReliabilityPolicy.BEST_EFFORT, 1, HistoryPolicy.KEEP_LAST, DurabilityPolicy.VOLATILE)
    q = adapter.qos_profile(load_profile("fr3_crisp").pose_qos)
    assert (q.reliability, q.depth) == (ReliabilityPolicy.RELIABLE, 10)


def test_missing_profile_and_interface() -> None:
    with pytest.raises(InputError, match="robot profile .ur5. not found.*fr3_crisp"):
        load_profile("ur5")
    with pytest.raises(InputError, match="franka_msgs"):
        import_interface("franka_msgs/action/ErrorRecovery")
    assert import_interface("std_srvs/srv/SetBool").__name__ == "SetBool"


def test_fill_message_names_unknown_fields() -> None:
    from std_srvs.srv import SetBool
    assert fill_message(SetBool.Request(), {"data": True}).data is True
    with pytest.raises(InputError, match="request.name"):
        fill_message(SetBool.Request(), {"name": "x"})


def test_float64_multiarray_target_roundtrip() -> None:
    q = np.array([1.0, 0.0, 0.0, 0.0])                      # sensor pointing down
    msg = adapter.target_msg("std_msgs/msg/Float64MultiArray", np.array([0.4, -0.2, 0.1]), q,
                             0.0, "panda_link0")
    assert len(msg.data) == 12
    r = np.array(msg.data[3:]).reshape(3, 3)
    np.testing.assert_allclose(r, np.diag([1.0, -1.0, -1.0]), atol=1e-12)
    assert msg.data[11] != 0.0          # multipanda applies the orientation only then
    xyz, q2 = adapter.target_to_array(msg)
    np.testing.assert_allclose(xyz, [0.4, -0.2, 0.1])
    assert abs(abs(float(np.dot(q, q2))) - 1.0) < 1e-9
    rng = np.random.default_rng(0)
    for _ in range(20):
        qr = rng.normal(size=4)
        qr /= np.linalg.norm(qr)
        back = adapter.matrix_to_quat(adapter.quat_to_matrix(qr))
        assert abs(abs(float(np.dot(qr, back))) - 1.0) < 1e-9
    pose = adapter.target_msg("geometry_msgs/msg/PoseStamped", xyz, q, 1.0, "fr3_link0")
    assert pose.header.frame_id == "fr3_link0"


def test_franka_state_and_wrench_sign() -> None:
    t = np.eye(4)
    t[:3, 3] = [0.5, 0.1, 0.2]
    st = SimpleNamespace(o_t_ee=list(t.T.ravel()),           # column-major as libfranka
                         o_f_ext_hat_k=[0.0, 3.0, -4.0, 0.0, 0.0, 0.0], robot_mode=4)
    pos, fn, mag, mode = adapter.franka_state_to_array(st, -1.0)
    np.testing.assert_allclose(pos, [0.5, 0.1, 0.2])
    assert fn == pytest.approx(4.0) and mag == pytest.approx(5.0)
    assert mode == adapter.FRANKA_MODE_REFLEX
    with pytest.raises(InputError, match="o_t_ee"):
        adapter.franka_state_to_array(SimpleNamespace(o_t_ee=[0.0] * 3,
                                                      o_f_ext_hat_k=[0.0] * 6), 1.0)


def test_graph_checks_profile_against_scene(tmp_path) -> None:
    nodes = describe(True)
    assert fixed_frame(nodes) == "fr3_link0"
    motion = next(n for n in nodes if n.name == "motion")
    arm = next(n for n in nodes if n.name == "mock_arm")
    assert motion.parameters["robot"] == arm.parameters["robot"] == "sim"
    with pytest.raises(InputError, match="panda_link0"):
        describe(False, robot="panda_crisp", scene_file=config_dir() / "scene.yaml")
    # the Panda's default scene is in its base frame, the FR3's default profile is CRISP's
    assert fixed_frame(describe(False, robot="panda_crisp")) == "panda_link0"
    motion = next(n for n in describe(False) if n.name == "motion")
    assert motion.parameters["robot"] == "fr3_crisp"
    f = tmp_path / "motion.yaml"
    f.write_text(yaml.safe_dump({"motion": {"ros__parameters": {"stiffness": 800.0,
                                                                "rate_hz": 100.0}}}))
    motion = next(n for n in describe(True, motion_file=f) if n.name == "motion")
    assert motion.parameters["stiffness"] == 800.0 and motion.parameters["rate_hz"] == 100.0
    f.write_text(yaml.safe_dump({"rate_hz": 1e9}))
    with pytest.raises(InputError, match="rate_hz"):
        describe(True, motion_file=f)
    with pytest.raises(InputError, match=r"platforms\[0\].*workspace.min.*60 N/m"):
        describe(True, motion={"stiffness": 60.0})
