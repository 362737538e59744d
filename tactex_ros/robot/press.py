"""The press sequence as a pure state machine (no rclpy), ticked by the motion node, and the
mock arm's physics.

The robot is under Cartesian impedance control: the motion node commands the controller's
*equilibrium* pose, and the arm pushes with ``F = K (x - x_eq)`` (``K`` the controller's
translational stiffness [N/m]). A press therefore commands the equilibrium *below* the surface:

``approach`` (lift to a safe height, travel above the platform, go to the approach point
``approach_height`` above its surface) -> ``tare`` (at the approach point and at rest, the
normal force's offset is the median over ``tare_window_s``; it settles when the spread over the
window is small and the arm does not move; not settled within ``tare_deadline_s``, or an offset
above ``tare_max_offset_n``, refuses the press with that reason) -> ``descend`` (the equilibrium goes straight down at
``descend_speed`` until the normal force reaches ``force_threshold``) -> ``settle`` (the
equilibrium is held at ``position - force / K``, never deeper than it already was: the static
force at the measured pose is then the force measured at the threshold, so the contact stays
at the threshold during settle and capture) -> ``capture`` (the caller
grabs a frame and calls ``captured``) -> ``retract`` (back to the approach point) -> ``done``.

The equilibrium never goes deeper than ``equilibrium_floor`` below the surface:
``max(max_depth, (force_threshold + max_force) / 2 / K)``. For compliant controllers
(``K * max_depth <= (force_threshold + max_force) / 2``) the static force at that floor is below
the midpoint of threshold and limit whatever the platform's stiffness, because the contact spring
only adds compliance in series; stiffer controllers rely on the threshold stop, checked every tick.
No contact: the sensor is ``max_depth`` below the surface, or the equilibrium has reached its
floor and the arm has settled there, and the force is still below the threshold.

Enforced on every tick, whatever the phase: the commanded target stays inside the workspace
box and moves at most ``max_speed`` (and the phase's own speed) per second; the force magnitude
never above ``max_force`` (abort: retract at once); a normal force that reads clearly negative
while pressing aborts (the wrench sign is wrong: a wrong sign would hide every contact); each
phase ends before its deadline (abort). A failed press still retracts; ``result`` then carries
the reason. From the tare on, every force the press acts on (threshold, limit, sign, the
force at capture) is the tared force: the offset is removed from the normal component, the
lateral part of the magnitude is left as measured. Units: m, s, N.
"""

from __future__ import annotations

from dataclasses import dataclass, replace as _replace
from typing import Protocol, Sequence

import numpy as np

from ..core.errors import InputError

APPROACH, TARE, DESCEND, SETTLE, CAPTURE, RETRACT, DONE = (
    "approach", "tare", "descend", "settle", "capture", "retract", "done")


class PressSettings(Protocol):
    """How a press is made (the scene file's ``press``, ``scene.PressSettings``): m, m/s, N, s."""

    approach_height: float
    travel_speed: float
    descend_speed: float
    max_speed: float
    force_threshold: float
    max_force: float
    max_depth: float
    settle_s: float
    approach_deadline_s: float
    descend_deadline_s: float
    capture_deadline_s: float
    retract_deadline_s: float
    position_tolerance: float
    tare_window_s: float
    tare_max_spread_n: float
    tare_max_motion_m: float
    tare_max_offset_n: float
    tare_deadline_s: float


class Platform(Protocol):
    """A platform: ``id``, surface centre ``position`` [m] in the base frame, ``radius`` [m]."""

    id: str
    position: tuple[float, float, float]
    radius: float


class Workspace(Protocol):
    """What a press needs of the scene (``scene.Scene``): the workspace box [m], the press
    settings and the platforms."""

    workspace_min: tuple[float, float, float]
    workspace_max: tuple[float, float, float]
    press: PressSettings
    platforms: Sequence[Platform]


def clamp(scene: Workspace, xyz: np.ndarray) -> np.ndarray:
    """Position [m] clipped into the workspace box."""
    return np.clip(np.asarray(xyz, dtype=float), scene.workspace_min, scene.workspace_max)


