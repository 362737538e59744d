"""GoalRequest (ros/goal.py) against a scripted action server on a fake clock: lost goal
responses and lost goal requests cost no touch and never make a second one."""

from __future__ import annotations

from types import SimpleNamespace

import pytest

pytest.importorskip("rclpy")

from action_msgs.msg import GoalStatus  # noqa: E402
from rclpy.action.client import ClientGoalHandle  # noqa: E402

from tactex_ros.ros.goal import GoalRequest  # noqa: E402


class Fut:
    def __init__(self) -> None:
        self._done, self._value = False, None

    def done(self) -> bool:
        return self._done

    def result(self):
        return self._value

    def set(self, value) -> None:
        self._done, self._value = True, value


class Server:
    """One goal at a time, like the motion node; ``duration`` [s] per goal; the goal requests
    numbered in ``lose_request`` never arrive, the responses in ``lose_response`` never come
    back; goals for ``bad`` are rejected."""

    def __init__(self, duration: float, lose_request=(), lose_response=(), bad="",
                 late_response=None) -> None:
        self.now, self.duration, self.bad = 0.0, duration, bad
        self.lose_request, self.lose_response = set(lose_request), set(lose_response)
        self.late_response = dict(late_response or {})   # request number -> delay [s]
        self.late: list[tuple[float, Fut, object]] = []  # (due, future, response)
        self.n_requests = 0
        self.goals: dict[bytes, dict] = {}     # goal id -> start, end, status
        self.waiting: list[tuple[bytes, Fut]] = []

    def running(self) -> bool:
        return any(g["status"] == GoalStatus.STATUS_EXECUTING for g in self.goals.values())

    def tick(self, dt: float) -> None:
        self.now += dt
        for due, f, value in list(self.late):
            if self.now >= due:
                f.set(value)
                self.late.remove((due, f, value))
        for g in self.goals.values():
            if g["status"] == GoalStatus.STATUS_EXECUTING and self.now >= g["end"]:
                g["status"] = GoalStatus.STATUS_SUCCEEDED
        for gid, f in list(self.waiting):
            if self.goals[gid]["status"] != GoalStatus.STATUS_EXECUTING:
                f.set(SimpleNamespace(status=self.goals[gid]["status"], result=gid))
                self.waiting.remove((gid, f))


class Client:
    """The parts of rclpy's ActionClient that GoalRequest and ClientGoalHandle use."""

    def __init__(self, server: Server) -> None:
        self.s = server

    def send_goal_async(self, goal, feedback_callback=None, goal_uuid=None):
        s, i, f = self.s, self.s.n_requests, Fut()
        s.n_requests += 1
        if i in s.lose_request:
            return f
        gid = bytes(goal_uuid.uuid)
        ok = goal != s.bad and not s.running()
        if ok:
            s.goals[gid] = {"status": GoalStatus.STATUS_EXECUTING, "end": s.now + s.duration}
        response = ClientGoalHandle(self, goal_uuid, SimpleNamespace(accepted=ok))
        if i in s.late_response:
            s.late.append((s.now + s.late_response[i], f, response))
        elif i not in s.lose_response:
            f.set(response)
        return f

    def _get_result_async(self, handle):
        gid, f = bytes(handle.goal_id.uuid), Fut()
        if gid not in self.s.goals:
            f.set(SimpleNamespace(status=GoalStatus.STATUS_UNKNOWN, result=None))
        else:
            self.s.waiting.append((gid, f))
            self.s.tick(0.0)
        return f

    def _cancel_goal_async(self, handle):
        g = self.s.goals.get(bytes(handle.goal_id.uuid))
        if g is not None and g["status"] == GoalStatus.STATUS_EXECUTING:
            g["status"] = GoalStatus.STATUS_CANCELED
        self.s.tick(0.0)
        return Fut()


def run(server: Server, goal: str = "c1", answer_s: float = 2.0, limit: float = 60.0,
        renew_s: float = 0.0, dt: float = 0.1):
    req = GoalRequest(Client(server), goal, answer_s=answer_s, clock=lambda: server.now,
                      renew_s=renew_s)
    while not req.finished() and server.now < limit:
        server.tick(dt)
    return req


