"""One action goal followed to its result, robust to a lost goal response.

A goal request sent soon after discovery can be taken by the server while its *response* is
lost: Fast DDS drops a service response sent before the server has matched the client's
response reader (CI saw a Press goal unanswered for 90 s while the press ran). ``GoalRequest``
re-sends a goal that is unanswered after ``answer_s`` under a new goal id, and asks the server
(a result request, which it answers with ``STATUS_UNKNOWN`` for a goal id it never took) what
became of the unanswered ones:

- a re-sent goal is accepted: it is followed; if a probe shows that the unanswered goal had
  been taken after all and has ended, that goal's result is used and the re-sent one is
  canceled (a second touch is never made and then dropped);
- a re-sent goal is rejected (the motion node takes one press at a time) while an earlier one
  is unanswered: the earlier one is followed by its goal id (its result request is held by
  the server until it ends); a result with ``STATUS_UNKNOWN`` means the server never took it;
- every goal answered and rejected: refused;
- every goal unanswered (the server's readers not yet matched on a loaded machine): with
  ``renew_s``, once the ``max_sends`` sends are out and the newest has gone unanswered for
  ``renew_s`` seconds, the goal is asked again as a new request (``max_sends`` more sends,
  new goal ids); the earlier ones are still followed should their answer come late.

Used by the explorer for every press and by the ROS tests, so the logic lives in one place.
Non-blocking: the caller polls ``answered()`` / ``finished()`` from its own wait loop (with its
own deadline), while an executor spins the client's node in another thread.
"""

from __future__ import annotations

import time
import uuid
from dataclasses import dataclass, field
from types import SimpleNamespace
from typing import Any
from collections.abc import Callable

from action_msgs.msg import GoalStatus
from builtin_interfaces.msg import Time
from rclpy.action.client import ClientGoalHandle
from unique_identifier_msgs.msg import UUID


@dataclass
class _Sent:
    gid: UUID
    fut: Any                          # future of the goal response (a ClientGoalHandle)
    t: float                          # when it was sent [s, monotonic]
    probes: list = field(default_factory=list)   # futures of result requests by its id
    probe_t: float = 0.0              # when the last probe was sent [s, monotonic]
    canceled: bool = False


