"""Real-process ROS 2 test helpers: an isolated DDS domain per test and a listener node."""

from __future__ import annotations

import itertools
import os
import threading

import pytest

rclpy = pytest.importorskip("rclpy")

_domains = itertools.count(100 + os.getpid() % 50 * 2)


class Listener:
    """A node in the test process with its own context, spun in a background thread."""

    def __init__(self, domain_id: int) -> None:
        from rclpy.executors import SingleThreadedExecutor
        self.domain_id = domain_id
        self.ctx = rclpy.Context()
        rclpy.init(context=self.ctx, domain_id=domain_id)
        self.node = rclpy.create_node("test_listener", context=self.ctx)
        self.ex = SingleThreadedExecutor(context=self.ctx)
        self.ex.add_node(self.node)
        self.thread = threading.Thread(target=self._spin, daemon=True)
        self.thread.start()

    def _spin(self) -> None:
        try:
            self.ex.spin()
        except Exception:  # noqa: BLE001 - context shut down at teardown
            pass

    def collect(self, msg_type, topic: str, qos=10) -> list:
        """Subscribe and return the list that receives every message."""
        got: list = []
        self.node.create_subscription(msg_type, topic, got.append, qos)
        return got

    def close(self) -> None:
        self.ex.shutdown(timeout_sec=1.0)
        self.node.destroy_node()
        rclpy.shutdown(context=self.ctx)


@pytest.fixture
def domain_id() -> int:
    return next(_domains)


@pytest.fixture
def listener(domain_id):
    lst = Listener(domain_id)
    yield lst
    lst.close()


def press_goal(listener: Listener, platform_id: str, timeout: float = 90.0,
               answer_s: float = 15.0):
    """Send a Press goal to ``/tactex/press`` and return its result (``None``: rejected).

    A goal request sent right after discovery can lose its response (the server may not have
    matched the client's response reader yet). An attempt unanswered within ``answer_s`` is
    re-sent; when the re-sent goal is rejected because the first one is running, the first
    one's result is requested by its goal id. Fails the test at ``timeout`` seconds.
    """
    import time
    import uuid

    from rclpy.action import ActionClient
    from rclpy.action.client import ClientGoalHandle
    from tactex.action import Press
    from unique_identifier_msgs.msg import UUID

    ac = ActionClient(listener.node, Press, "/tactex/press")
    if not ac.wait_for_server(timeout_sec=30.0):
        pytest.fail("no /tactex/press server within 30 s")
    end = time.monotonic() + timeout
    sent: list = []   # (goal id, future of its goal response)
    while True:
        gid = UUID(uuid=list(uuid.uuid4().bytes))
        sent.append((gid, ac.send_goal_async(Press.Goal(platform_id=platform_id),
                                             goal_uuid=gid)))
        until = min(end, time.monotonic() + answer_s)
        while not any(f.done() for _, f in sent) and time.monotonic() < until:
            time.sleep(0.02)
        answered = [f.result() for _, f in sent if f.done()]
        if answered:
            break
        if time.monotonic() >= end:
            pytest.fail(f"press goal for {platform_id} not answered within {timeout} s")
    handle = next((h for h in answered if h.accepted), None)
    if handle is None:
        lost = [gid for gid, f in sent if not f.done()]
        if not lost:
            return None
        # the re-sent goal was refused while the unanswered one runs: follow that one
        handle = ClientGoalHandle(ac, lost[0], Press.Impl.SendGoalService.Response(accepted=True))
    rfut = handle.get_result_async()
    while not rfut.done() and time.monotonic() < end:
        time.sleep(0.02)
    if not rfut.done():
        pytest.fail(f"press of {platform_id} did not finish within {timeout} s")
    return rfut.result().result


@pytest.fixture
def press(listener):
    """``press(platform_id, timeout=90.0)``: :func:`press_goal` through the test's listener."""
    return lambda platform_id, timeout=90.0: press_goal(listener, platform_id, timeout)