def platform_under(platforms: Sequence[Platform], position: np.ndarray
                   ) -> tuple[int | None, float]:
    """Index of the first of ``platforms`` whose disc (``radius`` around its centre, in x-y)
    holds the sensor at ``position`` (x, y, z) [m], and the sensor's depth below that
    platform's surface [m] (0 when above it); (None, 0.0) when no platform is under it. The
    mock arm (contact force) and the mock camera (which fabric to show) both ask this."""
    pos = np.asarray(position, dtype=float)
    for i, p in enumerate(platforms):
        c = np.asarray(p.position, dtype=float)
        if np.linalg.norm(pos[:2] - c[:2]) <= p.radius:
            return i, max(0.0, float(c[2] - pos[2]))
    return None, 0.0


@dataclass
class PressOutcome:
    success: bool
    reason: str                  # "" on success
    force_n: float               # normal force at capture [N] (0 when not captured)
    depth_m: float               # penetration below the surface at capture [m]
    max_force_n: float           # largest force magnitude seen during the press [N]
    tare: "TareResult | None" = None   # the tare before the descent (None: not reached)


@dataclass(frozen=True)
class TareResult:
    """A settled tare: ``offset_n`` (median normal force [N]), ``spread_n`` (90th minus 10th
    percentile over the window [N]), ``samples`` (how many), ``motion_m`` (largest distance of
    the measured position from the window's first one [m])."""

    offset_n: float
    spread_n: float
    samples: int
    motion_m: float


class Tare:
    """The wrench offset at rest: feed samples (time [s], normal force [N], position [m]);
    ``settled`` returns the result once the last ``window_s`` holds at least 3 samples spanning
    90 % of the window, with a force spread at most ``max_spread_n`` and the position within
    ``max_motion_m`` of the window's first sample."""

    def __init__(self, window_s: float, max_spread_n: float, max_motion_m: float) -> None:
        self.window_s, self.max_spread, self.max_motion = window_s, max_spread_n, max_motion_m
        self.t: list[float] = []
        self.f: list[float] = []
        self.x: list[np.ndarray] = []
        self.last: TareResult | None = None   # the latest full window, settled or not

    def add(self, t: float, force_n: float, position: np.ndarray) -> None:
        self.t.append(t)
        self.f.append(float(force_n))
        self.x.append(np.asarray(position, dtype=float))
        while self.t and t - self.t[0] > self.window_s:
            del self.t[0], self.f[0], self.x[0]

    def settled(self) -> TareResult | None:
        """The tare if the current window is full and quiet, else None (``last`` then holds
        the full window's figures, for the refusal)."""
        if len(self.t) < 3 or self.t[-1] - self.t[0] < 0.9 * self.window_s:
            return None
        f = np.asarray(self.f)
        lo, hi = np.percentile(f, [10, 90])
        motion = float(max(np.linalg.norm(x - self.x[0]) for x in self.x))
        self.last = TareResult(float(np.median(f)), float(hi - lo), len(f), motion)
        if self.last.spread_n <= self.max_spread and motion <= self.max_motion:
            return self.last
        return None


def tared(force_n: float, magnitude: float, offset_n: float) -> tuple[float, float]:
    """(normal force, magnitude) [N] with the normal offset removed; the lateral part of the
    magnitude (``sqrt(magnitude^2 - force_n^2)``) is kept as measured."""
    lateral2 = max(0.0, magnitude * magnitude - force_n * force_n)
    fn = force_n - offset_n
    return fn, float(np.sqrt(lateral2 + fn * fn))


def equilibrium_floor(press: PressSettings, stiffness: float) -> float:
    """Deepest equilibrium below the surface [m] for controller stiffness ``stiffness`` [N/m]."""
    return max(press.max_depth, 0.5 * (press.force_threshold + press.max_force) / stiffness)


