"""Robot profiles: which controller, topics, message types and recovery interface a robot stack
has (``config/robots/<name>.yaml``), validated once; every error names the field.

Pure Python (no rclpy). A profile says:

- ``frame_id``: the robot's base frame (scene positions, rviz fixed frame);
- ``controller``: the Cartesian impedance controller the motion node talks to (``name`` in the
  controller manager, ``plugin`` its pluginlib type) and its translational law, which the press
  relies on and the mock arm runs (``press.ControlLaw``): ``stiffness`` [N/m] (the press
  commands the equilibrium ``force / stiffness`` below the surface), ``damping`` [N s/m]
  (<= 0: ``2 sqrt(stiffness)``), ``rate_hz``, ``target_filter`` (EMA weight kept of the
  filtered target per cycle), ``error_clip`` [m] (0 = none), ``max_delta_tau`` [N m per joint
  and cycle] (0 = none) over ``torque_lever_m`` [m]; ``parameters``: the controller's own
  parameters (upstream names) as the shipped bring-up sets them; ``max_stiffness`` [N/m]
  (CRISP's translational stiffness clamp, ``variable_max_stiffness.translational``),
  ``joint_filter`` and ``torque_filter`` (CRISP's EMA weights kept of the previous joint state
  and output torque per cycle, ``filter.q``/``filter.dq`` and ``filter.output_torque``; 0 =
  none): what the mock arm models besides the law;
- ``target``: ``topic`` and ``type``: ``geometry_msgs/msg/PoseStamped`` or
  ``std_msgs/msg/Float64MultiArray`` (multipanda_ros2 layout: x y z, then the rotation matrix
  row by row);
- ``state``: either ``pose_topic`` + ``wrench_topic`` (PoseStamped + WrenchStamped, as
  franka_robot_state_broadcaster publishes them) or ``topic`` + ``type`` of a franka state
  message with ``o_t_ee`` (16, column-major), ``o_f_ext_hat_k`` (6) and ``robot_mode``
  (multipanda_ros2's ``franka_msgs/msg/FrankaState``); optionally ``mode_topic`` + ``mode_type``:
  a full state message whose ``robot_mode`` reports a reflex or a user stop (franka_ros2's
  ``franka_msgs/msg/FrankaRobotState``; read only where that type is installed); each topic's
  QoS (``pose_qos``, ``wrench_qos``, ``qos``, ``mode_qos``: ``reliability`` and ``depth``)
  equal to its upstream publisher's, and ``min_rate_hz``: the pre-flight's lowest acceptable
  rate of each state topic [Hz], set from the rate the shipped bring-up publishes at;
- ``force_sign``: normal force = ``force_sign * f_z`` of the base-frame wrench;
- ``scene``: the default scene file under ``config/`` (its ``frame_id`` is the profile's);
- ``collision`` (optional): franka's collision-threshold service (``service``, ``type``) and
  ``request_file``, the request the press needs (a YAML file under ``config/``);
- ``recovery``: ``kind`` (``action``, ``service`` or ``none``), ``name``, ``type``,
  ``ok_field`` (service: the response field that says it worked), and ``then``: the service
  calls that re-activate hardware and controllers after recovery, in order (``service``,
  ``type``, ``request`` fields, ``ok_field``); ``before``: service calls made before the
  recovery (franka_ros2 on Humble: deactivate the controllers, which stay active after a
  fault there); ``hold_target``: publish a hold target at the measured position (never below
  the platform's surface) before recovery, for stacks whose controller stays active and
  resumes its last target when the recovery restarts the control loop (multipanda_ros2).
"""

from __future__ import annotations

import importlib
from dataclasses import dataclass, field
from functools import cache
from pathlib import Path
from typing import Annotated, Any, Literal, TypeVar
from collections.abc import Sequence

from pydantic import StringConstraints, field_validator, model_validator

from ..core.schema import FieldError, Schema, param
from ..core.errors import InputError
from ..core.paths import config_dir, config_file, read_yaml
from .mock_world import ControlLaw

POSE_STAMPED = "geometry_msgs/msg/PoseStamped"
FLOAT64_MULTIARRAY = "std_msgs/msg/Float64MultiArray"
TARGET_TYPES = (POSE_STAMPED, FLOAT64_MULTIARRAY)
RECOVERY_KINDS = ("action", "service", "none")
RELIABILITIES = ("reliable", "best_effort")


