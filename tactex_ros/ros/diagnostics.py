"""Live health on ``/diagnostics`` (``diagnostic_msgs/DiagnosticArray``), as rqt_robot_monitor,
the diagnostic aggregator and Foxglove read it.

Follows diagnostic_updater's conventions (ros/diagnostics, ``diagnostic_updater/
diagnostic_updater/_diagnostic_updater.py``, ``Updater``): one ``DiagnosticStatus`` per task,
named ``"<node name>: <task>"``, with a ``hardware_id`` (the device the task watches), a level
``OK`` (0) / ``WARN`` (1) / ``ERROR`` (2) (``STALE`` 3 is the aggregator's), a message and
``KeyValue`` pairs (strings); all of a node's statuses go out together, every period (1 s by
default) on the topic ``/diagnostics``. diagnostic_updater itself is not installable here (no
wheel), so this module builds the messages with ``diagnostic_msgs`` only.

``grade`` turns a measurement and its WARN / ERROR thresholds (node settings, ``diag_*``) into
a level; ``RateMeter`` measures a message rate and the age of the newest message.

ERROR means a fault. A pause the graph expects (a node starting, the mock camera preparing a new
placement, the operator placing fabrics) is a ``Phase``: a named state with its own level (OK or
WARN, with a message saying what is awaited and for how long already) and its own deadline;
only past that deadline does it turn ERROR, naming the overrun.
"""

from __future__ import annotations

import collections
import threading
import time
from collections.abc import Callable

OK, WARN, ERROR, STALE = 0, 1, 2, 3
DIAGNOSTICS_TOPIC = "/diagnostics"
LEVEL_NAMES = {OK: "OK", WARN: "WARN", ERROR: "ERROR", STALE: "STALE"}

def robot_mode_name(mode: int | None) -> str:
    """franka's robot_mode as its name (``'reflex (4)'``); None: not reported."""
    from ..robot.preflight import ROBOT_MODES
    if mode is None:
        return "not reported by this robot profile"
    return f"{ROBOT_MODES.get(int(mode), 'unknown')} ({int(mode)})"

# a task: () -> (level, message, {key: value})
Task = Callable[[], "tuple[int, str, dict[str, object]]"]


def grade(value: float | None, warn: float, error: float, higher_is_worse: bool = True) -> int:
    """The level of ``value`` against its thresholds (None: no measurement yet -> ERROR)."""
    if value is None:
        return ERROR
    if higher_is_worse:
        return ERROR if value >= error else WARN if value >= warn else OK
    return ERROR if value <= error else WARN if value <= warn else OK


class Phase:
    """An expected pause: a named state with its level and deadline (module doc).

    ``begin(name, deadline_s)`` starts it, ``end()`` ends it; ``apply`` turns a task's own
    result into the phase's while it lasts: the measurement's level capped at the phase's
    ``level`` (a measurement that is fine stays OK), the message prefixed with the phase's name
    and how long it has lasted; past ``deadline_s``: ERROR, ``"<name> overran its deadline"``.
    For ``settle_s`` after the end, measurements over a window that still holds the pause are
    capped at WARN ("settling after <name>"). Thread-safe."""

    def __init__(self, settle_s: float = 2.5) -> None:
        self.settle_s = settle_s
        self._lock = threading.Lock()
        self.name: str | None = None
        self.level = WARN
        self.since = 0.0
        self.deadline_s = 0.0
        self._ended: tuple[str, float] | None = None

    def begin(self, name: str, deadline_s: float, level: int = WARN,
              now: float | None = None) -> None:
        with self._lock:
            self.name, self.level, self.deadline_s = name, level, deadline_s
            self.since = time.monotonic() if now is None else now

    def end(self, now: float | None = None) -> None:
        with self._lock:
            if self.name is not None:
                self._ended = (self.name, time.monotonic() if now is None else now)
            self.name = None

    @property
    def active(self) -> bool:
        return self.name is not None

    def apply(self, result: tuple[int, str, dict[str, object]], now: float | None = None
              ) -> tuple[int, str, dict[str, object]]:
        """``result`` (level, message, values) as the phase reports it (see the class doc)."""
        now = time.monotonic() if now is None else now
        level, msg, values = result
        with self._lock:
            name, ended = self.name, self._ended
            since, deadline, cap = self.since, self.deadline_s, self.level
        if name is not None:
            lasted = now - since
            values = dict(values, state=name, **{"state for [s]": lasted,
                                                 "state deadline [s]": deadline})
            if lasted > deadline:
                return ERROR, f"{name} overran its deadline ({deadline:g} s): {msg}", values
            text = f"{name} ({lasted:.0f} s of at most {deadline:g} s)"
            return (min(level, cap), text if level == OK else f"{text}: {msg}", values)
        values = dict(values, state="running")
        if ended is not None and now - ended[1] < self.settle_s and level > WARN:
            return WARN, f"settling after {ended[0]}: {msg}", values
        return level, msg, values