def check_press(scene: Workspace, stiffness: float, origin: str = "scene",
                error_clip: float = float("inf")) -> None:
    """Refuse press settings a controller of ``stiffness`` [N/m] cannot carry out in time or
    inside the workspace; InputError names the field. ``error_clip`` [m]: the controller
    clips the pose error there (CRISP ``task.error_clip``), so it never pushes with more than
    ``stiffness * error_clip`` at rest."""
    s = scene.press
    if stiffness * error_clip < 1.5 * s.force_threshold:
        raise InputError(
            f"{origin}: the controller pushes with at most stiffness x error_clip = "
            f"{stiffness:g} N/m x {error_clip:g} m = {stiffness * error_clip:.1f} N, less than "
            f"1.5 x press.force_threshold ({s.force_threshold} N)")
    floor = equilibrium_floor(s, stiffness)
    deepest = 0.0
    for i, p in enumerate(scene.platforms):
        room = min(floor, p.position[2] - scene.workspace_min[2])
        deepest = max(deepest, room)
        if stiffness * room < 1.5 * s.force_threshold:
            raise InputError(
                f"{origin}: platforms[{i}] ({p.id}): the equilibrium can go only {room:.4f} m "
                f"below the surface (workspace.min z {scene.workspace_min[2]}), which at "
                f"stiffness {stiffness:g} N/m gives less than 1.5 x force_threshold "
                f"({s.force_threshold} N)")
    need = (s.approach_height + deepest) / s.descend_speed + 1.0
    if need > s.descend_deadline_s:
        raise InputError(
            f"{origin}: press.descend_deadline_s ({s.descend_deadline_s} s) is shorter than a "
            f"descent can take at controller stiffness {stiffness:g} N/m: {need:.1f} s "
            f"(approach_height {s.approach_height} m + equilibrium floor {deepest:.4f} m at "
            f"descend_speed {s.descend_speed} m/s, + 1 s)")