@dataclass(frozen=True)
class Qos:
    """A topic's QoS as its upstream publisher creates it: ``reliability`` (reliable or
    best_effort), history keep-last ``depth``, durability volatile. The default is rclcpp's
    ``SystemDefaultsQoS()`` as the RMWs give it (reliable, keep last 10)."""

    reliability: str = "reliable"
    depth: int = 10


@dataclass(frozen=True)
class ServiceCall:
    """One service call of the re-activation sequence."""

    service: str
    type: str
    request: dict[str, Any]
    ok_field: str


@dataclass(frozen=True)
class Recovery:
    kind: str = "none"                   # action | service | none
    name: str = ""
    type: str = ""
    ok_field: str = ""                   # service response field (action: goal status)
    then: tuple[ServiceCall, ...] = ()
    before: tuple[ServiceCall, ...] = ()     # calls before the recovery itself
    hold_target: bool = False                # publish a hold target before the recovery


@dataclass(frozen=True)
class Collision:
    """franka's collision-threshold service and the request (a mapping) the press needs."""

    service: str
    type: str
    request: dict[str, Any]
    request_file: str                    # where the request was read (config-relative)


@dataclass(frozen=True)
class RobotProfile:
    name: str
    frame_id: str
    controller: str
    stiffness: float                     # N/m, translational, of the impedance controller
    target_topic: str
    target_type: str
    pose_topic: str = ""
    wrench_topic: str = ""
    state_topic: str = ""
    state_type: str = ""                 # "" = PoseStamped + WrenchStamped
    mode_topic: str = ""                 # optional: robot_mode of a full state message
    mode_type: str = ""
    force_sign: float = 1.0
    law: ControlLaw | None = None        # the controller's translational law (None: from stiffness)
    plugin: str = ""                     # the controller's pluginlib type
    parameters: dict[str, Any] = field(default_factory=dict)   # upstream names -> values
    max_publishers: int = 0              # the controller ignores targets beyond this many (0: no)
    collision: Collision | None = None
    recovery: Recovery = field(default_factory=Recovery)
    scene: str = "scene.yaml"            # the default scene under config/ (in frame_id)
    notes: str = ""
    min_state_rate_hz: float = 50.0      # the pre-flight's lowest state rate [Hz]
    pose_qos: Qos = field(default_factory=Qos)
    wrench_qos: Qos = field(default_factory=Qos)
    state_qos: Qos = field(default_factory=Qos)
    mode_qos: Qos = field(default_factory=Qos)
    max_stiffness: float = float("inf")  # N/m, the controller's translational clamp
    joint_filter: float = 0.0            # EMA weight kept of the previous q, dq per cycle
    torque_filter: float = 0.0           # EMA weight kept of the previous output torque

    def __post_init__(self) -> None:
        if self.law is None:
            object.__setattr__(self, "law", ControlLaw(stiffness=self.stiffness))

    @property
    def franka_state(self) -> bool:
        return bool(self.state_type)


Text = Annotated[str, StringConstraints(min_length=1)]


def _interface(*kinds: str) -> Any:
    """A ROS interface name ``package/<kind>/Name`` for one of ``kinds``."""
    return Annotated[str, StringConstraints(pattern=rf"^[^/]+/({'|'.join(kinds)})/[^/]+$")]


