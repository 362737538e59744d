"""Pre-flight checks before the arm moves (pure, no rclpy): what is measured and when it refuses
the start. The nodes gather the measurements (``ros/preflight.py``, the GelSight node) and end
their configuration with the reason these functions give; docs/hardware_checks.md lists every
refusal with what the lab does.

- robot state: its rate [Hz] over a window, and franka's ``robot_mode`` where it is read
  (libfranka's ``RobotMode``, franka_msgs ``FrankaRobotState.msg`` lines 64-71 in franka_ros2
  v3.4.0: 2 = move, the only mode in which a running controller follows targets);
- franka's collision thresholds (the robot profile's ``collision``: service, type and the
  request file, config/bringup/collision_thresholds.yaml): the press needs the reflex (upper)
  force thresholds above the largest raw force a press can reach (``max_force`` +
  ``tare_max_offset_n``), else franka's reflex, not the press's own limit, ends a press; set
  through franka_hardware's ``/service_server/set_force_torque_collision_behavior`` (franka_ros2
  v3.4.0 franka_hardware/src/franka_param_service_server.cpp:65-71, request fields
  franka_msgs/srv/SetForceTorqueCollisionBehavior.srv:1-4, answer ``success`` + ``error``), or
  by hand with the command ``collision_command`` prints;
- the tactile camera: its measured frame rate, and a no-contact frame that is not blank, not
  saturated, not already showing contact, and steady over the reference frames.
"""

from __future__ import annotations

from dataclasses import dataclass
from collections.abc import Sequence

import cv2
import numpy as np

from ..core.contact import blur, contact_score
from ..core.errors import DeviceError, DeviceNotReady, InputError

# libfranka RobotMode (franka_msgs FrankaRobotState.msg / FrankaState.msg ROBOT_MODE_*)
ROBOT_MODES = {0: "other", 1: "idle", 2: "move", 3: "guiding", 4: "reflex", 5: "user stopped",
               6: "automatic error recovery"}
ROBOT_MODE_MOVE = 2
#: robot modes in which the arm does not follow any command until recovered: reflex and user
#: stopped (franka_ros2 v3.4.0 franka_msgs/msg/FrankaRobotState.msg:68-69; multipanda_ros2
#: 8b6a92c franka_msgs/msg/FrankaState.msg:50-51)
FAULT_MODES = {4: "reflex", 5: "user stopped"}


def fault_mode(mode: int | None) -> str:
    """The name of a fault mode (``FAULT_MODES``), '' for any other mode or None."""
    return FAULT_MODES.get(mode, "") if mode is not None else ""


@dataclass(frozen=True)
class Problem:
    """A pre-flight refusal: ``check`` names it (docs/hardware_checks.md lists each: state,
    state_rate, robot_mode, collision, fps, no_frame, blank, saturated, contact, unsteady),
    ``text`` says what was measured and what to do."""

    check: str
    text: str

    def __str__(self) -> str:
        return f"pre-flight {self.check}: {self.text}"

    @property
    def absent(self) -> bool:
        """The device gave nothing at all (no state message, no frame): a run-time failure
        (exit status 1), not a refused setting (2)."""
        return self.check in ABSENT

    def error(self) -> Exception:
        """The exception to raise: DeviceError when the device is absent, DeviceNotReady when
        it (or the machine) is in a state that forbids the work (robot mode, a slow state
        stream: exit status 1), else InputError (exit status 2: a setting to change)."""
        if self.absent:
            return DeviceError(str(self))
        if self.check in NOT_READY:
            return DeviceNotReady(str(self))
        return InputError(str(self))


#: Pre-flight checks that fail when the device is absent rather than unfit.
ABSENT = ("state", "no_frame")
#: Pre-flight checks that fail on a run-time state of the device or of the machine, not on a
#: setting: the robot's mode, and a state stream measured slower than its floor (what the
#: machine did: a busy machine, a slow link or broadcaster; the same command can pass later)
NOT_READY = ("robot_mode", "state_rate")


def rate_hz(stamps: Sequence[float]) -> float:
    """Message rate [Hz] from arrival times [s] (0 with fewer than 2)."""
    if len(stamps) < 2 or stamps[-1] <= stamps[0]:
        return 0.0
    return (len(stamps) - 1) / (stamps[-1] - stamps[0])


