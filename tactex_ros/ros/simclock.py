"""The simulated graph's own time.

In a simulated graph (``use_sim_time`` true on every node) the mock arm is the clock source: it
steps its physics by a fixed dt and publishes ``rosgraph_msgs/Clock`` on ``/clock`` advancing by
dt per computed step, at most as fast as the wall clock, slower when the machine is starved.
Every node then measures its deadlines, rates and staleness in that simulated time, so a
starved machine makes a simulated trial slower, never different. The robot graph keeps wall
time (``time.monotonic``).

``NodeClock(node).now()`` [s] is the one clock a node's deadlines use: ROS time when the node
has ``use_sim_time``, else ``time.monotonic()``. A simulated clock that stands still for
``stall_s`` of wall time (no ``/clock`` at all, or the clock source stopped) raises
``SimClockStalled`` from ``now()``: every wait that reads the clock ends then, with what failed
named (a run-time failure, exit status 1).
"""

from __future__ import annotations

import time
from typing import Any

from rclpy.qos import QoSProfile, ReliabilityPolicy

from ..core.errors import DeviceError

#: The /clock topic (rclpy's TimeSource subscribes to it when use_sim_time is true)
CLOCK_TOPIC = "/clock"

#: Most wall time [s] a simulated clock may stand still before a wait fails on it
SIM_STALL_S = 60.0


def clock_qos() -> QoSProfile:
    """The /clock QoS: keep last 1, best effort, as rclpy's TimeSource subscribes and
    rclcpp's ``rclcpp::ClockQoS`` publishes (a reliable publisher would also match)."""
    return QoSProfile(depth=1, reliability=ReliabilityPolicy.BEST_EFFORT)


def uses_sim_time(node: Any) -> bool:
    """Whether ``node`` (an rclpy Node) runs on the simulated clock (``use_sim_time``)."""
    try:
        return bool(node.get_parameter("use_sim_time").value)
    except Exception:
        return False


class SimClockStalled(DeviceError):
    """The simulated clock has not advanced within ``SIM_STALL_S`` of wall time."""


class NodeClock:
    """``now()`` [s]: the node's ROS time on a simulated clock, else ``time.monotonic()``.

    On a simulated clock, ``now()`` raises ``SimClockStalled`` once the clock has stood still
    for ``stall_s`` [s] of wall time (``stall_s`` <= 0: never)."""

    def __init__(self, node: Any, stall_s: float = SIM_STALL_S) -> None:
        self.node = node
        self.sim = uses_sim_time(node)
        self.stall_s = float(stall_s)
        self._seen = (-1.0, time.monotonic())    # (last simulated time, wall time it changed)

    def now(self) -> float:
        """Seconds on this node's deadline clock (see the class doc)."""
        if not self.sim:
            return time.monotonic()
        self._peek()
        t, since = self._seen
        wall = time.monotonic()
        if self.stall_s > 0 and wall - since > self.stall_s:
            raise SimClockStalled(
                (f"no {CLOCK_TOPIC} within {self.stall_s:g} s (is the mock arm, the simulated "
                 "graph's clock source, running?)") if t == 0 else
                (f"the simulated clock ({CLOCK_TOPIC}) stood still for {wall - since:.0f} s "
                 f"of wall time at t = {t:.3f} s: the mock arm (the clock source) stopped"))
        return t

    def read(self) -> float:
        """``now()`` without the stall check (for callbacks and health reports)."""
        if not self.sim:
            return time.monotonic()
        self._peek()
        return self._seen[0]

    def behind_s(self) -> float:
        """Wall seconds [s] since the simulated clock last advanced (0 on wall time)."""
        if not self.sim:
            return 0.0
        self._peek()
        return time.monotonic() - self._seen[1]

    def _peek(self) -> None:
        t = self.node.get_clock().now().nanoseconds * 1e-9
        if t != self._seen[0]:
            self._seen = (t, time.monotonic())


class RealTimeFactor:
    """Simulated seconds per wall second over the last ``window_s`` [s] of wall time (the
    clock source's real-time factor: 1 when it keeps up, below 1 when starved)."""

    def __init__(self, window_s: float = 2.0) -> None:
        self.window_s = float(window_s)
        self._samples: list[tuple[float, float]] = []     # (wall, sim)

    def tick(self, sim_s: float, wall_s: float | None = None) -> None:
        """One reading of the simulated clock [s]; 0 (no /clock yet) is left out."""
        if sim_s <= 0.0:
            return
        wall = time.monotonic() if wall_s is None else wall_s
        self._samples.append((wall, sim_s))
        while len(self._samples) > 2 and self._samples[1][0] < wall - self.window_s:
            self._samples.pop(0)

    def factor(self, wall_s: float | None = None) -> float | None:
        """The factor, None before two samples; the time since the last step counts (a
        stopped source falls towards 0)."""
        if len(self._samples) < 2:
            return None
        wall = time.monotonic() if wall_s is None else wall_s
        (w0, s0), (_, s1) = self._samples[0], self._samples[-1]
        span = max(wall, self._samples[-1][0]) - w0
        return (s1 - s0) / span if span > 0 else None