class ControllerSpec(Schema):
    name: Text = param(..., "the Cartesian impedance controller's name in the controller "
                            "manager")
    plugin: str = param("", "its pluginlib type (package/Class)")
    stiffness: float = param(..., "translational stiffness [N/m]", 10.0, 1e6)
    damping: float = param(0.0, "translational damping [N s/m] (<= 0: 2 sqrt(stiffness))",
                           -1.0, 1e5)
    rate_hz: float = param(1000.0, "control loop rate [Hz]", 1.0, 1e4)
    target_filter: float = param(0.0, "EMA weight kept of the filtered target per control "
                                      "cycle (0 = no filter)", 0.0, 0.999)
    error_clip: float = param(0.0, "pose error clipped along z [m] (0 = not clipped): at "
                                   "rest the press pushes with at most stiffness x this",
                              0.0, 10.0)
    lateral_error_clip: float = param(0.0, "pose error clipped along x and y [m] (0 = "
                                           "error_clip): the travel's speed is at most "
                                           "stiffness x this / damping", 0.0, 10.0)
    max_delta_tau: float = param(0.0, "joint torque change per cycle at most [N m] (0 = no "
                                      "limit)", 0.0, 100.0)
    torque_lever_m: float = param(0.8, "longest lever from a joint to the sensor [m]: a "
                                       "torque step max_delta_tau is a force step "
                                       "max_delta_tau / torque_lever_m", 0.05, 2.0)
    parameters: dict[str, Any] = param({}, "the controller's parameters (upstream names) as "
                                           "the shipped bring-up sets them")
    max_stiffness: float = param(1e6, "the controller clamps its translational stiffness to "
                                      "this [N/m] (CRISP: variable_max_stiffness.translational)",
                                 10.0, 1e6)
    joint_filter: float = param(0.0, "EMA weight kept of the previous joint position and "
                                     "velocity per cycle (CRISP: filter.q, filter.dq; 0 = none)",
                                0.0, 0.999)
    torque_filter: float = param(0.0, "EMA weight kept of the previous output torque per "
                                      "cycle (CRISP: filter.output_torque; 0 = none)",
                                 0.0, 0.999)

    @model_validator(mode="after")
    def _not_clamped(self) -> ControllerSpec:
        if self.stiffness > self.max_stiffness:
            raise FieldError("stiffness", f"{self.stiffness:g} N/m is above max_stiffness "
                                          f"{self.max_stiffness:g} N/m: the controller would "
                                          "clamp it (raise its clamp in the bring-up and here)")
        return self

    def law(self) -> ControlLaw:
        inf = float("inf")
        return ControlLaw(stiffness=self.stiffness, damping=self.damping, rate_hz=self.rate_hz,
                          target_filter=self.target_filter,
                          error_clip=self.error_clip or inf,
                          lateral_error_clip=self.lateral_error_clip,
                          max_force_step=(self.max_delta_tau / self.torque_lever_m
                                          if self.max_delta_tau else inf),
                          max_stiffness=self.max_stiffness, state_filter=self.joint_filter,
                          output_filter=self.torque_filter)


class TargetSpec(Schema):
    topic: Text = param(..., "equilibrium target topic")
    type: Literal[POSE_STAMPED, FLOAT64_MULTIARRAY] = param(..., "target message type")
    max_publishers: int = param(0, "the controller ignores targets while more publishers than "
                                   "this are on the topic (0 = no such check)", 0, 100)


class QosSpec(Schema):
    reliability: Literal[RELIABILITIES] = param("reliable", "the upstream publisher's "
                                                            "reliability")
    depth: int = param(10, "its keep-last history depth", 1, 1000)

    def qos(self) -> Qos:
        return Qos(reliability=self.reliability, depth=self.depth)


class StateSpec(Schema):
    """Either ``pose_topic`` + ``wrench_topic`` (optionally ``mode_topic`` + ``mode_type``) or
    ``topic`` + ``type`` of a franka state message; each with its upstream publisher's QoS."""

    pose_topic: str = param("", "PoseStamped state topic")
    wrench_topic: str = param("", "WrenchStamped state topic")
    topic: str = param("", "franka state message topic")
    type: _interface("msg") | Literal[""] = param("", "franka state message type")
    mode_topic: str = param("", "robot_mode of a full state message: topic")
    mode_type: _interface("msg") | Literal[""] = param("", "... and its type")
    pose_qos: QosSpec = QosSpec()
    wrench_qos: QosSpec = QosSpec()
    qos: QosSpec = QosSpec()
    mode_qos: QosSpec = QosSpec()
    min_rate_hz: float = param(50.0, "the pre-flight refuses state topics slower than this "
                                     "[Hz]", 0.0, 10000.0)

    @model_validator(mode="after")
    def _one_kind(self) -> StateSpec:
        given = self.model_fields_set - {"pose_qos", "wrench_qos", "qos", "mode_qos",
                                         "min_rate_hz"}
        if given & {"topic", "type"}:
            if given & {"pose_topic", "wrench_topic"}:
                raise ValueError("give either topic + type (a franka state message) or "
                                 "pose_topic + wrench_topic, not both")
            need = ("topic", "type")
        else:
            need = ("pose_topic", "wrench_topic") + (
                ("mode_topic", "mode_type") if given & {"mode_topic", "mode_type"} else ())
        for name in need:
            if not getattr(self, name):
                raise FieldError(name, "expected a non-empty string")
        return self