def state_problem(stamps: Sequence[float], min_rate_hz: float, window_s: float,
                  what: str) -> Problem | None:
    """Why the robot state ``what`` (a topic) is not good enough to press with (None if it is):
    none within the window, or slower than ``min_rate_hz``."""
    if not stamps:
        return Problem("state", f"no message on {what} within the pre-flight window "
                f"({window_s} s): is the robot's bring-up (state broadcaster) running?")
    r = rate_hz(stamps)
    if r < min_rate_hz:
        return Problem("state_rate", f"{what} arrived at {r:.1f} Hz, below the minimum "
                f"{min_rate_hz} Hz (robot profile state.min_rate_hz, or min_state_rate_hz; "
                f"{len(stamps)} messages in {window_s} s): the robot's state stream was slow "
                "(a busy machine, a slow network link, or a state broadcaster publishing "
                "slower than the shipped bring-up: docs/hardware.md)")
    return None


def mode_problem(mode: int | None) -> Problem | None:
    """Why franka's ``robot_mode`` forbids a start (None for move, or when not read)."""
    if mode is None or mode == ROBOT_MODE_MOVE:
        return None
    name = ROBOT_MODES.get(mode, f"unknown ({mode})")
    hint = {1: "no controller is running: start the bring-up and activate the controller",
            4: "the robot is in a reflex: run the error recovery (docs/hardware_checks.md)",
            5: "the user stop is pressed: release it",
            3: "the robot is in guiding mode: release the guiding button",
            }.get(mode, "the robot must be in move mode with the controller running")
    return Problem("robot_mode", f"{name} (robot_mode {mode}); {hint}")


FORCE_FIELDS = ("lower_force_thresholds_nominal", "upper_force_thresholds_nominal")


def collision_problem(request: dict, max_force: float, max_offset: float) -> Problem | None:
    """Why franka's collision request (``SetForceTorqueCollisionBehavior`` fields, the
    profile's ``collision.request_file``) does not fit the press (None if it does): the reflex
    (upper) force thresholds x, y, z must lie above the largest raw force a press can reach,
    ``max_force + max_offset`` [N] (the press's limit acts on the tared force)."""
    missing = [f for f in FORCE_FIELDS if len(request.get(f, ())) < 3]
    if missing:
        return Problem("collision", f"the collision request lacks {missing} (x, y, z at least)")
    lower, upper = (list(map(float, request[f][:3])) for f in FORCE_FIELDS)
    if any(lo > hi for lo, hi in zip(lower, upper, strict=True)):
        return Problem("collision", f"lower_force_thresholds_nominal {lower} N above "
                                    f"upper_force_thresholds_nominal {upper} N")
    need = max_force + max_offset
    if min(upper) <= need:
        return Problem("collision", f"upper_force_thresholds_nominal x, y, z {upper} N must "
                                    f"be above max_force + tare_max_offset_n = {need:g} N, so "
                                    "that the press's own limit acts before franka's reflex")
    return None


def collision_command(service: str, type_name: str, request: dict) -> str:
    """The ``ros2 service call`` that sets the thresholds of ``request`` by hand."""
    fields = ", ".join(f"{k}: [{', '.join(f'{float(v):g}' for v in vals)}]"
                       for k, vals in request.items())
    return f"ros2 service call {service} {type_name} \"{{{fields}}}\""


@dataclass(frozen=True)
class FrameLimits:
    """What a sane no-contact frame is (grey levels 0..255 of the rgb8 frame):
    ``min_std`` (below: blank, e.g. LED off or lens covered), ``max_saturated`` (largest
    fraction of pixels at 250 or above), ``max_texture`` (high-pass energy, above: something
    textured already touches the gel), ``max_change`` (largest contact score of one reference
    frame against their mean: the gel must be still)."""

    min_std: float
    max_saturated: float
    max_texture: float
    max_change: float


