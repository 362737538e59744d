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
