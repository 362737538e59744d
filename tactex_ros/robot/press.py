"""The press sequence as a pure state machine (no rclpy), ticked by the motion node. (The mock
arm it presses in tests and in the simulated graph: ``robot/mock_world.py``.)

The robot is under Cartesian impedance control: the motion node commands the controller's
*equilibrium* pose, and the arm pushes with ``F = K (x - x_eq)`` (``K`` the controller's
translational stiffness [N/m], known only roughly: CRISP 2.3 clamps it). A press therefore
commands the equilibrium *below* the surface, and trusts neither the scene's surface height nor
``K``:

``approach`` (lift to a safe height, travel above the platform, go to the approach point
``approach_height`` above its surface, braking into it at ``approach_brake``) -> ``tare``
(at the approach point and at rest, the normal force's offset is the median over
``tare_window_s``; it settles when the spread over the window is small and the arm does not
move; not settled within ``tare_deadline_s``, or an offset above ``tare_max_offset_n``,
refuses the press with that reason; the arm's height above its target there, times ``K``, is
the *lift*: a static force that holds it up) -> ``descend`` (a
guarded descent: the equilibrium goes straight down at ``descend_speed``, on past the scene's
surface, until the smoothed tared force reaches ``contact_force_n``: the surface is *found*
there, with a warning when it lies more than ``surface_warn_m`` from the scene's; then on until
``force_threshold``) -> ``settle`` (the hold: the force error moves the equilibrium with time
constant ``HOLD_TAU_S`` until the force has stayed within ``force_tolerance_n`` of the
threshold, at rest, for ``settle_s``; not within ``hold_deadline_s``: refused ``hold``) ->
``capture`` (the caller grabs a frame and calls ``captured``; a light press without capture
goes straight on) -> ``retract`` (back to the approach point) -> ``done``.

A goal is reached when the arm is within ``position_tolerance`` of it, or within
``rest_tolerance`` and at rest (slower than ``rest_speed`` for ``rest_s``): a cable or a payload
error that holds the arm off still lets it arrive.

The spring's push at the measured pose, ``K (x - x_eq)``, is clipped every tick at ``cap``
(``spring_cap``: the midpoint of threshold and limit plus the lift, never above ``max_force``).
When the spring is at its cap, the arm at rest and the force below the threshold's band,
something the lift missed holds the arm up: the cap grows by the spring's push minus the contact
force, up to ``max_force``; there the press is refused ``stalled``. The equilibrium never goes
below ``equilibrium_floor`` under the scene's surface (``surface_search + max_depth + max_force
/ K``) nor below the workspace. No contact: the sensor ``surface_search`` below the scene's
surface without contact (``no contact``), ``max_depth`` below the surface found without the
threshold (``too soft``), or the equilibrium at its floor with the arm at rest.

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

import math
from dataclasses import dataclass, field
from typing import Protocol
from collections.abc import Sequence

import numpy as np

from ..core.errors import InputError

APPROACH, TARE, DESCEND, SETTLE, CAPTURE, RETRACT, DONE = (
    "approach", "tare", "descend", "settle", "capture", "retract", "done")


class PressSettings(Protocol):
    """How a press is made (the scene file's ``press``, ``scene.PressSettings``): m, m/s, N, s."""

    approach_height: float
    travel_speed: float
    descend_speed: float
    descend_fast_speed: float
    surface_tolerance: float
    found_tolerance: float
    max_speed: float
    force_threshold: float
    max_force: float
    max_depth: float
    settle_s: float
    approach_deadline_s: float
    descend_deadline_s: float
    capture_deadline_s: float
    capture_frames: int
    retract_deadline_s: float
    position_tolerance: float
    tare_window_s: float
    tare_max_spread_n: float
    tare_max_motion_m: float
    tare_max_offset_n: float
    tare_deadline_s: float
    surface_search: float
    contact_force_n: float
    surface_warn_m: float
    force_tolerance_n: float
    hold_deadline_s: float
    rest_speed: float
    rest_s: float
    rest_tolerance: float


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


#: [m/s^2] the target's deceleration into the approach point. The mock's 3 kg arm under the
#: sim profile's law (1000 N/m, 2 sqrt(K) N s/m) overshoots a target that stops from 0.4 m/s by
#: 4.7 mm (6 kg: 12 mm); braking at 1 m/s^2 leaves 1.5 mm (docs/simulated_world.md).
APPROACH_BRAKE_M_S2 = 1.0
#: [m/s^2] the target's deceleration at the end of the lift and of the travel (sideways or up:
#: an overshoot there presses nothing, but an arm that lags a target stopped at once rings)
TRAVEL_BRAKE_M_S2 = 2.0
#: [kg] the heaviest apparent mass the brake is sized for (the heaviest arm of the simulated
#: world's measurements): braking at a, an arm of mass m leads its target by m a / K.
BRAKE_MASS_KG = 6.0


def approach_brake(stiffness: float, approach_height: float) -> float:
    """The target's deceleration into the approach point [m/s^2] for controller stiffness
    ``stiffness`` [N/m] and the scene's ``approach_height`` [m]: ``APPROACH_BRAKE_M_S2``, or
    less where an arm of ``BRAKE_MASS_KG`` braking at it would lead its target by more than
    half the approach height (with 1 m/s^2, a 6 kg arm 5 mm above the fabric under 1000 N/m
    hit it at 31.9 N after a 0.1 m descent)."""
    return min(APPROACH_BRAKE_M_S2, stiffness * approach_height / (2.0 * BRAKE_MASS_KG))


@dataclass
class PressOutcome:
    success: bool
    reason: str                  # "" on success
    force_n: float               # normal force at capture [N] (0 when not captured)
    depth_m: float               # penetration below the surface at capture [m]
    max_force_n: float           # largest force magnitude seen during the press [N]
    tare: TareResult | None = None   # the tare before the descent (None: not reached)
    surface_z: float | None = None     # z where the descent found the surface [m] (None: not)
    warning: str = ""                  # e.g. the surface moved more than surface_warn_m
    phase_s: dict[str, float] = field(default_factory=dict)   # time spent in each phase [s]
    press_s: float = float("nan")      # from the approach's start to lift-off (the capture
                                       # done, the retract begins) [s]; nan: never lifted off


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


def peak_tared(samples: np.ndarray, offset_n: float) -> float:
    """Largest force magnitude [N] of ``samples`` (k, 2) of (normal force, magnitude) [N] with
    the normal offset ``offset_n`` [N] removed (``tared``, row by row)."""
    fn, mag = samples[:, 0], samples[:, 1]
    lateral2 = np.maximum(0.0, mag * mag - fn * fn)
    return float(np.sqrt(np.max(lateral2 + (fn - offset_n) ** 2)))


def equilibrium_floor(press: PressSettings, stiffness: float) -> float:
    """Deepest equilibrium below the scene's surface [m] for controller stiffness
    ``stiffness`` [N/m]: the search past the scene's surface, the sensor's ``max_depth`` below
    the surface found, and the spring's lead at ``max_force``."""
    return press.surface_search + press.max_depth + press.max_force / stiffness


def spring_cap(press: PressSettings, lift_n: float) -> float:
    """Largest spring force ``K (x - x_eq)`` [N] the press ever commands, given the static
    force ``lift_n`` [N] that holds the arm above its target at rest in free space (a cable, a
    payload heavier or lighter than configured; ``K`` times the offset of the arm from its
    target at the tare; a wrench bias does not move the arm): the midpoint of threshold and
    limit plus that lift (the contact must overcome it too), kept between the midpoint of
    threshold and that midpoint (a static force downward adds to the contact) and
    ``max_force``."""
    mid = 0.5 * (press.force_threshold + press.max_force)
    return float(np.clip(mid + lift_n, 0.5 * (press.force_threshold + mid), press.max_force))


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
    reach = s.surface_search + s.max_depth + s.force_threshold / stiffness
    need = (s.approach_height + reach) / s.descend_speed + 1.0
    if need > s.descend_deadline_s:
        raise InputError(
            f"{origin}: press.descend_deadline_s ({s.descend_deadline_s} s) is shorter than a "
            f"descent can take at controller stiffness {stiffness:g} N/m: {need:.1f} s "
            f"(approach_height {s.approach_height} m + surface_search {s.surface_search} m + "
            f"max_depth {s.max_depth} m + force_threshold / stiffness at descend_speed "
            f"{s.descend_speed} m/s, + 1 s)")


FORCE_SMOOTH_S = 0.05   # time constant of the smoothed force the press decides on [s]
HOLD_TAU_S = 0.06       # the hold closes the force error with this time constant [s]
#: the hold captures within this fraction of ``force_tolerance_n`` (the measured force): the
#: rest of the band is left for the reading's own error (drift, a bias that changes with the
#: pose: the true force must be within ``force_tolerance_n``)
CAPTURE_BAND = 0.5
#: [s] after contact the descent's speed is the force error over (K x RAMP_TAU_S), at least
#: descend_speed and at most descend_fast_speed: the force rises fast, then eases into the hold
RAMP_TAU_S = 0.08
#: [m/s^2] the fast descent slows to descend_speed at this deceleration, reaching it
#: DESCENT_MARGIN_M above the band where the surface may be
DESCENT_BRAKE_M_S2 = 0.5
DESCENT_MARGIN_M = 0.001
#: [s] how long an arm moving faster than its target takes to fall back to it (the mock's
#: heaviest arm, 5 kg under 1000 N/m and 2 sqrt(K) N s/m: 1 / (zeta omega) = 0.14 s, and
#: more: 0.15 s left 16 cycles over 12 N in 400 worlds, 0.25 s none)
ARM_SETTLE_S = 0.25
#: [m] the retract ends at least this far above the highest the surface may be
RETRACT_CLEAR_M = 0.005
#: [s] time constant of the static sag estimate on the travel leg (the arm's height below its
#: target times K: a payload error or a cable's pull)
SAG_SMOOTH_S = 0.1


class PressController:
    """One press of one platform. Call ``step`` at a steady rate with fresh measurements.

    ``stiffness``: the impedance controller's translational stiffness along z [N/m] (a
    position-controlled robot: a large value such as 1e5, the equilibrium is then the pose);
    the press needs it only roughly (the hold closes the loop on the force). ``capture``:
    False for a light press that only finds the surface and the force (no frame).
    ``period_s``: the loop's period [s] (a late tick moves the target at most two periods'
    worth). ``hold_s``: measurements older than this [s] (``step``'s ``state_age_s``) hold the
    target where it is and step nothing (``held``). ``surface_hint``: the surface z [m] an
    earlier press of this platform found (None: the scene's, known to ``surface_tolerance``);
    the approach point and the slow band then sit lower by ``surface_tolerance -
    found_tolerance``.
    """

    def __init__(self, scene: Workspace, platform: Platform, start: np.ndarray, now: float,
                 stiffness: float = 1e5, capture: bool = True, period_s: float = 0.02,
                 hold_s: float = math.inf, surface_hint: float | None = None) -> None:
        if not stiffness > 0:
            raise ValueError("stiffness must be positive [N/m]")
        if not period_s > 0:
            raise ValueError("period_s must be positive [s]")
        if not hold_s > 0:
            raise ValueError("hold_s must be positive [s]")
        self.hold_s = hold_s
        self.held = False      # the last step held the target: its measurements were stale
        # a late tick moves the target at most two periods' worth: a stalled loop must not
        # jump it (a step makes an impedance-controlled arm overshoot)
        self.max_move_dt = 2.0 * period_s
        self.scene, self.platform, self.s, self.k = scene, platform, scene.press, stiffness
        self.brake = approach_brake(stiffness, self.s.approach_height)   # [m/s^2]
        self.wants_capture = capture
        surface = np.asarray(platform.position, dtype=float)
        self.surface_z = surface[2]
        known = surface_hint is not None and math.isfinite(surface_hint)
        #: where the surface is expected [m] and how far above it the contact may come [m]
        self.expected_z = float(surface_hint) if known else float(surface[2])
        self.tolerance = self.s.found_tolerance if known else self.s.surface_tolerance
        lower = self.s.surface_tolerance - self.tolerance
        self.approach_point = np.array([surface[0], surface[1],
                                        self.expected_z + self.s.approach_height - lower])
        self.bottom = clamp(scene, np.array([surface[0], surface[1], self.expected_z])
                            - [0.0, 0.0, equilibrium_floor(self.s, stiffness)])
        start = clamp(scene, start)
        safe_z = max(start[2], self.approach_point[2])
        self._waypoints = [np.array([start[0], start[1], safe_z]),
                           np.array([surface[0], surface[1], safe_z]), self.approach_point]
        self.target = start.copy()
        self.phase = APPROACH
        self.phase_start = now
        self.start_t = now
        self.phase_s: dict[str, float] = {}
        self.lift_off_t: float | None = None
        self.sag_m = 0.0                   # the arm's height below its target on the travel [m]
        self.raised_m = 0.0                # the approach point raised by the sag [m]
        self.image_contact: bool | None = None   # the camera's latest verdict (None: unknown)
        self._last = now
        self._now = now
        self.failure = ""
        self.warning = ""
        self.capture_force = 0.0
        self.capture_depth = 0.0
        self.max_force = 0.0
        self._need_capture = False
        self._tare = Tare(self.s.tare_window_s, self.s.tare_max_spread_n,
                          self.s.tare_max_motion_m)
        self.tare: TareResult | None = None
        self.force_n = 0.0
        self.force_avg = 0.0               # smoothed normal force [N]
        self.lift_n = 0.0                   # static force holding the arm up at the tare [N]
        self.cap = spring_cap(self.s, 0.0)  # largest commanded spring force [N]
        self.surface_found: float | None = None   # z where the descent met the surface [m]
        self._touch = (0.0, 0.0)           # (z [m], smoothed force [N]) when it met it
        self._prev: np.ndarray | None = None
        self.speed = 0.0                   # smoothed measured speed [m/s]
        self._rest_since: float | None = None
        self._band_since: float | None = None

    # ------------------------------------------------------------------ helpers
    def _enter(self, phase: str, now: float) -> None:
        self.phase_s[self.phase] = self.phase_s.get(self.phase, 0.0) + (now - self.phase_start)
        if phase == RETRACT and self.lift_off_t is None and self.phase in (SETTLE, CAPTURE):
            self.lift_off_t = now
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
                SETTLE: self.s.settle_s + self.s.hold_deadline_s + 1.0,
                CAPTURE: self.s.capture_deadline_s,
                RETRACT: self.s.retract_deadline_s}.get(self.phase, float("inf"))

    def _move_towards(self, goal: np.ndarray, speed: float, dt: float) -> bool:
        """Advance the target towards ``goal`` at ``speed`` [m/s]; True when it is there."""
        step = min(speed, self.s.max_speed) * min(dt, self.max_move_dt)
        d = goal - self.target
        dist = float(np.linalg.norm(d))
        self.target = goal.copy() if dist <= step else self.target + d * (step / dist)
        self.target = clamp(self.scene, self.target)
        return dist <= step

    def _track(self, now: float, position: np.ndarray, force_n: float, dt: float) -> None:
        """Smoothed force and speed; since when the arm has been at rest."""
        if dt > 0:
            w = min(1.0, dt / FORCE_SMOOTH_S)
            self.force_avg += w * (force_n - self.force_avg)
            if self._prev is not None:
                v = math.dist(position, self._prev) / dt
                self.speed += w * (v - self.speed)
        else:
            self.force_avg = force_n if self._prev is None else self.force_avg
        self._prev = position.copy()
        if self.speed <= self.s.rest_speed:
            self._rest_since = now if self._rest_since is None else self._rest_since
        else:
            self._rest_since = None

    def _at_rest(self, now: float) -> bool:
        """The measured speed has stayed below ``rest_speed`` for ``rest_s``."""
        return self._rest_since is not None and now - self._rest_since >= self.s.rest_s

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
             force_magnitude: float | None = None, state_age_s: float = 0.0,
             samples: np.ndarray | None = None, contact: bool | None = None) -> np.ndarray:
        """Advance to time ``now`` [s] given the measured position [m], the signed normal force
        [N] (positive = pressing) and the force magnitude [N] (default ``|force_n|``), measured
        ``state_age_s`` [s] ago. Older than ``hold_s``: nothing is stepped and the target stays
        where it is (``held``); a target moved on a force not seen could press on unseen.
        ``samples``: every wrench sample since the last step, (k, 2) of (normal force,
        magnitude) [N] as measured: the force limit and ``max_force`` take the largest of them
        (a 1 kHz stream between 50 Hz steps). ``contact``: the camera's latest contact verdict
        (True: the gel image shows contact; None: no camera stream).

        Returns the equilibrium position to command (always inside the workspace).
        """
        self.held = state_age_s > self.hold_s
        if self.held:
            return self.target
        dt = max(0.0, min(now - self._last, 0.2))  # a stalled loop must not jump the target
        self._last = self._now = now
        position = np.asarray(position, dtype=float)
        mag = abs(force_n) if force_magnitude is None else float(force_magnitude)
        offset = 0.0 if self.tare is None else self.tare.offset_n
        if self.tare is not None:
            force_n, mag = tared(force_n, mag, offset)
        peak = mag
        if samples is not None and len(samples):
            arr = np.asarray(samples, dtype=float)
            peak = max(peak, peak_tared(arr, offset))
            # the tick's normal force: the mean of its samples (less noise than the newest)
            force_n = float(np.mean(arr[:, 0])) - offset
        self.force_n = force_n     # the normal force the press acts on (tared once settled)
        self.image_contact = contact
        self.max_force = max(self.max_force, peak)
        self._track(now, position, force_n, dt)
        if self.phase == DONE:
            return self.target
        self._check_limits(now, force_n, peak)
        if self.phase == APPROACH:
            self._approach(now, position, dt)
        elif self.phase == TARE:
            self._tare_step(now, position, force_n)
        elif self.phase == DESCEND:
            self._descend(now, position, dt)
        elif self.phase == SETTLE:
            self._settle(now, position, dt)
        elif self.phase == RETRACT:  # noqa: SIM102 - the phase dispatch stays one branch a phase
            # off the surface again, the arm rests the travel's sag below its target, as at
            # the approach's waypoints (else a sagging arm waits rest_s there)
            if self._arrive(self._retract_point(), self.s.travel_speed, position, dt,
                            self._free_sag()):
                self._enter(DONE, now)
        return self.target

    def _check_limits(self, now: float, force_n: float, mag: float) -> None:
        """Abort on the force limit (``mag``: the largest magnitude of every sample since the
        last tick), a normal force of the wrong sign while pressing, or the phase's deadline
        (checked on every tick, whatever the phase)."""
        s = self.s
        if mag > s.max_force:
            why = f"force limit: {mag:.1f} N > max_force {s.max_force} N"
            if self.phase == RETRACT:       # lifting off already: go on, but never a success
                self.failure = self.failure or f"{why} (while retracting)"
            else:
                self.abort(why, now)
        elif (self.force_avg < -s.force_threshold and force_n < -s.force_threshold
              and self.phase in (DESCEND, SETTLE, CAPTURE)):
            self.abort(f"force sign: the normal force reads {force_n:.1f} N while pressing; "
                       "the wrench sign (force_sign) is wrong for this robot", now)
        if now - self.phase_start > self._deadline():
            self.abort(f"deadline: phase {self.phase} took longer than "
                       f"{self._deadline():.1f} s", now)

    def _arrive(self, goal: np.ndarray, speed: float, position: np.ndarray, dt: float,
                sag_m: float = 0.0) -> bool:
        """Move the target towards ``goal``; True once the target is there and the measured
        position within ``position_tolerance`` of where the arm rests under it (``sag_m`` [m]
        below it: a static force measured on the travel), or within ``rest_tolerance`` and at
        rest (an arm held off by a static force, a cable or friction, still arrives)."""
        if not self._move_towards(goal, speed, dt):
            return False
        off = float(np.linalg.norm(position - goal + [0.0, 0.0, sag_m]))
        return off <= self.s.position_tolerance or (
            off <= self.s.rest_tolerance and self._at_rest(self._now))

    def _free_sag(self) -> float:
        """[m] How far below its target the arm rests in free air: the travel's sag
        (``sag_m``), at most ``approach_height`` either way."""
        return float(np.clip(self.sag_m, -self.s.approach_height, self.s.approach_height))

    def _approach(self, now: float, position: np.ndarray, dt: float) -> None:
        """Through the waypoints (lift, travel, approach point); then tare. Into the approach
        point the target slows at ``approach_brake``: an impedance-controlled arm lags
        its moving target and overshoots where the target stops, towards the surface."""
        speed = self.s.travel_speed
        if len(self._waypoints) == 2 and dt > 0:
            # the travel leg keeps its height: the arm's height below the target is the sag
            w = min(1.0, dt / SAG_SMOOTH_S)
            self.sag_m += w * (float(self.target[2] - position[2]) - self.sag_m)
        left = float(np.linalg.norm(self._waypoints[0] - self.target))
        brake = self.brake if len(self._waypoints) == 1 else TRAVEL_BRAKE_M_S2
        speed = min(speed, math.sqrt(2.0 * brake * left))
        # the sag is known once the travel has begun: the arm rests that far below the
        # travel's end and the approach point (else an arm sagging more than
        # position_tolerance waits rest_s at each: a 6 kg arm with 3 N down, 0.4 s)
        if self._arrive(self._waypoints[0], speed, position, dt, self._free_sag()):
            self._waypoints.pop(0)
            if len(self._waypoints) == 1:
                # a payload or cable pulling down holds the arm below its target: raise the
                # approach point by that, so the arm, not its target, stops approach_height
                # above the surface (at most by approach_height)
                self.raised_m = float(np.clip(self.sag_m, 0.0, self.s.approach_height))
                self.approach_point = self.approach_point + [0.0, 0.0, self.raised_m]
                self._waypoints[0] = self.approach_point
            if not self._waypoints:
                self._enter(TARE, now)

    def _tare_step(self, now: float, position: np.ndarray, force_n: float) -> None:
        """Hold the approach point and measure the offset; descend once it settled, refuse
        the press when it does not settle in time or is too large."""
        s = self.s
        if self.image_contact:
            self.abort("tare in contact: the gel image shows contact at the approach point "
                       f"({self.approach_point[2] - self.expected_z:.4f} m above the expected "
                       "surface); the surface is higher than the scene says or the arm sags: "
                       "measure the scene again (tactex robot measure-scene)", now)
            return
        self._tare.add(now, force_n, position)
        got = self._tare.settled()
        if got is not None:
            if abs(got.offset_n) > s.tare_max_offset_n:
                self.abort(f"tare: offset {got.offset_n:.2f} N is larger than "
                           f"tare_max_offset_n {s.tare_max_offset_n} N (payload or wrench "
                           "model error; the press would act on a force that far off)", now)
                return
            self.tare = got
            self.lift_n = self.k * float(position[2] - self.target[2])
            self.cap = spring_cap(s, self.lift_n)
            self.force_avg = 0.0
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

    def _guard(self, position: np.ndarray) -> None:
        """Keep the equilibrium where its spring pushes with at most ``cap`` at the measured
        pose (``K (x - x_eq) <= cap``), no deeper than ``bottom``, no higher than the approach
        point, inside the workspace."""
        z = max(self.target[2], position[2] - self.cap / self.k, self.bottom[2])
        self.target = clamp(self.scene, np.array([self.target[0], self.target[1],
                                                  min(z, self.approach_point[2])]))

    def _found(self, position: np.ndarray) -> None:
        """The smoothed force says contact: remember where, warn if the scene is off."""
        s = self.s
        if self.surface_found is not None or (self.force_avg < s.contact_force_n
                                              and not self.image_contact):
            return
        self.surface_found = float(position[2])
        self._touch = (self.surface_found, self.force_avg)
        self._warn_moved()

    def _warn_moved(self) -> None:
        s = self.s
        moved = self.surface_found - self.surface_z
        if abs(moved) > s.surface_warn_m:
            self.warning = (f"surface moved: {self.platform.id} found at z "
                            f"{self.surface_found:.4f} m, {moved * 1000:+.1f} mm from the "
                            f"scene's {self.surface_z:.4f} m (more than surface_warn_m "
                            f"{s.surface_warn_m * 1000:g} mm); measure the scene again")

    def _too_deep(self, position: np.ndarray, now: float) -> bool:
        """Abort when the sensor is past the search below the scene's surface without contact,
        or ``max_depth`` below the surface it found."""
        s = self.s
        if self.surface_found is None:
            if self.expected_z - position[2] >= s.surface_search:
                self.abort(f"no contact: {self.force_avg:.2f} N < contact_force_n "
                           f"{s.contact_force_n} N with the sensor surface_search "
                           f"{s.surface_search} m below the expected surface", now)
                return True
        elif self.surface_found - position[2] >= s.max_depth:
            self.abort(f"too soft: {self.force_avg:.2f} N < force_threshold "
                       f"{s.force_threshold} N with the sensor max_depth {s.max_depth} m "
                       "below the surface it found", now)
            return True
        return False

    def _capped(self, position: np.ndarray) -> bool:
        """The spring pushes with its cap at the measured pose (``_guard`` binds)."""
        return bool(self.target[2] <= position[2] - self.cap / self.k + 1e-6)

    def _stalled(self, now: float, position: np.ndarray) -> bool:
        """The spring pushes with its cap, the arm is at rest and the force is below the
        threshold's band (``force_tolerance_n``): something holds the arm up (an upward force,
        friction) that the tare's lift underestimated. The spring's push minus the contact
        force measures it: the cap grows by it, up to ``max_force``; at ``max_force`` the
        press is refused (True)."""
        s = self.s
        if (not self._capped(position) or not self._at_rest(now)
                or self.force_avg >= s.force_threshold - s.force_tolerance_n):
            return False
        if self.cap >= s.max_force - 1e-9:
            self.abort(f"stalled: {self.force_avg:.2f} N < force_threshold "
                       f"{s.force_threshold} N with the spring at max_force {s.max_force} N "
                       "and the arm at rest: an unmodelled force or friction holds it up",
                       now)
            return True
        self.lift_n = max(self.lift_n, self.cap - self.force_avg)
        self.cap = spring_cap(s, self.lift_n)
        self._rest_since = None          # judge again after the next rest
        return False

    def _descend(self, now: float, position: np.ndarray, dt: float) -> None:
        """Guarded descent: the equilibrium goes down past the scene's surface until the
        smoothed force says contact (the surface found) and then the threshold (hold)."""
        s = self.s
        self._found(position)
        if self.force_avg >= s.force_threshold or (
                self.force_avg >= s.force_threshold - s.force_tolerance_n
                and self._capped(position) and self._at_rest(now)):   # the hold's work
            self._band_since = None
            self._enter(SETTLE, now)
            return
        if self._too_deep(position, now):
            return
        at_bottom = self._move_towards(self.bottom, self._descent_speed(position), dt)
        self._guard(position)
        if self._stalled(now, position):
            return
        if at_bottom and self._at_rest(now):
            self.abort(f"no contact: {self.force_avg:.2f} N < force_threshold "
                       f"{s.force_threshold} N with the equilibrium at its floor "
                       f"{self.surface_z - self.target[2]:.4f} m below the scene's surface",
                       now)

    def _retract_point(self) -> np.ndarray:
        """Straight up to the approach point, or higher: at least ``RETRACT_CLEAR_M`` above
        the highest the surface may be (``expected_z + tolerance``) and above where the
        surface was found (an approach point inside a surface higher than expected, a
        refused tare in contact, is never the retract's goal)."""
        top = self.expected_z + self.tolerance
        if self.surface_found is not None:
            top = max(top, self.surface_found)
        z = max(float(self.approach_point[2]), top + RETRACT_CLEAR_M)
        return clamp(self.scene, np.array([self.approach_point[0], self.approach_point[1], z]))

    def _descent_speed(self, position: np.ndarray) -> float:
        """[m/s] Above the band where the surface may be (``expected_z + tolerance``), the
        arm's lower bound (its measured height or its target's plus the lift) slows from
        ``descend_fast_speed`` at ``DESCENT_BRAKE_M_S2`` to ``descend_speed``
        ``DESCENT_MARGIN_M`` above the band; after contact the force error over ``K x
        RAMP_TAU_S``, between the two, and ``descend_speed`` whenever the tick's force reads
        below ``contact_force_n`` with the arm above where it found the surface (thrown off
        it again)."""
        s = self.s
        fast = max(s.descend_fast_speed, s.descend_speed)
        if self.surface_found is not None:
            if self.force_n < s.contact_force_n and position[2] > self.surface_found:
                # thrown back above where it met the surface (a heavy arm on a rigid platform:
                # the smoothed force still says contact): the next impact at the contact
                # speed, not at the ramp's (a 6 kg arm with 3.1 N down hit at 12.2 N)
                return s.descend_speed
            err = s.force_threshold - self.force_avg
            return float(np.clip(err / (self.k * RAMP_TAU_S), s.descend_speed, fast))
        low = min(float(position[2]), float(self.target[2]) + self.lift_n / self.k)
        # an arm moving faster than the contact speed (catching up its target's lag, an
        # underdamped heavy arm) slows later than its target: slow that much earlier
        lead = max(0.0, self.speed - s.descend_speed) * ARM_SETTLE_S
        gap = low - (self.expected_z + self.tolerance) - DESCENT_MARGIN_M - lead
        if gap <= 0.0:
            return s.descend_speed
        return min(fast, s.descend_speed + math.sqrt(2.0 * DESCENT_BRAKE_M_S2 * gap))

    def _settle(self, now: float, position: np.ndarray, dt: float) -> None:
        """The hold: the smoothed force error moves the equilibrium (``HOLD_TAU_S``, guarded
        by ``cap``); once the force has stayed within ``force_tolerance_n`` of the threshold
        with the arm at rest for ``settle_s``, ask for the capture."""
        s = self.s
        self._found(position)
        if self._too_deep(position, now):
            return
        err = s.force_threshold - self.force_avg
        self.target = self.target - [0.0, 0.0, err / (self.k * HOLD_TAU_S) * dt]
        self._guard(position)
        if self._stalled(now, position):
            return
        band = CAPTURE_BAND * s.force_tolerance_n
        # the smoothed force and the tick's own (its samples' mean: a ringing arm's force
        # swings about the smoothed one) both in the band, at rest
        if (abs(err) <= band and abs(s.force_threshold - self.force_n) <= band
                and self.speed <= s.rest_speed):
            self._band_since = now if self._band_since is None else self._band_since
        else:
            self._band_since = None
        if self._band_since is None or now - self._band_since < s.settle_s:
            if now - self.phase_start > s.settle_s + s.hold_deadline_s - 1e-9:
                self.abort(f"hold: the force stayed {self.force_avg:.2f} N, not within "
                           f"force_tolerance_n {s.force_tolerance_n} N of force_threshold "
                           f"{s.force_threshold} N at rest, for hold_deadline_s "
                           f"{s.hold_deadline_s} s", now)
            return
        self.capture_force = self.force_avg
        if self.surface_found is not None:
            # the surface where the force would be zero: back along the line through the
            # touch and the hold (a soft platform is already pressed in at contact_force_n)
            z0, f0 = self._touch
            if self.force_avg > f0 + 0.5 and z0 > position[2]:
                self.surface_found = z0 + (z0 - position[2]) * f0 / (self.force_avg - f0)
                self.warning = ""
                self._warn_moved()
        found = self.surface_z if self.surface_found is None else self.surface_found
        self.capture_depth = max(0.0, found - position[2])
        if self.wants_capture:
            self._need_capture = True
            self._enter(CAPTURE, now)
        else:
            self._enter(RETRACT, now)

    @property
    def done(self) -> bool:
        return self.phase == DONE

    def outcome(self) -> PressOutcome:
        phase_s = dict(self.phase_s)
        if self.phase != DONE:
            phase_s[self.phase] = phase_s.get(self.phase, 0.0) + self._now - self.phase_start
        return PressOutcome(success=self.done and not self.failure, reason=self.failure,
                            force_n=self.capture_force, depth_m=self.capture_depth,
                            max_force_n=self.max_force, tare=self.tare,
                            surface_z=self.surface_found, warning=self.warning,
                            phase_s=phase_s,
                            press_s=(float("nan") if self.lift_off_t is None
                                     else self.lift_off_t - self.start_t))