def texture(frame: np.ndarray) -> float:
    """High-pass energy of an (H, W, 3) uint8 frame [grey levels]: mean |g - blur41(g)| of the
    5x5-blurred grey image g (sensor noise averaged out). No-contact GelSight Mini frames of
    octopi-dev: 0.56-0.62; a textured contact (bristles, rice, mesh): 0.9-2.5; soft fabrics
    barely differ from no contact, which a single frame cannot tell."""
    g = cv2.GaussianBlur(cv2.cvtColor(frame, cv2.COLOR_RGB2GRAY).astype(np.float32), (5, 5), 0)
    return float(np.abs(g - cv2.GaussianBlur(g, (41, 41), 0)).mean())


def frame_problem(frames: Sequence[np.ndarray], limits: FrameLimits) -> Problem | None:
    """Why the no-contact frames (reference frames, (H, W, 3) uint8) are not sane ('' if they
    are); the no-contact frame is their mean."""
    if not len(frames):
        return Problem("no_frame", "the camera gave no frame")
    ref = np.mean(np.asarray(frames, dtype=np.float32), axis=0).round().astype(np.uint8)
    std = float(ref.std())
    if std < limits.min_std:
        return Problem("blank", f"the no-contact frame is blank (grey-level spread {std:.1f} < "
                f"frame_min_std {limits.min_std}; mean {ref.mean():.0f}): LED off, lens "
                "covered or a wrong device")
    sat = float((ref >= 250).mean())
    if sat > limits.max_saturated:
        return Problem("saturated", f"the no-contact frame is saturated ({sat:.1%} of pixels "
                                    f"at 250 or above > frame_max_saturated "
                                    f"{limits.max_saturated:.1%}): exposure or LED too strong")
    tex = texture(ref)
    if tex > limits.max_texture:
        return Problem("contact", f"the no-contact frame shows contact (texture {tex:.2f} > "
                f"frame_max_texture {limits.max_texture}): the gel touches something at "
                "start-up; lift the sensor clear")
    rb = blur(ref)
    change = max(contact_score(f, rb) for f in frames)
    if change > limits.max_change:
        return Problem("unsteady", f"the no-contact frames change (contact score {change:.2f} > "
                f"frame_max_change {limits.max_change}): something moves on the gel or the "
                "lighting is not steady")
    return None


def fps_problem(stamps: Sequence[float], requested: float,
                min_fraction: float) -> Problem | None:
    """Why the camera's measured frame rate is too low (None if it is not): below
    ``min_fraction`` of the ``requested`` rate [Hz]."""
    r = rate_hz(stamps)
    if r < min_fraction * requested:
        return Problem("fps", f"measured {r:.1f} frames/s over {len(stamps)} frames, below "
                f"min_fps_fraction {min_fraction} x the requested {requested:g} frames/s "
                "(USB bandwidth, capture mode or exposure too long)")
    return None


@dataclass(frozen=True)
class PushReading:
    """What ``push_sign`` saw: the hands-off ``baseline_n`` and the push's ``delta_n`` of the
    raw base-frame f_z [N] (median over the hold), and the ``force_sign`` it implies (+1 or
    -1; 0 = no push seen)."""

    baseline_n: float
    delta_n: float
    force_sign: int


def push_sign(baseline: Sequence[float], times: Sequence[float], fz: Sequence[float],
              push_n: float, hold_s: float) -> PushReading:
    """The wrench sign from a hand push: the sensor pushed *up* (as a platform pushes it during
    a press) must read as a positive normal force, so ``force_sign = sign(delta f_z)`` once
    ``|f_z - baseline|`` stays at ``push_n`` [N] or more for ``hold_s`` [s] (baseline: median
    of the hands-off samples). ``times`` [s] and ``fz`` [N] are the samples after the prompt."""
    base = float(np.median(baseline)) if len(baseline) else 0.0
    start = None
    for i, (t, f) in enumerate(zip(times, fz, strict=True)):
        if abs(f - base) < push_n or (start is not None and
                                      np.sign(f - base) != np.sign(fz[start] - base)):
            start = None
            continue
        if start is None:
            start = i
        if t - times[start] >= hold_s:
            delta = float(np.median(np.asarray(fz[start:i + 1]))) - base
            return PushReading(base, delta, 1 if delta > 0 else -1)
    return PushReading(base, 0.0, 0)