class ServiceCallSpec(Schema):
    service: Text = param(..., "service name")
    type: _interface("srv") = param(..., "service type")
    request: dict[str, Any] = param({}, "request fields")
    ok_field: Text = param(..., "the response field that says it worked")


class RecoverySpec(Schema):
    kind: Literal[RECOVERY_KINDS] = param("none", "recovery interface")
    name: str = param("", "action or service name")
    type: str = param("", "action or service type")
    ok_field: str = param("", "service: the response field that says it worked")
    then: list[ServiceCallSpec] = param([], "re-activation calls after recovery, in order")
    before: list[ServiceCallSpec] = param([], "calls before the recovery, in order (e.g. "
                                              "deactivate controllers that stay active after "
                                              "a fault)")
    hold_target: bool = param(False, "publish a hold target at the measured position (not "
                                     "below the platform's surface) before the recovery: "
                                     "the controller stays active through it")

    @model_validator(mode="after")
    def _complete(self) -> RecoverySpec:
        if self.kind == "none":
            return self
        if not self.name:
            raise FieldError("name", "expected a non-empty string")
        kind = "action" if self.kind == "action" else "srv"
        parts = self.type.split("/")
        if len(parts) != 3 or parts[1] != kind or not all(parts):
            raise FieldError("type", f"expected 'package/{kind}/Name', got {self.type!r}")
        if self.kind == "service" and not self.ok_field:
            raise FieldError("ok_field", "expected a non-empty string")
        return self


class CollisionSpec(Schema):
    service: Text = param(..., "franka's collision-threshold service")
    type: _interface("srv") = param(..., "its type")
    request_file: Text = param(..., "the request the press needs: a YAML file under config/")


class ProfileFile(Schema):
    """A robot profile file (``config/robots/<name>.yaml``) as written."""

    name: Text = param(..., "profile name")
    frame_id: Text = param(..., "the robot's base frame")
    controller: ControllerSpec
    target: TargetSpec
    state: StateSpec
    force_sign: float = param(1.0, "normal force = force_sign * f_z (1 or -1)")
    collision: CollisionSpec | None = param(None, "franka's collision thresholds for the press")
    recovery: RecoverySpec = RecoverySpec()
    scene: Text = param("scene.yaml", "the default scene: a file under config/ in frame_id")
    notes: str = param("", "free text")

    @field_validator("force_sign")
    @classmethod
    def _sign(cls, v: float) -> float:
        if v not in (1.0, -1.0):
            raise ValueError(f"1 or -1, got {v!r}")
        return v


def parse_profile(data: Any, origin: str = "robot profile") -> RobotProfile:
    """Validate a profile mapping; InputError names every bad field (``controller.stiffness``,
    ``recovery.then.0.type``)."""
    f = ProfileFile.check(data, origin)
    st = f.state
    state = ({"state_topic": st.topic, "state_type": st.type} if st.topic else
             {"pose_topic": st.pose_topic, "wrench_topic": st.wrench_topic,
              "mode_topic": st.mode_topic, "mode_type": st.mode_type})
    rec = f.recovery

    def calls(specs: list[ServiceCallSpec]) -> tuple[ServiceCall, ...]:
        return tuple(ServiceCall(service=c.service, type=c.type, request=c.request,
                                 ok_field=c.ok_field) for c in specs)
    recovery = Recovery() if rec.kind == "none" else Recovery(
        kind=rec.kind, name=rec.name, type=rec.type, ok_field=rec.ok_field,
        then=calls(rec.then), before=calls(rec.before), hold_target=rec.hold_target)
    c = f.controller
    try:
        law = c.law()
    except ValueError as exc:
        raise InputError(f"{origin}: controller: {exc}") from None
    return RobotProfile(
        name=f.name, frame_id=f.frame_id, controller=c.name, plugin=c.plugin,
        stiffness=float(c.stiffness), law=law, parameters=dict(c.parameters),
        target_topic=f.target.topic, target_type=f.target.type,
        max_publishers=f.target.max_publishers, force_sign=float(f.force_sign),
        collision=_collision(f.collision, origin), recovery=recovery, scene=f.scene,
        notes=f.notes, min_state_rate_hz=float(st.min_rate_hz), pose_qos=st.pose_qos.qos(),
        wrench_qos=st.wrench_qos.qos(), state_qos=st.qos.qos(), mode_qos=st.mode_qos.qos(),
        max_stiffness=float(c.max_stiffness), joint_filter=float(c.joint_filter),
        torque_filter=float(c.torque_filter), **state)


