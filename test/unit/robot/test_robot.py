"""Robot profiles (config/robots/) and the adapters per interface, pure (no rclpy.init)."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest
import yaml

from tactex_ros.ros import adapter
from tactex_ros.core.errors import InputError
from tactex_ros.ros.graph import describe, fixed_frame
from tactex_ros.paths import config_dir, config_names
from tactex_ros.robot.robots import fill_message, import_interface, load_profile, parse_profile


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
    assert panda.collision.service == "/param_service_server/set_force_torque_collision_behavior"
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