def worst(*levels: int) -> int:
    return max(levels) if levels else OK


class RateMeter:
    """Arrival times of a stream over the last ``window_s``: rate [Hz] and age [s] (monotonic
    clock). ``tick()`` is cheap and thread-safe (call it from any callback)."""

    def __init__(self, window_s: float = 2.0) -> None:
        self.window_s = window_s
        self._t: collections.deque[float] = collections.deque()
        self._lock = threading.Lock()
        self.last: float | None = None
        self.count = 0

    def tick(self, now: float | None = None) -> None:
        now = time.monotonic() if now is None else now
        with self._lock:
            self._t.append(now)
            self.last = now
            self.count += 1
            while self._t and now - self._t[0] > self.window_s:
                self._t.popleft()

    def rate(self, now: float | None = None) -> float:
        """Messages per second over the window ending ``now``."""
        now = time.monotonic() if now is None else now
        with self._lock:
            n = sum(1 for t in self._t if now - t <= self.window_s)
        return n / self.window_s

    def age(self, now: float | None = None) -> float | None:
        """Seconds since the newest message (None: none yet)."""
        now = time.monotonic() if now is None else now
        return None if self.last is None else now - self.last


class Diagnostics:
    """A node's diagnostic tasks, published together every ``period_s`` on ``/diagnostics``.

    Made in a node's configure stage (the base releases its publisher and timer at cleanup);
    reports while the node is inactive too (a task sees ``node.active``)."""

    def __init__(self, node, period_s: float = 1.0) -> None:
        from diagnostic_msgs.msg import DiagnosticArray
        self.node = node
        self.tasks: list[tuple[str, str, Task]] = []
        self.pub = node.create_publisher(DiagnosticArray, DIAGNOSTICS_TOPIC, 10)
        # on the steady (wall) clock, also in a simulated graph: a simulation that stopped
        # (its clock standing still) is still reported
        from rclpy.clock import Clock, ClockType
        self.timer = node.create_timer(period_s, self.publish,
                                       clock=Clock(clock_type=ClockType.STEADY_TIME))

    def add(self, name: str, hardware_id: str, task: Task) -> None:
        """Task ``name`` (the status is named ``"<node>: <name>"``) watching ``hardware_id``."""
        self.tasks.append((name, hardware_id, task))

    def statuses(self) -> list:
        from diagnostic_msgs.msg import DiagnosticStatus, KeyValue
        out = []
        for name, hwid, task in self.tasks:
            try:
                level, message, values = task()
            except Exception as exc:  # noqa: BLE001 - a broken check is itself an error
                level, message, values = ERROR, f"check failed: {exc}", {}
            out.append(DiagnosticStatus(
                level=bytes([int(level)]), name=f"{self.node.get_name()}: {name}",
                message=message, hardware_id=hwid,
                values=[KeyValue(key=str(k), value=_text(v)) for k, v in values.items()]))
        return out

    def publish(self) -> None:
        from diagnostic_msgs.msg import DiagnosticArray
        msg = DiagnosticArray(status=self.statuses())
        msg.header.stamp = self.node.get_clock().now().to_msg()
        self.pub.publish(msg)


def _text(v: object) -> str:
    if isinstance(v, float):
        return f"{v:.4g}"
    return "" if v is None else str(v)


def summary(levels_and_messages: list[tuple[int, str]]) -> tuple[int, str]:
    """The worst level and the messages at that level, joined (``'ok'`` when all are OK)."""
    if not levels_and_messages:
        return OK, "ok"
    top = max(lv for lv, _ in levels_and_messages)
    if top == OK:
        return OK, "ok"
    return top, "; ".join(m for lv, m in levels_and_messages if lv == top)


