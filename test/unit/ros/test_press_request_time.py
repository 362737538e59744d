"""The explorer's press request time on a simulated clock that has not ticked yet (no
``/clock`` received: ROS time 0). The operator walk of issue 47 recorded ``requested: 0.0``
for the first press of a session started right after the nodes came up: the press time was
then unknown, and the terminal's trial time left out the first press and what followed it
until the second (14 s printed against 16 s recorded)."""

from __future__ import annotations

import functools
import threading
import time
from types import SimpleNamespace

import pytest

pytest.importorskip("rclpy")

from tactex_ros.ros.goal import Silence  # noqa: E402
from tactex_ros.ros.nodes.explorer_node import ExplorerNode  # noqa: E402


class _Sent(Exception):
    """Raised by the stand-in once the press goal would be sent: the request time is set."""


class _Clock:
    """ROS time of a simulated graph [s]: 0 until ``tick_after_s`` of wall time, then epoch."""

    def __init__(self, tick_after_s: float | None) -> None:
        self.t0, self.after = time.monotonic(), tick_after_s

    def __call__(self) -> float:
        if self.after is None or time.monotonic() - self.t0 < self.after:
            return 0.0
        return 1_796_313_580.0 + time.monotonic() - self.t0


def _explorer(clock: _Clock, press_timeout_s: float) -> SimpleNamespace:
    running = threading.Event()
    running.set()
    fake = SimpleNamespace(
        settings=SimpleNamespace(pause_timeout_s=5.0, press_timeout_s=press_timeout_s,
                                 press_silence_s=10.0, goal_answer_s=1.0),
        _running=running, _stopping=False, context=SimpleNamespace(ok=lambda: True),
        operator=None, ids=["reference", "c1"], _now=clock, press=None,
        _silence=Silence())
    fake._wait_running = functools.partial(ExplorerNode._wait_running, fake)
    fake._wait = functools.partial(ExplorerNode._wait, fake)
    fake._failed = ExplorerNode._failed

    def sent() -> None:
        raise _Sent
    fake._silence.reset = sent           # the next step after the request time is taken
    return fake


def test_the_request_waits_for_the_first_tick_of_the_simulated_clock() -> None:
    meta: dict = {}
    with pytest.raises(_Sent):
        ExplorerNode._press(_explorer(_Clock(0.3), press_timeout_s=5.0), 1, meta)
    assert meta["requested"] > 1.7e9            # the simulated epoch, never 0


def test_no_simulated_clock_by_the_press_deadline_fails_the_press() -> None:
    from tactex_ros.core.engine import TouchFailed
    meta: dict = {}
    t = time.monotonic()
    with pytest.raises(TouchFailed, match="clock"):
        ExplorerNode._press(_explorer(_Clock(None), press_timeout_s=0.5), 1, meta)
    assert 0.4 < time.monotonic() - t < 3.0 and meta["attempts"] == 0
    assert "requested" not in meta
