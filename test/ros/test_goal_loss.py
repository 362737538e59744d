"""A lost Press goal response or request costs no touch (ros/goal.py against the real
motion node, mock arm and mock camera over DDS).

The loss is made on the client side: the goal request goes out and the motion node takes it,
but its response never reaches GoalRequest (as when Fast DDS drops a response sent before the
server matched the client's response reader); or the request is never sent."""

from __future__ import annotations

import time
from pathlib import Path

import pytest
from action_msgs.msg import GoalStatus
from rclpy.task import Future

from tactex_ros.ros.graph import describe
from tactex_ros.ros.goal import GoalRequest
from tactex_ros.ros.devrun.launcher import Graph
from tactex_ros.ros.nodes.motion_node import FEEDBACK_PERIOD_S

pytestmark = pytest.mark.ros


class LossyClient:
    """An ActionClient whose goal responses numbered in ``lose_response`` never come back
    and whose goal requests numbered in ``lose_request`` are never sent."""

    def __init__(self, client, lose_response=(), lose_request=()) -> None:
        self.client, self.n = client, 0
        self.lose_response, self.lose_request = set(lose_response), set(lose_request)

    def send_goal_async(self, goal, feedback_callback=None, goal_uuid=None):
        i, self.n = self.n, self.n + 1
        if i in self.lose_request:
            return Future()
        fut = self.client.send_goal_async(goal, feedback_callback=feedback_callback,
                                          goal_uuid=goal_uuid)
        return Future() if i in self.lose_response else fut

    def __getattr__(self, name):
        return getattr(self.client, name)


def _press(client, platform: str, timeout: float = 90.0):
    from tactex.action import Press
    fb: list = []
    req = GoalRequest(client, Press.Goal(platform_id=platform), answer_s=1.0,
                      feedback_callback=fb.append)
    end = time.monotonic() + timeout
    while not req.finished() and time.monotonic() < end:
        time.sleep(0.02)
    assert req.finished(), f"press of {platform} not finished within {timeout} s"
    return req, {bytes(m.goal_id.uuid) for m in fb}, [m.feedback for m in fb]


def test_lost_goal_response_and_request_cost_no_touch(tmp_path: Path, listener,
                                                     quick_scene: str) -> None:
    from rclpy.action import ActionClient
    from tactex.action import Press
    nodes = [n for n in describe(True, quick_scene)
             if n.name in ("mock_arm", "mock_image", "motion")]
    ac = ActionClient(listener.node, Press, "/tactex/press")
    with Graph(nodes, tmp_path / "logs", listener.domain_id):
        assert ac.wait_for_server(timeout_sec=30.0)
        # the motion node takes the goal, its response is lost: the re-sent goal is refused
        # (a press runs) and the first one is followed by its id to its result
        req, fb_ids, feedback = _press(LossyClient(ac, lose_response={0}), "c1")
        first = bytes(req.sent[0].gid.uuid)
        assert req.resent >= 1 and req.result.status == GoalStatus.STATUS_SUCCEEDED
        assert req.result.result.success, req.result.result.reason
        assert req.result.result.touch.image.width == 320
        assert bytes(req.handle.goal_id.uuid) == first
        assert fb_ids == {first}               # one press made, by the first goal
        # feedback: the phases in the press's order, at most one message per
        # FEEDBACK_PERIOD_S besides a phase change (the press's time is simulated, as the
        # feedback's pace). Not asked: every phase, the last one ("done" may come after the
        # result, on another topic) and the first (a starved listener's depth-10 history
        # drops the oldest)
        last = [f for f in feedback if f.attempt == req.result.result.attempts]
        phases = [f.phase for i, f in enumerate(last) if i == 0 or f.phase != last[i - 1].phase]
        order = ["approach", "tare", "descend", "settle", "capture", "retract", "done"]
        assert len(phases) >= 3 and phases == sorted(phases, key=order.index), phases
        press_s = req.result.result.touch.press_s
        assert len(last) <= press_s / FEEDBACK_PERIOD_S + len(phases) + 2, (len(last), press_s)
        # the goal request is lost: the re-sent goal is taken and makes the only press
        req, fb_ids, _ = _press(LossyClient(ac, lose_request={0}), "c2")
        assert req.resent == 1 and req.result.status == GoalStatus.STATUS_SUCCEEDED
        assert req.result.result.success, req.result.result.reason
        assert fb_ids == {bytes(req.sent[1].gid.uuid)}


#: rclpy's ActionServer keeps a result this long by default on Kilted (Humble: 900 s)
KILTED_RESULT_TIMEOUT_S = 10.0


def test_a_result_fetched_after_kilteds_timeout_is_kept(tmp_path: Path, listener,
                                                       quick_scene: str) -> None:
    """The explorer may fetch a press's result late (it was stopped while the press ended:
    test_faults' stalled explorer). The motion node keeps it for ``result_timeout`` (900 s),
    not rclpy's Kilted default of 10 s, after which a result request is answered UNKNOWN."""
    from rclpy.action import ActionClient
    from tactex.action import Press
    nodes = [n for n in describe(True, quick_scene)
             if n.name in ("mock_arm", "mock_image", "motion")]
    ac = ActionClient(listener.node, Press, "/tactex/press")
    with Graph(nodes, tmp_path / "logs", listener.domain_id):
        assert ac.wait_for_server(timeout_sec=30.0)
        req = GoalRequest(ac, Press.Goal(platform_id="c1"), answer_s=2.0)
        end = time.monotonic() + 60.0
        while not req.answered() and time.monotonic() < end:
            time.sleep(0.02)
        assert req.handle is not None, "press goal not answered within 60 s"
        handle, end = req.handle, time.monotonic() + 90.0
        while handle.status != GoalStatus.STATUS_SUCCEEDED and time.monotonic() < end:
            time.sleep(0.05)        # the goal's status topic: the press ended, result unread
        assert handle.status == GoalStatus.STATUS_SUCCEEDED, handle.status
        ended = time.monotonic()
        time.sleep(KILTED_RESULT_TIMEOUT_S + 2.0)   # the duration under test, not a deadline
        fut = handle.get_result_async()
        end = time.monotonic() + 30.0
        while not fut.done() and time.monotonic() < end:
            time.sleep(0.02)
        assert fut.done(), "no answer to the late result request within 30 s"
        assert time.monotonic() - ended > KILTED_RESULT_TIMEOUT_S
        res = fut.result()
        assert res.status == GoalStatus.STATUS_SUCCEEDED, res.status
        assert res.result.success and res.result.touch.image.width == 320
