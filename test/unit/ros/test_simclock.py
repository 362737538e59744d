"""ros/simclock.py: the deadline clock of a node (simulated or monotonic), its stall check and
the real-time factor."""

from __future__ import annotations

import time

import pytest

from tactex_ros.ros.simclock import NodeClock, RealTimeFactor, SimClockStalled


class _Now:
    def __init__(self, ns: int) -> None:
        self.nanoseconds = ns


class _FakeNode:
    """A node stand-in: ``use_sim_time`` and a ROS clock the test sets [s]."""

    def __init__(self, sim: bool) -> None:
        self.sim, self.t = sim, 0.0

    def get_parameter(self, name: str):
        assert name == "use_sim_time"
        return type("P", (), {"value": self.sim})()

    def get_clock(self):
        return type("C", (), {"now": lambda _s: _Now(int(self.t * 1e9))})()


def test_wall_time_is_monotonic() -> None:
    c = NodeClock(_FakeNode(False))
    assert not c.sim and abs(c.now() - time.monotonic()) < 0.1 and c.behind_s() == 0.0


def test_sim_time_is_the_node_clock_and_a_standing_clock_raises() -> None:
    node = _FakeNode(True)
    c = NodeClock(node, stall_s=0.2)
    node.t = 100.5
    assert c.now() == pytest.approx(100.5)
    time.sleep(0.3)
    with pytest.raises(SimClockStalled, match="stood still"):
        c.now()
    assert c.behind_s() > 0.2
    node.t = 100.6                     # the clock moves again: no stall
    assert c.now() == pytest.approx(100.6) and c.behind_s() < 0.1


def test_no_clock_at_all_is_named() -> None:
    c = NodeClock(_FakeNode(True), stall_s=0.1)
    c.now()
    time.sleep(0.2)
    with pytest.raises(SimClockStalled, match="no /clock"):
        c.now()
    assert c.read() == 0.0             # read never raises


def test_real_time_factor() -> None:
    r = RealTimeFactor(window_s=2.0)
    assert r.factor() is None
    r.tick(0.0, 0.0)                   # no clock yet: left out
    for i in range(11):                # 0.25 simulated s per wall s
        r.tick(1000.0 + 0.025 * i, 10.0 + 0.1 * i)
    assert r.factor(11.0) == pytest.approx(0.25)
    assert r.factor(13.0) == pytest.approx(0.25 / 3.0)   # a stopped source falls towards 0
