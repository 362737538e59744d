"""The press sequence as a pure state machine (no rclpy), ticked by the motion node.

Phases: ``approach`` (lift to a safe height, travel above the platform, go to the approach point
``approach_height`` above its surface) -> ``descend`` (straight down at ``descend_speed`` until
the normal force reaches ``force_threshold`` or the target reaches ``max_depth`` below the
surface) -> ``settle`` (hold ``settle_s``) -> ``capture`` (the caller grabs a frame and calls
``captured``) -> ``retract`` (back to the approach point) -> ``done``.

Enforced on every tick, whatever the phase: the commanded target stays inside the workspace
box, moves at most ``max_speed`` (and the phase's own speed) per second, the normal force never
above ``max_force`` (abort: retract at once), and each phase ends before its deadline (abort).
A failed press still retracts; ``result`` then carries the reason. Units: m, s, N.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..scene import Platform, Scene

APPROACH, DESCEND, SETTLE, CAPTURE, RETRACT, DONE = ("approach", "descend", "settle", "capture",
                                                    "retract", "done")


@dataclass
class PressOutcome:
    success: bool
    reason: str                  # "" on success
    force_n: float               # normal force at capture [N] (0 when not captured)
    depth_m: float               # penetration below the surface at capture [m]
    max_force_n: float           # largest normal force seen during the press [N]


class PressController:
    """One press of one platform. Call ``step`` at a steady rate with fresh measurements."""

    def __init__(self, scene: Scene, platform: Platform, start: np.ndarray, now: float) -> None:
        self.scene, self.platform, self.s = scene, platform, scene.press
        surface = np.asarray(platform.position, dtype=float)
        self.surface_z = surface[2]
        self.approach_point = surface + [0.0, 0.0, self.s.approach_height]
        start = scene.clamp(np.asarray(start, dtype=float))
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

    # ------------------------------------------------------------------ helpers
    def _enter(self, phase: str, now: float) -> None:
        self.phase, self.phase_start = phase, now

    def _abort(self, reason: str, now: float) -> None:
        if not self.failure:
            self.failure = reason
        if self.phase == RETRACT:
            self._enter(DONE, now)
        else:
            self._enter(RETRACT, now)

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
        self.target = self.scene.clamp(self.target)
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
            self._abort(f"capture failed: {reason}", now)
        else:
            self._enter(RETRACT, now)

    def step(self, now: float, position: np.ndarray, force_n: float) -> np.ndarray:
        """Advance to time ``now`` [s] given the measured position [m] and normal force [N].

        Returns the target position to command (always inside the workspace).
        """
        dt = max(0.0, min(now - self._last, 0.2))  # a stalled loop must not jump the target
        self._last = now
        position = np.asarray(position, dtype=float)
        self.max_force = max(self.max_force, force_n)
        if self.phase == DONE:
            return self.target
        if force_n > self.s.max_force and self.phase != RETRACT:
            self._abort(f"force limit: {force_n:.1f} N > max_force {self.s.max_force} N", now)
        if now - self.phase_start > self._deadline():
            self._abort(f"deadline: phase {self.phase} took longer than "
                        f"{self._deadline():.1f} s", now)
        tol = self.s.position_tolerance
        if self.phase == APPROACH:
            goal = self._waypoints[0]
            if self._move_towards(goal, self.s.travel_speed, dt) and \
                    np.linalg.norm(position - goal) <= tol:
                self._waypoints.pop(0)
                if not self._waypoints:
                    self._enter(DESCEND, now)
        elif self.phase == DESCEND:
            if force_n >= self.s.force_threshold:
                self.target = self.scene.clamp(position.copy())  # hold where contact is made
                self._enter(SETTLE, now)
            else:
                bottom = self.approach_point - [0.0, 0.0, self.s.approach_height +
                                                self.s.max_depth]
                at_bottom = self._move_towards(bottom, self.s.descend_speed, dt)
                if at_bottom and np.linalg.norm(position - bottom) <= tol:
                    self._abort(f"no contact: {force_n:.2f} N < force_threshold "
                                f"{self.s.force_threshold} N at max_depth {self.s.max_depth} m",
                                now)
        elif self.phase == SETTLE:
            if now - self.phase_start >= self.s.settle_s:
                self.capture_force = force_n
                self.capture_depth = max(0.0, self.surface_z - position[2])
                self._need_capture = True
                self._enter(CAPTURE, now)
        elif self.phase == RETRACT:
            if self._move_towards(self.approach_point, self.s.travel_speed, dt) and \
                    np.linalg.norm(position - self.approach_point) <= tol:
                self._enter(DONE, now)
        return self.target

    @property
    def done(self) -> bool:
        return self.phase == DONE

    def outcome(self) -> PressOutcome:
        return PressOutcome(success=self.done and not self.failure, reason=self.failure,
                            force_n=self.capture_force, depth_m=self.capture_depth,
                            max_force_n=self.max_force)


class ArmModel:
    """Mock arm: the end effector follows a commanded target with a speed limit; platforms push
    back with a linear spring (``stiffness`` N/m) when the sensor is below their surface within
    their radius. Positions in m, time in s."""

    def __init__(self, scene: Scene, start: np.ndarray, stiffness: float = 2000.0,
                 max_speed: float = 0.25) -> None:
        if stiffness <= 0 or max_speed <= 0:
            raise ValueError("stiffness and max_speed must be positive")
        self.scene, self.k, self.vmax = scene, stiffness, max_speed
        self.position = np.asarray(start, dtype=float).copy()
        self.target = self.position.copy()

    def step(self, dt: float) -> None:
        d = self.target - self.position
        dist = float(np.linalg.norm(d))
        step = self.vmax * dt
        self.position = self.target.copy() if dist <= step else self.position + d * step / dist

    def contact(self) -> tuple[Platform | None, float]:
        """Platform under the sensor and the penetration below its surface [m] (0 if none)."""
        for p in self.scene.platforms:
            c = np.asarray(p.position)
            if np.linalg.norm(self.position[:2] - c[:2]) <= p.radius:
                return p, max(0.0, c[2] - self.position[2])
        return None, 0.0

    def normal_force(self) -> float:
        """Normal force on the sensor [N]."""
        return self.k * self.contact()[1]
