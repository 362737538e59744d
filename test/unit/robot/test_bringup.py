"""The bring-up the lab runs (config/bringup/) against the robot profiles: the controller's
parameters equal the profile's, the profile's law equals those parameters (CRISP's names and
bounds), and the collision thresholds leave room for the press. Pure (YAML files only)."""

from __future__ import annotations

import pytest
import yaml

from tactex_ros.core.schema import flatten
from tactex_ros.core.paths import config_dir
from tactex_ros.robot.robots import load_profile
from tactex_ros.robot.scene import load_scene

BRINGUP = config_dir() / "bringup"
CONTROLLER = "crisp_cartesian_impedance_controller"


def _yaml(path) -> dict:
    return yaml.safe_load(path.read_text())


def _fr3_files() -> tuple[dict, dict]:
    """(controller_manager parameters, {node: ros__parameters}) of the FR3 bring-up."""
    doc = _yaml(BRINGUP / "fr3_crisp_controllers.yaml")["/**"]
    nodes = {k: v["ros__parameters"] for k, v in doc.items()}
    return nodes.pop("controller_manager"), nodes


def _controller_params(profile: str) -> dict:
    """The CRISP controller's parameters as the profile's bring-up file sets them (flat)."""
    if profile == "fr3_crisp":
        return flatten(_fr3_files()[1][CONTROLLER])
    doc = _yaml(BRINGUP / "panda_crisp_controller.yaml")
    return flatten(doc[CONTROLLER]["ros__parameters"])


@pytest.mark.parametrize("name", ["fr3_crisp", "panda_crisp"])
def test_bringup_sets_the_profiles_parameters(name: str) -> None:
    prof = load_profile(name)
    got = _controller_params(name)
    assert prof.controller == CONTROLLER and prof.parameters
    for key, value in prof.parameters.items():
        assert key in got, (name, key)
        assert got[key] == value, (name, key, got[key], value)
    assert got["base_frame"] == prof.frame_id
    arm = "fr3" if name == "fr3_crisp" else "panda"
    assert got["joints"] == [f"{arm}_joint{i}" for i in range(1, 8)]
    assert got["end_effector_frame"] == f"{arm}_link8"
    assert got.get("type", prof.plugin) == prof.plugin


def test_fr3_bringup_registers_the_controllers_and_rates() -> None:
    prof = load_profile("fr3_crisp")
    cm, nodes = _fr3_files()
    assert cm["update_rate"] == prof.law.rate_hz
    assert cm[CONTROLLER]["type"] == prof.plugin == "crisp_controllers/CartesianController"
    assert cm["crisp_pose_broadcaster"]["type"] == "crisp_controllers/PoseBroadcaster"
    assert cm["franka_robot_state_broadcaster"]["type"] == \
        "franka_robot_state_broadcaster/FrankaRobotStateBroadcaster"
    # the pose tactex reads is the controller's end-effector frame, in the profile's base frame
    pose, ctrl = nodes["crisp_pose_broadcaster"], nodes[CONTROLLER]
    assert (pose["end_effector_frame"], pose["joints"], pose["base_frame"]) == (
        ctrl["end_effector_frame"], ctrl["joints"], prof.frame_id)
    # every controller the recovery re-activates is registered
    switch = prof.recovery.then[-1].request["activate_controllers"]
    assert set(switch) <= set(k for k, v in cm.items() if isinstance(v, dict))


@pytest.mark.parametrize("name", ["fr3_crisp", "panda_crisp"])
def test_profile_law_is_crisps_law_of_those_parameters(name: str) -> None:
    """stiffness = task.k_pos_x/y/z, damping task.d_pos_* = 2 sqrt(K) set explicitly, target_filter =
    filter.target_pose, error_clip = task.error_clip.x/y/z (limit_error), force step from
    max_delta_tau (limit_torques); each inside CRISP's declared bounds
    (CRISP 2.1.0 src/cartesian_controller.yaml:27-63, 231-237)."""
    raw = _yaml(config_dir() / "robots" / f"{name}.yaml")["controller"]
    law, p = load_profile(name).law, _controller_params(name)
    for ax in "xyz":
        assert p[f"task.k_pos_{ax}"] == law.stiffness and 0.0 <= law.stiffness <= 5000.0
        assert p[f"task.d_pos_{ax}"] == raw["damping"] == pytest.approx(law.d, abs=1e-4)
        assert p[f"task.error_clip.{ax}"] == law.clip["xyz".index(ax)]
    assert law.d == pytest.approx(2.0 * law.stiffness ** 0.5)
    assert p["filter.target_pose"] == law.target_filter and 0.1 <= law.target_filter <= 1.0
    assert p["limit_error"] is True and p["limit_torques"] is True
    assert p["max_delta_tau"] == raw["max_delta_tau"]
    assert law.max_force_step == pytest.approx(raw["max_delta_tau"] / raw["torque_lever_m"])
    assert p["use_operational_space"] is False and p["stop_commands"] is False