class PressController:
    """One press of one platform. Call ``step`` at a steady rate with fresh measurements.

    ``stiffness``: the impedance controller's translational stiffness along z [N/m] (a
    position-controlled robot: a large value such as 1e5, the equilibrium is then the pose).
    """

    def __init__(self, scene: Workspace, platform: Platform, start: np.ndarray, now: float,
                 stiffness: float = 1e5) -> None:
        if not stiffness > 0:
            raise ValueError("stiffness must be positive [N/m]")
        self.scene, self.platform, self.s, self.k = scene, platform, scene.press, stiffness
        surface = np.asarray(platform.position, dtype=float)
        self.surface_z = surface[2]
        self.approach_point = surface + [0.0, 0.0, self.s.approach_height]
        self.bottom = clamp(scene, surface - [0.0, 0.0, equilibrium_floor(self.s, stiffness)])
        start = clamp(scene, start)
        safe_z = max(start[2], self.approach_point[2])
        self._waypoints = [np.array([start[0], start[1], safe_z]),
                           np.array([surface[0], surface[1], safe_z]), self.approach_point]
        self.target = start.copy()
        self.phase = APPROACH
        self.phase_start = now
        self._last = now
        self.failure = ""
        self.capture_force = 0.0
        self.capture_depth = 0.0
        self.max_force = 0.0
        self._need_capture = False
        self._tare = Tare(self.s.tare_window_s, self.s.tare_max_spread_n,
                          self.s.tare_max_motion_m)
        self.tare: TareResult | None = None
        self.force_n = 0.0

    # ------------------------------------------------------------------ helpers
    def _enter(self, phase: str, now: float) -> None:
        self.phase, self.phase_start = phase, now

    def abort(self, reason: str, now: float) -> None:
        """End the press with ``reason``: retract from where it is (done if retracting)."""
        if not self.failure:
            self.failure = reason
        if self.phase in (RETRACT, DONE):
            self._enter(DONE, now)
        else:
            self._enter(RETRACT, now)

    _abort = abort

    def _deadline(self) -> float:
        return {APPROACH: self.s.approach_deadline_s, DESCEND: self.s.descend_deadline_s,
                SETTLE: self.s.settle_s + self.s.capture_deadline_s,
                CAPTURE: self.s.capture_deadline_s,
                RETRACT: self.s.retract_deadline_s}.get(self.phase, float("inf"))

    def _move_towards(self, goal: np.ndarray, speed: float, dt: float) -> bool:
        """Advance the target towards ``goal`` at ``speed`` [m/s]; True when it is there."""
        step = min(speed, self.s.max_speed) * dt
        d = goal - self.target
        dist = float(np.linalg.norm(d))
        self.target = goal.copy() if dist <= step else self.target + d * (step / dist)
        self.target = clamp(self.scene, self.target)
        return dist <= step

    # ------------------------------------------------------------------ API
    @property
    def capture_requested(self) -> bool:
        """True once, when the press has settled and a frame should be captured now."""
        return self.phase == CAPTURE and self._need_capture

    def captured(self, ok: bool, reason: str, now: float) -> None:
        """Report the capture; the press then retracts."""
        self._need_capture = False
        if not ok:
            self.abort(f"capture failed: {reason}", now)
        else:
            self._enter(RETRACT, now)

    def step(self, now: float, position: np.ndarray, force_n: float,
             force_magnitude: float | None = None) -> np.ndarray:
        """Advance to time ``now`` [s] given the measured position [m], the signed normal force
        [N] (positive = pressing) and the force magnitude [N] (default ``|force_n|``).

        Returns the equilibrium position to command (always inside the workspace).
        """
        dt = max(0.0, min(now - self._last, 0.2))  # a stalled loop must not jump the target
        self._last = now
        position = np.asarray(position, dtype=float)
        mag = abs(force_n) if force_magnitude is None else float(force_magnitude)
        if self.tare is not None:
            force_n, mag = tared(force_n, mag, self.tare.offset_n)
        self.force_n = force_n     # the normal force the press acts on (tared once settled)
        self.max_force = max(self.max_force, mag)
        if self.phase == DONE:
            return self.target
        self._check_limits(now, force_n, mag)
        if self.phase == APPROACH:
            self._approach(now, position, dt)
        elif self.phase == TARE:
            self._tare_step(now, position, force_n)
        elif self.phase == DESCEND:
            self._descend(now, position, force_n, dt)
        elif self.phase == SETTLE:
            self._settle(now, position, force_n)
        elif self.phase == RETRACT:
            if self._arrive(self.approach_point, self.s.travel_speed, position, dt):
                self._enter(DONE, now)
        return self.target

    def _check_limits(self, now: float, force_n: float, mag: float) -> None:
        """Abort on the force limit, a normal force of the wrong sign while pressing, or the
        phase's deadline (checked on every tick, whatever the phase)."""
        s = self.s
        if mag > s.max_force and self.phase != RETRACT:
            self.abort(f"force limit: {mag:.1f} N > max_force {s.max_force} N", now)
        elif force_n < -s.force_threshold and self.phase in (DESCEND, SETTLE, CAPTURE):
            self.abort(f"force sign: the normal force reads {force_n:.1f} N while pressing; "
                       "the wrench sign (force_sign) is wrong for this robot", now)
        if now - self.phase_start > self._deadline():
            self.abort(f"deadline: phase {self.phase} took longer than "
                       f"{self._deadline():.1f} s", now)

    def _arrive(self, goal: np.ndarray, speed: float, position: np.ndarray, dt: float) -> bool:
        """Move the target towards ``goal``; True once the target is there and the measured
        position within ``position_tolerance`` of it."""
        return (self._move_towards(goal, speed, dt)
                and np.linalg.norm(position - goal) <= self.s.position_tolerance)

    def _approach(self, now: float, position: np.ndarray, dt: float) -> None:
        """Through the waypoints (lift, travel, approach point); then tare."""
        if self._arrive(self._waypoints[0], self.s.travel_speed, position, dt):
            self._waypoints.pop(0)
            if not self._waypoints:
                self._enter(TARE, now)

    def _tare_step(self, now: float, position: np.ndarray, force_n: float) -> None:
        """Hold the approach point and measure the offset; descend once it settled, refuse
        the press when it does not settle in time or is too large."""
        s = self.s
        self._tare.add(now, force_n, position)
        got = self._tare.settled()
        if got is not None:
            if abs(got.offset_n) > s.tare_max_offset_n:
                self.abort(f"tare: offset {got.offset_n:.2f} N is larger than "
                           f"tare_max_offset_n {s.tare_max_offset_n} N (payload or wrench "
                           "model error; the press would act on a force that far off)", now)
                return
            self.tare = got
            self._enter(DESCEND, now)
        elif now - self.phase_start > s.tare_deadline_s:
            last = self._tare.last
            why = ("no full window of samples" if last is None else
                   f"force spread {last.spread_n:.2f} N (limit tare_max_spread_n "
                   f"{s.tare_max_spread_n} N), arm moved {last.motion_m * 1000:.2f} mm (limit "
                   f"tare_max_motion_m {s.tare_max_motion_m * 1000:g} mm) over "
                   f"{last.samples} samples")
            self.abort(f"tare did not settle within tare_deadline_s {s.tare_deadline_s} s: "
                       f"{why}", now)

    def _descend(self, now: float, position: np.ndarray, force_n: float, dt: float) -> None:
        """Equilibrium down until the threshold force (then settle), or no contact."""
        s = self.s
        if force_n >= s.force_threshold:
            # hold the equilibrium whose static force at the measured pose is the force
            # measured now (>= threshold), never deeper than the one that reached it
            hold = self.target.copy()
            hold[2] = max(position[2] - force_n / self.k, self.target[2])
            self.target = clamp(self.scene, hold)
            self._enter(SETTLE, now)
        elif self.surface_z - position[2] >= s.max_depth:
            self.abort(f"no contact: {force_n:.2f} N < force_threshold "
                       f"{s.force_threshold} N with the sensor max_depth {s.max_depth} m "
                       "below the surface", now)
        elif self._arrive(self.bottom, s.descend_speed, position, dt):
            self.abort(f"no contact: {force_n:.2f} N < force_threshold "
                       f"{s.force_threshold} N with the equilibrium at its floor "
                       f"{self.surface_z - self.bottom[2]:.4f} m below the surface", now)

    def _settle(self, now: float, position: np.ndarray, force_n: float) -> None:
        """After ``settle_s``: ask for the capture, or abort if the contact was lost."""
        s = self.s
        if now - self.phase_start < s.settle_s:
            return
        if force_n < 0.5 * s.force_threshold:
            self.abort(f"contact lost while settling: {force_n:.2f} N < half the "
                       f"force_threshold {s.force_threshold} N", now)
        else:
            self.capture_force = force_n
            self.capture_depth = max(0.0, self.surface_z - position[2])
            self._need_capture = True
            self._enter(CAPTURE, now)

    @property
    def done(self) -> bool:
        return self.phase == DONE

    def outcome(self) -> PressOutcome:
        return PressOutcome(success=self.done and not self.failure, reason=self.failure,
                            force_n=self.capture_force, depth_m=self.capture_depth,
                            max_force_n=self.max_force, tare=self.tare)


