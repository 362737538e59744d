"""Robot profiles: which controller, topics, message types and recovery interface a robot stack
has (``config/robots/<name>.yaml``), validated once; every error names the field.

Pure Python (no rclpy). A profile says:

- ``frame_id``: the robot's base frame (scene positions, rviz fixed frame);
- ``controller``: the Cartesian impedance controller the motion node talks to, its
  translational ``stiffness`` [N/m] (the press commands the equilibrium ``force / stiffness``
  below the surface) and ``target_filter_s`` (its filter on the equilibrium, for the mock);
- ``target``: ``topic`` and ``type``: ``geometry_msgs/msg/PoseStamped`` or
  ``std_msgs/msg/Float64MultiArray`` (multipanda_ros2 layout: x y z, then the rotation matrix
  row by row);
- ``state``: either ``pose_topic`` + ``wrench_topic`` (PoseStamped + WrenchStamped, as
  franka_robot_state_broadcaster publishes them) or ``topic`` + ``type`` of a franka state
  message with ``o_t_ee`` (16, column-major), ``o_f_ext_hat_k`` (6) and ``robot_mode``
  (multipanda_ros2's ``franka_msgs/msg/FrankaState``); optionally ``mode_topic`` + ``mode_type``:
  a full state message whose ``robot_mode`` reports a reflex (franka_ros2's
  ``franka_msgs/msg/FrankaRobotState``; read only where that type is installed);
- ``force_sign``: normal force = ``force_sign * f_z`` of the base-frame wrench;
- ``collision``: ``service`` + ``type`` of franka's collision-threshold service, where the
  stack offers one (franka_ros2: ``/service_server/set_force_torque_collision_behavior``); the
  motion node's pre-flight sets the thresholds the press needs through it;
- ``recovery``: ``kind`` (``action``, ``service`` or ``none``), ``name``, ``type``,
  ``ok_field`` (service: the response field that says it worked), and ``then``: the service
  calls that re-activate hardware and controllers after recovery, in order (``service``,
  ``type``, ``request`` fields, ``ok_field``).
"""

from __future__ import annotations

import importlib
from dataclasses import dataclass, field
from typing import Annotated, Any, Literal

from pydantic import StringConstraints, field_validator, model_validator

from ..core.config import FieldError, Schema, param
from ..core.errors import TactexError
from ..paths import config_file, read_yaml

POSE_STAMPED = "geometry_msgs/msg/PoseStamped"
FLOAT64_MULTIARRAY = "std_msgs/msg/Float64MultiArray"
TARGET_TYPES = (POSE_STAMPED, FLOAT64_MULTIARRAY)
RECOVERY_KINDS = ("action", "service", "none")


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
    target_filter_s: float = 0.0         # s, the controller's filter on the equilibrium
    recovery: Recovery = field(default_factory=Recovery)
    collision_service: str = ""          # franka's collision-threshold service ("" = none)
    collision_type: str = ""
    notes: str = ""

    @property
    def franka_state(self) -> bool:
        return bool(self.state_type)


Text = Annotated[str, StringConstraints(min_length=1)]


def _interface(*kinds: str) -> Any:
    """A ROS interface name ``package/<kind>/Name`` for one of ``kinds``."""
    return Annotated[str, StringConstraints(pattern=rf"^[^/]+/({'|'.join(kinds)})/[^/]+$")]


class ControllerSpec(Schema):
    name: Text = param(..., "the Cartesian impedance controller")
    stiffness: float = param(..., "translational stiffness [N/m]", 10.0, 1e6)
    target_filter_s: float = param(0.0, "the controller's filter on the equilibrium [s]",
                                   0.0, 5.0)


class TargetSpec(Schema):
    topic: Text = param(..., "equilibrium target topic")
    type: Literal[POSE_STAMPED, FLOAT64_MULTIARRAY] = param(..., "target message type")