@pytest.mark.parametrize("name", ["fr3_crisp", "panda_crisp"])
def test_collision_thresholds_leave_room_for_the_press(name: str) -> None:
    """franka's reflex must not trip during a press: the upper Cartesian force thresholds are
    at least twice the scene's max_force, and the controller cannot push with more than
    max_force at rest (K x error_clip)."""
    prof = load_profile(name)
    scene = load_scene(config_dir() / prof.scene)
    req = prof.collision.request
    assert {k: len(v) for k, v in req.items()} == {
        "lower_torque_thresholds_nominal": 7, "upper_torque_thresholds_nominal": 7,
        "lower_force_thresholds_nominal": 6, "upper_force_thresholds_nominal": 6}
    for lo, hi in (("lower_torque_thresholds_nominal", "upper_torque_thresholds_nominal"),
                   ("lower_force_thresholds_nominal", "upper_force_thresholds_nominal")):
        assert all(0 < a <= b for a, b in zip(req[lo], req[hi], strict=True)), (lo, hi)
    assert min(req["upper_force_thresholds_nominal"][:3]) >= 2.0 * scene.press.max_force
    assert min(req["lower_force_thresholds_nominal"][:3]) > scene.press.max_force
    assert prof.law.max_static_force <= scene.press.max_force


@pytest.mark.parametrize("name", ["fr3_crisp", "panda_crisp"])
def test_hand_guiding_controller_has_no_translational_stiffness(name: str) -> None:
    """crisp_gravity_compensation (for measuring the scene by hand) holds the orientation only,
    on the same joints and frames as the impedance controller."""
    if name == "fr3_crisp":
        cm, nodes = _fr3_files()
        assert cm["crisp_gravity_compensation"]["type"] == "crisp_controllers/CartesianController"
        g = flatten(nodes["crisp_gravity_compensation"])
    else:
        g = flatten(_yaml(BRINGUP / "panda_crisp_controller.yaml")
                    ["crisp_gravity_compensation"]["ros__parameters"])
    c = _controller_params(name)
    assert [g[f"task.k_pos_{a}"] for a in "xyz"] == [0.0, 0.0, 0.0]
    assert min(g[f"task.k_rot_{a}"] for a in "xyz") > 0.0
    for key in ("joints", "end_effector_frame", "base_frame"):
        assert g[key] == c[key]


def test_fr3_bringup_keeps_frankas_real_time_settings_and_rates() -> None:
    """franka's controller_manager settings (franka_ros2 v3.4.0 franka_bringup/config/
    controllers.yaml:9-13) and state rates at or above the profile's pre-flight minimum."""
    prof = load_profile("fr3_crisp")
    cm, nodes = _fr3_files()
    assert cm["thread_priority"] == 98
    assert cm["overruns"]["manage"] is False
    assert nodes["franka_robot_state_broadcaster"]["convenience_publish_rate"] >= \
        prof.min_state_rate_hz
    assert nodes["crisp_pose_broadcaster"]["publish_frequency"] >= prof.min_state_rate_hz


def test_panda_bringup_sets_the_state_broadcasters_rate() -> None:
    """multipanda's broadcaster publishes at its `frequency` (default 30 Hz); the bring-up
    sets it so that even one skipped cycle per publish (the gap is measured from the clock
    after publishing) stays at or above the profile's minimum."""
    prof = load_profile("panda_crisp")
    b = _yaml(BRINGUP / "panda_crisp_controller.yaml")["franka_robot_state_broadcaster"][
        "ros__parameters"]
    assert b["type"] == "franka_robot_state_broadcaster/FrankaRobotStateBroadcaster"
    assert b["arm_id"] == "panda" and isinstance(b["frequency"], int)
    update_hz = prof.law.rate_hz
    worst = update_hz / (update_hz / b["frequency"] + 1)
    assert worst >= prof.min_state_rate_hz


@pytest.mark.parametrize("name", ["fr3_crisp", "panda_crisp"])
def test_bringup_sets_crisps_filters_and_clamp(name: str) -> None:
    """Releases after v1.0.0 filter joint state and output torque (default 0.5) and later ones
    clamp the translational stiffness (default 900 N/m): the bring-up sets them explicitly, as
    the profile (which the mock arm models) says, and the clamp never below the stiffness."""
    prof, p = load_profile(name), _controller_params(name)
    assert p["filter.q"] == p["filter.dq"] == prof.joint_filter
    assert p["filter.output_torque"] == prof.torque_filter
    assert p["variable_max_stiffness.translational"] == prof.max_stiffness >= prof.stiffness
    for key in ("filter.q", "filter.dq", "filter.q_ref", "filter.output_torque"):
        assert 0.0 <= p[key] <= 1.0            # CRISP 2.1.0 src/cartesian_controller.yaml:238-262


