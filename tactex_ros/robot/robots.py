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
- ``recovery``: ``kind`` (``action``, ``service`` or ``none``), ``name``, ``type``,
  ``ok_field`` (service: the response field that says it worked), and ``then``: the service
  calls that re-activate hardware and controllers after recovery, in order (``service``,
  ``type``, ``request`` fields, ``ok_field``).
"""

from __future__ import annotations

import importlib
from dataclasses import dataclass, field
from typing import Any

from ..core.errors import TactexError
from ..paths import check_mapping, config_file, read_yaml

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
    notes: str = ""

    @property
    def franka_state(self) -> bool:
        return bool(self.state_type)


def _str(d: dict, key: str, where: str, required: bool = True) -> str:
    v = d.get(key, "")
    if not isinstance(v, str) or (required and not v):
        raise TactexError(f"{where}.{key}: expected a non-empty string, got {v!r}")
    return v


def _interface_name(v: str, where: str, kinds: tuple[str, ...]) -> str:
    parts = v.split("/")
    if len(parts) != 3 or parts[1] not in kinds or not all(parts):
        raise TactexError(f"{where}: expected 'package/{'|'.join(kinds)}/Name', got {v!r}")
    return v


def parse_profile(data: Any, origin: str = "robot profile") -> RobotProfile:
    """Validate a profile mapping; TactexError names the first bad field."""
    d = check_mapping(data, origin, {"name", "frame_id", "controller", "target", "state",
                                "force_sign", "recovery", "notes"})
    ctl = check_mapping(d.get("controller"), f"{origin}: controller",
                   {"name", "stiffness", "target_filter_s"})
    k = ctl.get("stiffness")
    if isinstance(k, bool) or not isinstance(k, (int, float)) or not 10.0 <= k <= 1e6:
        raise TactexError(f"{origin}: controller.stiffness: N/m in [10, 1e6], got {k!r}")
    filt = ctl.get("target_filter_s", 0.0)
    if isinstance(filt, bool) or not isinstance(filt, (int, float)) or not 0 <= filt <= 5:
        raise TactexError(f"{origin}: controller.target_filter_s: s in [0, 5], got {filt!r}")
    tgt = check_mapping(d.get("target"), f"{origin}: target", {"topic", "type"})
    ttype = _str(tgt, "type", f"{origin}: target")
    if ttype not in TARGET_TYPES:
        raise TactexError(f"{origin}: target.type: one of {list(TARGET_TYPES)}, got {ttype!r}")
    st = check_mapping(d.get("state"), f"{origin}: state",
                  {"pose_topic", "wrench_topic", "topic", "type", "mode_topic", "mode_type"})
    if "topic" in st or "type" in st:
        if "pose_topic" in st or "wrench_topic" in st:
            raise TactexError(f"{origin}: state: give either topic + type (a franka state "
                              "message) or pose_topic + wrench_topic, not both")
        state = {"state_topic": _str(st, "topic", f"{origin}: state"),
                 "state_type": _interface_name(_str(st, "type", f"{origin}: state"),
                                               f"{origin}: state.type", ("msg",))}
    else:
        state = {"pose_topic": _str(st, "pose_topic", f"{origin}: state"),
                 "wrench_topic": _str(st, "wrench_topic", f"{origin}: state")}
        if "mode_topic" in st or "mode_type" in st:
            state["mode_topic"] = _str(st, "mode_topic", f"{origin}: state")
            state["mode_type"] = _interface_name(_str(st, "mode_type", f"{origin}: state"),
                                                 f"{origin}: state.mode_type", ("msg",))
    sign = d.get("force_sign", 1.0)
    if sign not in (1, -1, 1.0, -1.0) or isinstance(sign, bool):
        raise TactexError(f"{origin}: force_sign: 1 or -1, got {sign!r}")
    rec = check_mapping(d.get("recovery", {"kind": "none"}), f"{origin}: recovery",
                   {"kind", "name", "type", "ok_field", "then"})
    kind = rec.get("kind", "none")
    if kind not in RECOVERY_KINDS:
        raise TactexError(f"{origin}: recovery.kind: one of {list(RECOVERY_KINDS)}, got "
                          f"{kind!r}")
    recovery = Recovery()
    if kind != "none":
        then = []
        for i, c in enumerate(rec.get("then", []) or []):
            w = f"{origin}: recovery.then[{i}]"
            c = check_mapping(c, w, {"service", "type", "request", "ok_field"})
            req = c.get("request", {})
            if not isinstance(req, dict):
                raise TactexError(f"{w}.request: expected a mapping of request fields")
            then.append(ServiceCall(service=_str(c, "service", w),
                                    type=_interface_name(_str(c, "type", w), f"{w}.type",
                                                         ("srv",)),
                                    request=req, ok_field=_str(c, "ok_field", w)))
        recovery = Recovery(
            kind=kind, name=_str(rec, "name", f"{origin}: recovery"),
            type=_interface_name(_str(rec, "type", f"{origin}: recovery"),
                                 f"{origin}: recovery.type",
                                 ("action",) if kind == "action" else ("srv",)),
            ok_field=_str(rec, "ok_field", f"{origin}: recovery", required=kind == "service"),
            then=tuple(then))
    return RobotProfile(
        name=_str(d, "name", origin), frame_id=_str(d, "frame_id", origin),
        controller=_str(ctl, "name", f"{origin}: controller"), stiffness=float(k),
        target_topic=_str(tgt, "topic", f"{origin}: target"), target_type=ttype,
        force_sign=float(sign), target_filter_s=float(filt), recovery=recovery,
        notes=str(d.get("notes", "")), **state)


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
