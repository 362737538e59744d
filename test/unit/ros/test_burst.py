"""The motion node's capture of a press (``motion_node.Burst``), polled by the press loop
without blocking it: a whole burst at once, a short one asked for again after
``BURST_RETRY_S`` and kept when the deadline is near, no contact or no answer refused, the
request in flight forgotten on cancel."""

from __future__ import annotations

import pytest

pytest.importorskip("rclpy")
srv = pytest.importorskip("tactex.srv")

from rclpy.task import Future  # noqa: E402
from sensor_msgs.msg import Image  # noqa: E402

from tactex_ros.ros.nodes.motion_node import BURST_RETRY_S, Burst  # noqa: E402


class Client:
    """A Capture client whose answers the test gives."""

    def __init__(self, ready: bool = True) -> None:
        self.ready, self.sent, self.removed = ready, [], []

    def service_is_ready(self) -> bool:
        return self.ready

    def call_async(self, request) -> Future:
        fut = Future()
        self.sent.append((request, fut))
        return fut

    def remove_pending_request(self, fut: Future) -> None:
        self.removed.append(fut)


def _answer(frames: int, score: float = 5.0, success: bool = True) -> srv.Capture.Response:
    return srv.Capture.Response(success=success, reason="" if success else "camera stopped",
                                contact_score=score, image=Image(),
                                extra_images=[Image() for _ in range(frames - 1)])


def _burst(client: Client, now: float = 100.0) -> Burst:
    return Burst(client, window_s=0.5, frames=4, deadline_s=2.0, min_contact_score=1.0,
                 now=now)


def test_a_whole_burst_comes_back_at_once():
    c = Client()
    b = _burst(c)
    assert b.poll(100.0) is None and len(c.sent) == 1
    req, fut = c.sent[0]
    assert (req.window_s, req.frames) == (0.5, 4)
    assert b.poll(100.02) is None                  # not answered yet: the loop steps on
    fut.set_result(_answer(4))
    ok, reason, resp = b.poll(100.04)
    assert ok and reason == "" and len(resp.extra_images) == 3 and b.short == 0


def test_a_short_burst_is_asked_again_then_kept_near_the_deadline():
    c = Client()
    b = _burst(c)
    b.poll(100.0)
    c.sent[0][1].set_result(_answer(2))
    assert b.poll(100.1) is None                   # short: asked again after the retry
    assert b.poll(100.1 + BURST_RETRY_S / 2) is None and len(c.sent) == 1
    assert b.poll(100.1 + BURST_RETRY_S) is None and len(c.sent) == 2
    c.sent[1][1].set_result(_answer(4))
    ok, _, resp = b.poll(100.2)
    assert ok and len(resp.extra_images) == 3 and b.short == 0
    # a burst still short with less than two retries left before the deadline is kept
    c2 = Client()
    b2 = _burst(c2)
    b2.poll(100.0)
    c2.sent[0][1].set_result(_answer(3))
    ok, _, resp = b2.poll(102.0 - BURST_RETRY_S)
    assert ok and b2.short == 3 and len(c2.sent) == 1


@pytest.mark.parametrize("answer, reason", [
    (_answer(4, score=0.5), "no contact in the captured frames: score 0.50 < min_contact_score "
                            "1.0"),
    (_answer(4, success=False), "camera stopped")])
def test_no_contact_or_a_failed_capture_is_refused(answer, reason):
    c = Client()
    b = _burst(c)
    b.poll(100.0)
    c.sent[0][1].set_result(answer)
    assert b.poll(100.1) == (False, reason, None)


def test_no_service_or_no_answer_by_the_deadline_fails_and_forgets_the_request():
    c = Client(ready=False)
    b = _burst(c)
    assert b.poll(101.9) is None and not c.sent     # waits for the service up to the deadline
    assert b.poll(102.01) == (False, "capture service not available", None)
    c = Client()
    b = _burst(c)
    b.poll(100.0)
    assert b.poll(102.0) is None
    ok, reason, _ = b.poll(102.01)
    assert not ok and "capture_deadline_s (2.0 s)" in reason
    assert c.removed == [c.sent[0][1]]
    c = Client()
    b = _burst(c)
    b.poll(100.0)
    b.cancel()                                       # the press ended the capture
    assert c.removed == [c.sent[0][1]] and b.fut is None