#: The traced list of CRISP's CartesianController parameter declarations (names, defaults,
#: bounds and lines of src/cartesian_controller.yaml at the release the profiles cite), written
#: by scripts/crisp_params.py from the upstream source.
UPSTREAM = config_dir() / "upstream" / "crisp_cartesian_controller.yaml"


def _upstream() -> dict[str, dict]:
    """name -> {type, default?, bounds?, line} of the traced CRISP release."""
    return {p["name"]: p for p in _yaml(UPSTREAM)["parameters"]}


def _sentinels() -> list[str]:
    """The parameters whose upstream default is the -1 sentinel ("if negative, computed as
    2 sqrt(stiffness)"). The controller tested nullspace.damping with
    `if (params_.nullspace.damping)`, true for -1, and damped with -1 x weights (issue 54)."""
    return [n for n, p in _upstream().items() if p.get("default") == -1.0]


def _declared(name: str, upstream: dict[str, dict]) -> dict | None:
    """The upstream declaration a bring-up key sets (a per-joint key maps to __map_joints)."""
    if name in upstream:
        return upstream[name]
    parts = name.split(".")
    if len(parts) >= 3:
        mapped = ".".join(parts[:-2] + ["__map_joints", parts[-1]])
        return upstream.get(mapped)
    return None


def test_the_traced_list_names_the_known_sentinels() -> None:
    """The list is the release's: the seven -1 defaults (task.d_pos_*, task.d_rot_*,
    nullspace.damping) and the 2.2.0 stiffness clamp are in it, each with a line."""
    up = _upstream()
    assert set(_sentinels()) == {f"task.d_{k}_{a}" for k in ("pos", "rot") for a in "xyz"} | {
        "nullspace.damping"}
    assert up["variable_max_stiffness.translational"]["default"] == 900.0
    assert all(isinstance(p["line"], int) and p["line"] > 0 for p in up.values())


def _crisp_controllers(path) -> dict[str, dict]:
    """Every CRISP CartesianController of a bring-up file: name -> flat ros__parameters."""
    nodes: dict[str, dict] = {}

    def walk(d: dict) -> None:
        for k, v in d.items():
            if isinstance(v, dict):
                if "ros__parameters" in v:
                    nodes[k] = v["ros__parameters"]
                walk(v)
    data = _yaml(path)
    walk(data)
    names = set()
    for key, value in flatten(data).items():
        parts = key.split(".")
        if parts[-1] == "type" and value == "crisp_controllers/CartesianController":
            names.add(parts[-3] if parts[-2] == "ros__parameters" else parts[-2])
    return {n: flatten(nodes[n]) for n in names}


@pytest.mark.parametrize("bringup", ["fr3_crisp_controllers.yaml", "panda_crisp_controller.yaml"])
def test_no_crisp_controller_is_left_on_a_minus_one_sentinel(bringup: str) -> None:
    """Every CRISP controller of the bring-up (the impedance controller and the gravity
    compensation used while hand-guiding) sets each parameter whose upstream default is the
    -1 sentinel, none of them negative, and nullspace.damping positive."""
    ctrls = _crisp_controllers(config_dir() / "bringup" / bringup)
    assert len(ctrls) == 2, ctrls.keys()
    assert len(_sentinels()) == 7
    for name, p in ctrls.items():
        for key in _sentinels():
            assert key in p, (name, key)
            assert p[key] >= 0.0, (name, key, p[key])
        assert p["nullspace.damping"] > 0.0, name


@pytest.mark.parametrize("bringup", ["fr3_crisp_controllers.yaml", "panda_crisp_controller.yaml"])
def test_every_crisp_parameter_a_bringup_sets_is_declared_upstream(bringup: str) -> None:
    """Each name a CRISP controller of the bring-up sets is one the traced release declares
    (a misspelt or removed name would be declared by ros2_control and never read), with a value
    of the declared type and inside the declared bounds (else the controller fails to
    configure)."""
    up = _upstream()
    kinds = {"double": (int, float), "bool": (bool,), "string": (str,), "string_array": (list,),
             "double_array": (list,)}
    for name, p in _crisp_controllers(config_dir() / "bringup" / bringup).items():
        for key, value in p.items():
            if key == "type":          # the controller_manager's plugin name, not CRISP's
                continue
            decl = _declared(key, up)
            assert decl is not None, (name, key)
            assert isinstance(value, kinds[decl["type"]]), (name, key, value, decl["type"])
            if decl["type"] == "double":
                assert not isinstance(value, bool), (name, key)
            if "bounds" in decl:
                lo, hi = decl["bounds"]
                assert lo <= value <= hi, (name, key, value, decl["bounds"])