# ---------------------------------------------------------------------- mock arm physics
# (kept apart from the press state machine above: the mock arm's model of the controller)


@dataclass(frozen=True)
class ControlLaw:
    """The translational law of the Cartesian impedance controller a robot profile names, as the
    mock arm runs it: one control cycle every ``1 / rate_hz`` s, the force held in between.

    Per cycle, per axis (x_t the commanded target, x_f the filtered target, x, v the arm):

    1. target filter: ``x_f <- (1 - target_filter) x_t + target_filter x_f`` (an exponential
       moving average; 0 = none; CRISP ``filter.target_pose``);
    2. error: ``e = clip(x_f - x, -error_clip, error_clip)`` (CRISP ``task.error_clip`` with
       ``limit_error``; inf = none);
    3. force: ``F = K e - D v`` with ``D = damping`` if > 0, else ``2 sqrt(K)`` (CRISP
       ``task.d_pos_*``, franka_ros2's and multipanda_ros2's examples);
    4. rate limit: ``F <- F_prev + clip(F - F_prev, -max_force_step, max_force_step)`` (CRISP's
       ``max_delta_tau`` per joint and cycle, seen at the end effector; inf = none).

    Units: N/m, N s/m, Hz, m, N.
    """

    stiffness: float
    damping: float = 0.0
    rate_hz: float = 1000.0
    target_filter: float = 0.0
    error_clip: float = float("inf")
    max_force_step: float = float("inf")

    def __post_init__(self) -> None:
        if not self.stiffness > 0 or not self.rate_hz > 0:
            raise ValueError(f"stiffness ({self.stiffness}) and rate_hz ({self.rate_hz}) must "
                             "be positive")
        if not 0.0 <= self.target_filter < 1.0:
            raise ValueError(f"target_filter must be in [0, 1), got {self.target_filter}")
        if not self.error_clip > 0 or not self.max_force_step > 0:
            raise ValueError("error_clip and max_force_step must be positive (inf = none)")

    @property
    def d(self) -> float:
        """The damping the controller computes [N s/m]."""
        return self.damping if self.damping > 0 else 2.0 * float(np.sqrt(self.stiffness))

    @property
    def max_static_force(self) -> float:
        """Largest force the law pushes with at rest [N] (``K * error_clip``; inf if unclipped)."""
        return self.stiffness * self.error_clip

    def replace(self, **kw: float) -> "ControlLaw":
        return _replace(self, **kw)