def ids(server: Server, status: int) -> list[bytes]:
    return [k for k, g in server.goals.items() if g["status"] == status]


def test_answered_goal_is_followed() -> None:
    s = Server(duration=5.0)
    req = run(s)
    assert req.answered() and req.resent == 0 and not req.switched
    assert req.result.status == GoalStatus.STATUS_SUCCEEDED
    assert req.result.result == bytes(req.sent[0].gid.uuid)


def test_lost_response_goal_running_is_followed_by_its_id() -> None:
    s = Server(duration=8.0, lose_response={0})
    req = run(s)
    assert req.resent == 1                       # re-sent after answer_s, refused (busy)
    assert req.result.status == GoalStatus.STATUS_SUCCEEDED
    assert req.result.result == bytes(req.sent[0].gid.uuid)    # the first goal's result
    assert len(s.goals) == 1                     # one touch made
    assert s.now == pytest.approx(8.0, abs=0.15)  # no time lost waiting


def test_lost_request_resent_goal_runs() -> None:
    s = Server(duration=4.0, lose_request={0})
    req = run(s)
    assert req.resent == 1 and not req.switched
    assert req.result.status == GoalStatus.STATUS_SUCCEEDED
    assert req.result.result == bytes(req.sent[1].gid.uuid)
    assert len(s.goals) == 1


def test_lost_response_goal_already_ended_is_used_and_resend_canceled() -> None:
    s = Server(duration=1.0, lose_response={0})     # ends before answer_s
    req = run(s)
    assert req.switched
    assert req.result.status == GoalStatus.STATUS_SUCCEEDED
    assert req.result.result == bytes(req.sent[0].gid.uuid)
    assert ids(s, GoalStatus.STATUS_CANCELED) == [bytes(req.sent[1].gid.uuid)]


def test_rejected_goal_is_refused() -> None:
    s = Server(duration=1.0, bad="nope")
    req = run(s, goal="nope")
    assert req.refused and req.answered() and req.result is None and req.resent == 0


def test_lost_rejection_ends_unknown() -> None:
    s = Server(duration=1.0, bad="nope", lose_response={0})
    req = run(s, goal="nope")
    assert req.finished() and not req.refused
    assert req.result.status == GoalStatus.STATUS_UNKNOWN   # the server never took it
    assert s.goals == {}


def test_late_rejection_is_a_refusal_not_a_lost_goal() -> None:
    # a loaded machine: the rejection of the first goal arrives after the re-send was refused
    # and after the probe said STATUS_UNKNOWN: still a refusal (CI at load 26)
    s = Server(duration=1.0, bad="nope", late_response={0: 3.0})
    req = run(s, goal="nope")
    assert req.refused and req.result is None and req.resent == 1
    assert s.now == pytest.approx(3.0, abs=0.15)


def test_late_acceptance_is_followed_to_its_result() -> None:
    # the server is busy with another goal, so the re-send is refused; the first goal's
    # acceptance then arrives late: its result is the one followed (one touch)
    s = Server(duration=6.0, late_response={0: 3.0})
    req = run(s)
    assert not req.refused and req.result.status == GoalStatus.STATUS_SUCCEEDED
    assert req.result.result == bytes(req.sent[0].gid.uuid) and len(s.goals) == 1


def test_silent_server_sends_at_most_max_sends() -> None:
    s = Server(duration=1.0, lose_request={0, 1, 2, 3, 4})
    req = run(s, limit=30.0)
    assert not req.answered() and len(req.sent) == 3 and s.n_requests == 3


def test_unanswered_request_is_asked_again_after_renew_s() -> None:
    # the server's readers match late: the three sends at 0, 2, 4 s are lost; 5 s after the
    # newest (t = 9 s) the goal is asked again as a new request, which runs 4 s: one touch
    s = Server(duration=4.0, lose_request={0, 1, 2})
    req = run(s, renew_s=5.0, dt=0.25)        # a binary fraction: exact times
    assert req.renewals == 1 and len(req.sent) == 4 and s.n_requests == 4
    assert [x.t for x in req.sent] == [0.0, 2.0, 4.0, 9.0]
    assert req.result.status == GoalStatus.STATUS_SUCCEEDED
    assert req.result.result == bytes(req.sent[3].gid.uuid) and len(s.goals) == 1
    assert s.now == 13.0