class StateSpec(Schema):
    """Either ``pose_topic`` + ``wrench_topic`` (optionally ``mode_topic`` + ``mode_type``) or
    ``topic`` + ``type`` of a franka state message."""

    pose_topic: str = param("", "PoseStamped state topic")
    wrench_topic: str = param("", "WrenchStamped state topic")
    topic: str = param("", "franka state message topic")
    type: _interface("msg") | Literal[""] = param("", "franka state message type")
    mode_topic: str = param("", "robot_mode of a full state message: topic")
    mode_type: _interface("msg") | Literal[""] = param("", "... and its type")

    @model_validator(mode="after")
    def _one_kind(self) -> "StateSpec":
        given = self.model_fields_set
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

    @model_validator(mode="after")
    def _complete(self) -> "RecoverySpec":
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
    """franka's collision-threshold service where the robot stack offers one (pre-flight)."""

    service: str = param("", "service name ('' = the stack offers none)")
    type: _interface("srv") | Literal[""] = param("", "service type")

    @model_validator(mode="after")
    def _both(self) -> "CollisionSpec":
        if bool(self.service) != bool(self.type):
            raise FieldError("type" if self.service else "service",
                             "give both service and type, or neither")
        return self


class ProfileFile(Schema):
    """A robot profile file (``config/robots/<name>.yaml``) as written."""

    name: Text = param(..., "profile name")
    frame_id: Text = param(..., "the robot's base frame")
    controller: ControllerSpec
    target: TargetSpec
    state: StateSpec
    force_sign: float = param(1.0, "normal force = force_sign * f_z (1 or -1)")
    recovery: RecoverySpec = RecoverySpec()
    collision: CollisionSpec = CollisionSpec()
    notes: str = param("", "free text")

    @field_validator("force_sign")
    @classmethod
    def _sign(cls, v: float) -> float:
        if v not in (1.0, -1.0):
            raise ValueError(f"1 or -1, got {v!r}")
        return v


def parse_profile(data: Any, origin: str = "robot profile") -> RobotProfile:
    """Validate a profile mapping; TactexError names every bad field (``controller.stiffness``,
    ``recovery.then.0.type``)."""
    f = ProfileFile.check(data, origin)
    st = f.state
    state = ({"state_topic": st.topic, "state_type": st.type} if st.topic else
             {"pose_topic": st.pose_topic, "wrench_topic": st.wrench_topic,
              "mode_topic": st.mode_topic, "mode_type": st.mode_type})
    rec = f.recovery
    recovery = Recovery() if rec.kind == "none" else Recovery(
        kind=rec.kind, name=rec.name, type=rec.type, ok_field=rec.ok_field,
        then=tuple(ServiceCall(service=c.service, type=c.type, request=c.request,
                               ok_field=c.ok_field) for c in rec.then))
    return RobotProfile(
        name=f.name, frame_id=f.frame_id, controller=f.controller.name,
        stiffness=float(f.controller.stiffness), target_topic=f.target.topic,
        target_type=f.target.type, force_sign=float(f.force_sign),
        target_filter_s=float(f.controller.target_filter_s), recovery=recovery,
        collision_service=f.collision.service, collision_type=f.collision.type,
        notes=f.notes, **state)


def load_profile(name_or_path: str) -> RobotProfile:
    """Read and validate a robot profile by name (``config/robots/``) or path."""
    p = config_file(name_or_path, "robots", "robot profile")
    return parse_profile(read_yaml(p, "robot profile"), origin=f"robot profile {p.name}")


def import_interface(name: str) -> type:
    """``pkg/msg|srv|action/Name`` -> the Python class; TactexError if its package is missing."""
    pkg, kind, cls = name.split("/")
    try:
        return getattr(importlib.import_module(f"{pkg}.{kind}"), cls)
    except (ImportError, AttributeError) as exc:
        raise TactexError(f"interface {name} is not available here ({exc}); install the "
                          f"package {pkg} (e.g. from the robot's ROS 2 workspace)") from None


def fill_message(msg: Any, values: dict[str, Any], where: str = "request") -> Any:
    """Set ``msg``'s fields from a (nested) mapping; TactexError names an unknown field."""
    for key, v in values.items():
        if not hasattr(msg, key):
            raise TactexError(f"{where}.{key}: {type(msg).__name__} has no field {key!r}")
        if isinstance(v, dict):
            fill_message(getattr(msg, key), v, f"{where}.{key}")
        else:
            try:
                setattr(msg, key, v)
            except (TypeError, ValueError, AssertionError) as exc:
                raise TactexError(f"{where}.{key}: {exc}") from None
    return msg