class ArmModel:
    """Mock arm under the Cartesian impedance ``law``: a point mass ``mass`` [kg], gravity
    compensated, pushed by the controller's force (``ControlLaw``: target filter, error clip,
    spring ``K``, damper ``D``, force rate limit), computed once per control cycle and held over
    it (the plant integrated exactly for a constant force). Platforms push back with a spring
    ``platform_stiffness`` [N/m] (gel, fabric and platform in series) and a damper
    ``platform_damping`` [N s/m] when the sensor is below their surface within their radius.
    Every control cycle is one sample. Positions in m, time in s, forces in N.
    """

    def __init__(self, scene: Workspace, start: np.ndarray, law: ControlLaw | None = None, *,
                 mass: float = 3.0, platform_stiffness: float = 2e4,
                 platform_damping: float = 50.0) -> None:
        for name, v in (("mass", mass), ("platform_stiffness", platform_stiffness)):
            if not v > 0:
                raise ValueError(f"{name} must be positive, got {v}")
        if platform_damping < 0:
            raise ValueError("platform_damping must be >= 0")
        self.scene, self.m = scene, float(mass)
        self.law = law or ControlLaw(stiffness=1000.0)
        self.k, self.d = self.law.stiffness, self.law.d
        self.kp, self.dp = float(platform_stiffness), float(platform_damping)
        self.h = 1.0 / self.law.rate_hz
        self.position = np.asarray(start, dtype=float).copy()
        self.velocity = np.zeros(3)
        self.target = self.position.copy()
        self.equilibrium = self.position.copy()   # the filtered target
        self.command = np.zeros(3)     # the controller's force on the arm [N]
        self.force = np.zeros(3)       # contact force on the sensor (base frame) [N]
        self.peak_force = 0.0          # largest contact force over the cycles of the last step
        self.frozen = False            # a reflex stopped the arm
        self._due = 0.0                # time not yet simulated [s]

    def contact(self, position: np.ndarray | None = None) -> tuple[Platform | None, float]:
        """Platform under the sensor and the penetration below its surface [m] (0 if none)."""
        i, pen = platform_under(self.scene.platforms,
                                self.position if position is None else position)
        return (None, 0.0) if i is None else (self.scene.platforms[i], pen)

    def _contact_force(self) -> np.ndarray:
        _, pen = self.contact()
        if pen <= 0.0:
            return np.zeros(3)
        fz = max(0.0, self.kp * pen - self.dp * self.velocity[2])
        return np.array([0.0, 0.0, fz])

    def control(self) -> np.ndarray:
        """One control cycle of the law: filter the target, clip the error, spring-damper,
        rate limit; returns (and holds) the controller's force [N]."""
        law = self.law
        a = law.target_filter
        self.equilibrium = (1.0 - a) * np.asarray(self.target, dtype=float) + a * self.equilibrium
        err = np.clip(self.equilibrium - self.position, -law.error_clip, law.error_clip)
        f = self.k * err - self.d * self.velocity
        self.command = self.command + np.clip(f - self.command, -law.max_force_step,
                                              law.max_force_step)
        return self.command

    def cycle(self) -> None:
        """One control cycle of ``1 / rate_hz`` s (one sample)."""
        h = self.h
        self.force = self._contact_force()
        if self.frozen:
            self.command = np.zeros(3)
        else:
            acc = (self.control() + self.force) / self.m
            self.position = self.position + self.velocity * h + 0.5 * acc * h * h
            self.velocity = self.velocity + acc * h
        self.force = self._contact_force()
        self.peak_force = max(self.peak_force, float(np.linalg.norm(self.force)))

    def step(self, dt: float) -> None:
        """Advance ``dt`` [s] in whole control cycles (a remainder is carried to the next
        step); ``peak_force`` = largest contact force among them."""
        self._due += max(0.0, dt)
        self.peak_force = float(np.linalg.norm(self.force))
        n = int(np.floor(self._due / self.h + 1e-9))
        self._due -= n * self.h
        for _ in range(n):
            self.cycle()

    def freeze(self) -> None:
        """A reflex: the arm stops where it is (brakes)."""
        self.frozen = True
        self.velocity = np.zeros(3)

    def release(self) -> None:
        """Control is back: the target restarts at the current pose (CRISP's ``on_activate``
        sets it to the measured pose) and the held force at zero."""
        self.frozen = False
        self.target = self.position.copy()
        self.equilibrium = self.position.copy()
        self.command = np.zeros(3)

    def normal_force(self) -> float:
        """Normal force on the sensor [N] (>= 0)."""
        return float(self.force[2])