def _collision(spec: CollisionSpec | None, origin: str) -> Collision | None:
    """The collision block with its request read from ``config/<request_file>``."""
    if spec is None:
        return None
    path = config_dir() / spec.request_file
    if not path.is_file():
        raise InputError(f"{origin}: collision.request_file: {str(path)!r} not found")
    request = read_yaml(path, "collision request")
    if not isinstance(request, dict):
        raise InputError(f"{origin}: collision.request_file: {spec.request_file} is not a "
                          "mapping of request fields")
    return Collision(service=spec.service, type=spec.type, request=request,
                     request_file=spec.request_file)


def load_profile(name_or_path: str) -> RobotProfile:
    """Read and validate a robot profile by name (``config/robots/``) or path: once per
    process and file version (a profile edited on disk is read again)."""
    p = config_file(name_or_path, "robots", "robot profile")
    return _parsed_profile(str(p.resolve()), p.stat().st_mtime_ns)


@cache
def _parsed_profile(path: str, mtime_ns: int) -> RobotProfile:
    p = Path(path)
    return parse_profile(read_yaml(p, "robot profile"), origin=f"robot profile {p.name}")


#: Node settings that are the robot profile's value where they are left empty ('' or 0):
#: {setting: profile field}.
FROM_PROFILE = {"stiffness": "stiffness", "force_sign": "force_sign",
                "wrench_sign": "force_sign", "state_topic": "state_topic",
                "pose_topic": "pose_topic", "wrench_topic": "wrench_topic",
                "mode_topic": "mode_topic", "target_topic": "target_topic",
                "min_state_rate_hz": "min_state_rate_hz"}

S = TypeVar("S", bound=Schema)


def with_profile(settings: S, prof: RobotProfile) -> S:
    """``settings`` (a node's frozen settings model) with each ``FROM_PROFILE`` field it has and
    leaves empty ('' or 0) set to the profile's value: resolved once, where the node configures,
    so the node reads one value everywhere."""
    names = type(settings).model_fields
    update = {n: getattr(prof, f) for n, f in FROM_PROFILE.items()
              if n in names and not getattr(settings, n)}
    return settings.model_copy(update=update) if update else settings


def hold_target(position: Sequence[float], surface_z: float, ws_min: Sequence[float],
                ws_max: Sequence[float]) -> tuple[float, float, float]:
    """The target a recovery leaves the controller with (``recovery.hold_target``): the
    measured ``position`` (x, y, z [m]), raised to the platform's ``surface_z`` where it is
    below it, inside the workspace box: at rest it pushes nothing into the platform."""
    x, y, z = (float(v) for v in position)
    held = (x, y, max(z, float(surface_z)))
    return tuple(min(max(v, float(lo)), float(hi)) for v, lo, hi in zip(held, ws_min, ws_max, strict=True))


def import_interface(name: str) -> type:
    """``pkg/msg|srv|action/Name`` -> the Python class; InputError if its package is missing."""
    pkg, kind, cls = name.split("/")
    try:
        return getattr(importlib.import_module(f"{pkg}.{kind}"), cls)
    except (ImportError, AttributeError) as exc:
        raise InputError(f"interface {name} is not available here ({exc}); install the "
                         f"package {pkg} (e.g. from the robot's ROS 2 workspace)") from None


def fill_message(msg: Any, values: dict[str, Any], where: str = "request") -> Any:
    """Set ``msg``'s fields from a (nested) mapping; InputError names an unknown field."""
    for key, v in values.items():
        if not hasattr(msg, key):
            raise InputError(f"{where}.{key}: {type(msg).__name__} has no field {key!r}")
        if isinstance(v, dict):
            fill_message(getattr(msg, key), v, f"{where}.{key}")
        else:
            try:
                setattr(msg, key, v)
            except (TypeError, ValueError, AssertionError) as exc:
                raise InputError(f"{where}.{key}: {exc}") from None
    return msg