class CameraHealth:
    """A camera's health from the frames it publishes: measured frame rate against the
    expected one, age of the newest frame, and the drift of the no-contact frame since the
    start [grey levels]: the mean absolute difference (every 8th pixel) between a frame and the
    first frame seen, at its lowest over the last ``drift_window_s`` (presses are shorter than
    that, so the lowest is a no-contact frame). ``th``: the node's settings (``diag_*``).
    ``simulated``: the frames are computed by a simulation (the mock camera), whose rate falls
    only when the machine cannot compute it in time: a low rate is then at most WARN,
    "simulation behind", never a camera ERROR."""

    def __init__(self, expected_hz: float, th, drift_window_s: float = 5.0,
                 simulated: bool = False) -> None:
        self.expected_hz = expected_hz
        self.simulated = simulated
        self.phase = Phase(settle_s=_settle_s(th))
        self.phase.begin("starting: waiting for the first frame", th.diag_startup_s)
        self.th = th
        self.meter = RateMeter(2.0)
        self.reference = None
        self._drift: collections.deque[tuple[float, float]] = collections.deque()
        self.drift_window_s = drift_window_s
        self._lock = threading.Lock()

    def observe(self, frame, now: float | None = None) -> None:
        import numpy as np
        now = time.monotonic() if now is None else now
        if self.meter.count == 0:
            self.phase.end(now)
        self.meter.tick(now)
        small = np.asarray(frame[::8, ::8], dtype=np.float32)
        if self.reference is None or self.reference.shape != small.shape:
            self.reference = small
        d = float(np.mean(np.abs(small - self.reference)))
        with self._lock:
            self._drift.append((now, d))
            while self._drift and now - self._drift[0][0] > self.drift_window_s:
                self._drift.popleft()

    def drift(self) -> float | None:
        """Lowest difference to the first frame over the window [grey levels]."""
        with self._lock:
            return min((d for _, d in self._drift), default=None)

    def check(self, now: float | None = None) -> tuple[int, str, dict[str, object]]:
        now = time.monotonic() if now is None else now
        th, rate, age, drift = self.th, self.meter.rate(now), self.meter.age(now), self.drift()
        parts = [(grade(age, th.diag_age_warn_s, th.diag_age_error_s),
                  "no frame yet" if age is None else f"newest frame {age:.2f} s old"),
                 self._rate_part(rate)]
        if drift is not None:
            parts.append((grade(drift, th.diag_drift_warn, th.diag_drift_error),
                          f"no-contact frame drifted {drift:.1f} grey levels"))
        level, message = summary(parts)
        return self.phase.apply((level, message, {
            "frame rate [Hz]": rate, "expected rate [Hz]": self.expected_hz,
            "newest frame age [s]": age, "frames": self.meter.count,
            "no-contact drift [grey levels]": drift}), now)


    def _rate_part(self, rate: float) -> tuple[int, str]:
        """The frame rate's (level, message)."""
        th = self.th
        level = grade(rate, th.diag_rate_warn * self.expected_hz,
                      th.diag_rate_error * self.expected_hz, higher_is_worse=False)
        text = f"frame rate {rate:.1f} Hz of {self.expected_hz:g}"
        if self.simulated and level != OK:
            return WARN, (f"simulation behind: {text} (the machine cannot compute the "
                          "simulated camera in real time)")
        return level, text


def _settle_s(th) -> float:
    """[s] after a pause, the rate window (2 s) still holds it: graded at most WARN meanwhile."""
    return 2.0 + max(th.diag_age_error_s, 0.5)


def link_check(meter: RateMeter, what: str, warn_s: float, error_s: float,
               now: float | None = None, phase: Phase | None = None,
               wall: float | None = None) -> tuple[int, str, dict[str, object]]:
    """A subscriber's view of a stream it needs: ERROR once its newest message is older than
    ``error_s`` (or none came), WARN above ``warn_s``, on the meter's clock (``now`` [s], the
    clock its ticks were stamped on: a simulated graph's simulated time). ``phase``: the
    node's start-up (ended by the first message: ``startup_phase``), during which no message
    yet is expected, on the wall clock (``wall`` [s], default ``now``)."""
    now = time.monotonic() if now is None else now
    wall = now if wall is None else wall
    age, rate = meter.age(now), meter.rate(now)
    level = grade(age, warn_s, error_s)
    msg = (f"no {what} received" if age is None else
           f"{what} {'stale: newest ' if level == ERROR else 'newest '}{age:.2f} s old, "
           f"{rate:.1f} Hz")
    out = level, msg, {"rate [Hz]": rate, "newest age [s]": age, "received": meter.count}
    if phase is not None:
        if age is not None and phase.active:
            phase.end(wall)
        return phase.apply(out, wall)
    return out


def startup_phase(what: str, deadline_s: float) -> Phase:
    """A phase begun now: ``"starting: waiting for the first <what>"`` with ``deadline_s``."""
    ph = Phase()
    ph.begin(f"starting: waiting for the first {what}", deadline_s)
    return ph