class GoalRequest:
    """Send ``goal`` on ``client`` (an ``rclpy.action.ActionClient``) and follow it.

    ``answer_s``: re-send a goal whose response has not come within this many seconds
    (at most ``max_sends`` goals per request). ``renew_s``: when all ``max_sends`` goals of a
    request went unanswered and the newest has waited this many seconds, ask again as a new
    request (``renewals`` counts them; 0: never, the caller's deadline ends the wait).
    ``feedback_callback`` receives feedback of every goal sent (only the one running sends
    any). After ``finished()``: ``result`` is the
    GetResult response (``status``, ``result``) of the goal that ran, or None when refused;
    ``status == GoalStatus.STATUS_UNKNOWN`` says the followed goal was never taken.
    """

    def __init__(self, client: Any, goal: Any, answer_s: float = 2.0,
                 feedback_callback: Callable[[Any], None] | None = None, max_sends: int = 3,
                 clock: Callable[[], float] = time.monotonic, renew_s: float = 0.0) -> None:
        if answer_s <= 0 or max_sends < 1 or renew_s < 0:
            raise ValueError(f"GoalRequest: answer_s ({answer_s}) must be > 0, max_sends "
                             f"({max_sends}) >= 1 and renew_s ({renew_s}) >= 0")
        self.client, self.goal, self.answer_s = client, goal, float(answer_s)
        self.renew_s = float(renew_s)
        self.renewals = 0        # times every send went unanswered and the goal was asked again
        self._request_start = 0  # index in ``sent`` of the current request's first send
        self.feedback_callback, self.max_sends, self.clock = feedback_callback, max_sends, clock
        self.sent: list[_Sent] = []
        self.handle: ClientGoalHandle | None = None   # the goal followed
        self._result_fut: Any = None
        self.refused = False
        self.switched = False    # a probe showed that an unanswered goal ran: its result used
        self.stalled_s = 0.0     # [s] time this process was not running while it followed
        self._last_poll = clock()
        # an unanswered goal followed by its id: a STATUS_UNKNOWN probe is not final while its
        # goal response may still come (a loaded machine answers late, after the re-send)
        self._unanswered: _Sent | None = None
        self._send()

    # ---------------------------------------------------------------- caller's view
    def answered(self) -> bool:
        """True once a goal is being followed, or every goal was refused (polls)."""
        self._poll()
        return self.handle is not None or self.refused

    def finished(self) -> bool:
        """True once the followed goal's result is in, or every goal was refused (polls)."""
        self._poll()
        return self.refused or (self._result_fut is not None and self._result_fut.done()
                                and self._unanswered is None)

    @property
    def result(self) -> Any:
        """The GetResult response of the followed goal (None before ``finished()`` or when
        refused)."""
        if self._result_fut is None or not self._result_fut.done():
            return None
        return self._result_fut.result()

    @property
    def resent(self) -> int:
        """How many times the goal was sent again."""
        return len(self.sent) - 1

    def ask_again(self) -> None:
        """Request the followed goal's result once more (e.g. after this process was stopped
        long enough for the server to forget it and drop the answer): the server answers a
        goal that has ended with its stored result. Nothing when no goal is followed or the
        result is in."""
        if self.handle is None or (self._result_fut is not None and self._result_fut.done()):
            return
        self._result_fut = self.handle.get_result_async()

    def cancel(self) -> None:
        """Ask the server to cancel the followed goal and every unanswered one."""
        if self.handle is not None:
            self.handle.cancel_goal_async()
        for s in self.sent:
            if not s.fut.done() and (self.handle is None or
                                     bytes(s.gid.uuid) != bytes(self.handle.goal_id.uuid)):
                self._handle_of(s).cancel_goal_async()

    # ---------------------------------------------------------------- internals
    def _send(self) -> None:
        gid = UUID(uuid=list(uuid.uuid4().bytes))
        fut = self.client.send_goal_async(self.goal, feedback_callback=self.feedback_callback,
                                          goal_uuid=gid)
        self.sent.append(_Sent(gid, fut, self.clock()))

    def _handle_of(self, s: _Sent) -> ClientGoalHandle:
        """A handle for a goal whose response never came (taken as accepted)."""
        return ClientGoalHandle(self.client, s.gid,
                                SimpleNamespace(accepted=True, stamp=Time()))

    def _probe(self, s: _Sent) -> Any:
        """Ask the server for the result of ``s`` by its id (held until the goal ends;
        STATUS_UNKNOWN at once for an id it never took)."""
        p = self._handle_of(s).get_result_async()
        s.probes.append(p)
        s.probe_t = self.clock()
        return p

    def _follow(self, handle: ClientGoalHandle, result_fut: Any) -> None:
        self.handle, self._result_fut = handle, result_fut

    def _is(self, s: _Sent) -> bool:
        return self.handle is not None and bytes(s.gid.uuid) == bytes(self.handle.goal_id.uuid)

    STALL_S = 0.5     # [s] a gap between polls longer than this: the caller was not running

    def _poll(self) -> None:
        now = self.clock()
        gap, self._last_poll = now - self._last_poll, now
        if gap > self.STALL_S:
            # this process was stopped (SIGSTOP, a starved machine): answers that came
            # meanwhile are still queued for the executor, so the wait for an answer starts
            # again now instead of counting the stall as the server's silence (a goal re-sent
            # here would press a second time after a press made during the stall)
            self.stalled_s += gap
            for s in self.sent:
                s.t += gap
                s.probe_t += gap
        if self.refused:
            return
        self._settle_unanswered()
        if self.refused:
            return
        # an unanswered goal that ran after all (a probe came back with its status): its
        # result counts, unless the followed goal has already ended with a real result; a
        # re-sent goal followed meanwhile is canceled (it would press a second time)
        if not self._followed_ran():
            for s in self.sent:
                p = next((p for p in s.probes if p.done() and p.result() is not None and
                          p.result().status != GoalStatus.STATUS_UNKNOWN), None)
                if p is None or self._is(s):
                    continue
                self._follow(self._handle_of(s), p)
                self.switched = True
                break
        if self.switched:
            self._cancel_others()
        if self.handle is not None:
            return
        answered = [s for s in self.sent if s.fut.done()]
        accepted = next((s for s in answered if s.fut.result() is not None and
                         s.fut.result().accepted), None)
        if accepted is not None:
            h = accepted.fut.result()
            self._follow(h, h.get_result_async())
            return
        lost = [s for s in self.sent if not s.fut.done()]
        if answered and not lost:
            self.refused = True
            return
        if answered:
            # a re-sent goal was refused while an earlier one is unanswered: the server is busy
            # with that one (or never took it): follow the oldest by its goal id, asked after
            # the refusal (a probe sent earlier may have overtaken the goal request)
            first = lost[0]
            self._follow(self._handle_of(first), self._probe(first))
            self._unanswered = first
            return
        newest = self.sent[-1]
        waited = self.clock() - newest.t
        if len(self.sent) - self._request_start < self.max_sends:
            if waited < self.answer_s:
                return
        elif not self.renew_s or waited < self.renew_s:
            return
        else:
            # every send of this request unanswered for renew_s: ask again as a new request
            self.renewals += 1
            self._request_start = len(self.sent)
        self._probe(newest)      # in case it was taken and has ended already
        self._send()

    def _settle_unanswered(self) -> None:
        """An unanswered goal followed by its id whose probe came back: a real status is its
        result; STATUS_UNKNOWN is final only once its own response says so (rejected: every
        goal refused; accepted: followed by its handle) or, with the response still missing,
        after ``max_sends`` probes ``answer_s`` apart (the request was lost)."""
        s = self._unanswered
        if s is None or self._result_fut is None or not self._result_fut.done():
            return
        r = self._result_fut.result()
        if r is not None and r.status != GoalStatus.STATUS_UNKNOWN:
            self._unanswered = None
            return
        if s.fut.done():
            self._unanswered = None
            h = s.fut.result()
            if h is not None and h.accepted:
                self._follow(h, h.get_result_async())
            elif all(x.fut.done() and (x.fut.result() is None or not x.fut.result().accepted)
                     for x in self.sent):
                self.refused, self.handle, self._result_fut = True, None, None
            return
        if len(s.probes) >= self.max_sends:
            self._unanswered = None                   # never answered: never taken
        elif self.clock() - s.probe_t >= self.answer_s:
            self._result_fut = self._probe(s)

    def _cancel_others(self) -> None:
        """Cancel every other goal the server took or may have taken (once each): a re-sent
        goal must not press again once the first one's result is in."""
        for s in self.sent:
            if self._is(s) or s.canceled:
                continue
            if s.fut.done():
                h = s.fut.result()
                if h is None or not h.accepted:
                    continue
            else:
                h = self._handle_of(s)
            h.cancel_goal_async()
            s.canceled = True

    def _followed_ran(self) -> bool:
        """The followed goal has ended with a real status (it was taken and ran)."""
        r = self.result
        return r is not None and r.status != GoalStatus.STATUS_UNKNOWN