def test_silent_server_is_asked_again_every_renew_s() -> None:
    # sends at 0 2 4 | 9 11 13 | 18 20 22 | 27 29 s within 30 s (without renew_s: 0 2 4,
    # test_silent_server_sends_at_most_max_sends)
    s = Server(duration=1.0, lose_request=set(range(20)))
    req = run(s, renew_s=5.0, limit=30.0, dt=0.25)
    assert not req.answered() and req.renewals == 3 and s.n_requests == 11
    assert [x.t for x in req.sent] == [0, 2, 4, 9, 11, 13, 18, 20, 22, 27, 29]


def test_bad_arguments() -> None:
    with pytest.raises(ValueError, match="answer_s"):
        GoalRequest(Client(Server(1.0)), "c1", answer_s=0.0)
    with pytest.raises(ValueError, match="renew_s"):
        GoalRequest(Client(Server(1.0)), "c1", renew_s=-1.0)


def test_silence_does_not_count_time_the_caller_was_stopped():
    from tactex_ros.ros.goal import Silence
    now = [0.0]
    s = Silence(clock=lambda: now[0], stall_s=0.5)
    for _ in range(100):                   # awake, polling every 10 ms, nothing heard: 1 s
        now[0] += 0.01
        assert s.tick() == 0.0
    assert s.silent_s() == pytest.approx(1.0)
    now[0] += 20.0                         # SIGSTOP for 20 s, then SIGCONT
    assert s.tick() == pytest.approx(20.0)
    assert s.silent_s() == pytest.approx(1.0)       # the stall is not the server's silence
    s.heard()
    now[0] += 0.3
    s.tick()
    assert s.silent_s() == pytest.approx(0.3)
    for _ in range(1000):                  # a server silent for 10 s while the caller is awake
        now[0] += 0.01
        s.tick()
    assert s.silent_s() == pytest.approx(10.3)


def test_result_dropped_during_a_stall_is_asked_for_again() -> None:
    """The result request's answer is lost (the server forgot the stalled client): asking
    again gets the ended goal's stored result; the press is used, not made again."""
    s = Server(duration=3.0)
    req = GoalRequest(Client(s), "c1", answer_s=2.0, clock=lambda: s.now)
    while not req.answered():
        s.tick(0.1)
    s.waiting.clear()                      # the pending result request dropped
    for _ in range(100):
        s.tick(0.1)
    assert not req.finished()
    req.ask_again()
    s.tick(0.0)
    assert req.finished() and req.result.status == GoalStatus.STATUS_SUCCEEDED
    assert req.result.result == bytes(req.sent[0].gid.uuid) and len(s.goals) == 1


def test_press_made_while_the_caller_stalled_is_used_once() -> None:
    """The caller (the explorer) is stopped for 20 s right after sending a press goal; the
    motion node takes it, presses and ends meanwhile; the goal's answer is still queued when
    the caller wakes up. The goal is not sent again (no second press): its answer, then its
    result, are used, and the stall is counted as the caller's."""
    s = Server(duration=3.0)
    held: list = []
    client = Client(s)
    send = client.send_goal_async

    def queued(goal, feedback_callback=None, goal_uuid=None):    # answer delivered late
        f = send(goal, feedback_callback=feedback_callback, goal_uuid=goal_uuid)
        late = Fut()
        held.append((f, late))
        return late
    client.send_goal_async = queued
    req = GoalRequest(client, "c1", answer_s=2.0, clock=lambda: s.now)
    assert not req.answered()
    s.tick(20.0)                             # SIGSTOP 20 s: the press ran and ended
    assert not req.answered()                # woken: the executor has not delivered yet
    s.tick(0.05)
    for f, late in held:                     # the queued answers arrive
        late.set(f.result())
    while not req.finished() and s.now < 60:
        s.tick(0.1)
    assert s.n_requests == 1 and len(s.goals) == 1          # one goal sent, one press
    assert req.result.status == GoalStatus.STATUS_SUCCEEDED
    assert req.result.result == bytes(req.sent[0].gid.uuid)
    assert req.stalled_s == pytest.approx(20.0, abs=0.2)