class Silence:
    """How long a server has been silent, counting only time the caller could hear it.

    ``heard()`` (any message: goal response, feedback, result) restarts the count. The caller
    ``tick()``s from its wait loop every few milliseconds; a gap between ticks longer than
    ``stall_s`` means this process was not running (SIGSTOP, a starved machine): messages that
    arrived meanwhile are still queued unread, so the gap is not counted as the server's
    silence (and ``tick`` returns it, for the caller to move its own deadlines). A stalled
    caller therefore never blames a healthy server; a server that really stops talking is
    still found out within the silence limit of time the caller was awake.
    """

    def __init__(self, clock: Callable[[], float] = time.monotonic,
                 stall_s: float = 0.5) -> None:
        self.clock, self.stall_s = clock, float(stall_s)
        self.reset()

    def reset(self) -> None:
        """Start counting now (a new goal was sent)."""
        self.last_heard = self.last_awake = self.clock()

    def heard(self) -> None:
        """A message from the server arrived."""
        self.last_heard = self.clock()

    def tick(self) -> float:
        """The caller is awake; returns the stall [s] since the last tick (0.0 if none)."""
        now = self.clock()
        gap = now - self.last_awake
        self.last_awake = now
        if gap > self.stall_s:
            self.last_heard += gap
            return gap
        return 0.0

    def silent_s(self) -> float:
        """Seconds of silence the caller was awake for."""
        return self.clock() - self.last_heard
