"""The operator's hold on the running trial of a session, without ROS (``OperatorControl``).

Five actions: ``pause`` (no new press starts until ``resume``; the press under way ends),
``resume``, ``abort`` (the session ends after the press under way; the trial stays resumable,
every press made is on disk), ``skip`` (the trial ends now and is recorded as skipped) and
``redo`` (the trial starts again; its earlier presses stay in the record as superseded). Each
accepted request is recorded (``record(event)``) with who asked: ``by`` (``key``: the
terminal, ``service``: a ROS service call) and ``caller`` where known. The explorer asks
``gate()`` before every press: it waits while paused and raises ``OperatorStop`` for an
abort, a skip or a redo.
"""

from __future__ import annotations

import threading
import time
from typing import Any
from collections.abc import Callable

from ..core.errors import TrialError

#: the operator's actions, in the order the terminal and the layout show them
ACTIONS = ("pause", "resume", "abort", "skip", "redo")
#: the terminal's key (a line with this letter, then Enter) for each action
KEYS = {"p": "pause", "r": "resume", "a": "abort", "s": "skip", "d": "redo"}


class OperatorStop(TrialError):
    """The operator ended the current trial: ``action`` is 'abort', 'skip' or 'redo'."""

    def __init__(self, action: str, by: str, caller: str) -> None:
        super().__init__(f"trial stopped by the operator: {action} (by {by}"
                         + (f", {caller}" if caller else "") + ")")
        self.action, self.by, self.caller = action, by, caller


class OperatorControl:
    """Pause/resume/abort/skip/redo requests for the trial ``trial`` names (None: no trial
    runs, every request is refused). ``record(event)``: where an accepted request goes (the
    session's and the trial's events)."""

    def __init__(self, record: Callable[[dict[str, Any]], None]) -> None:
        self._record = record
        self._lock = threading.Lock()
        self._resumed = threading.Event()
        self._resumed.set()
        self.trial: str | None = None
        self.pending: OperatorStop | None = None
        self.paused_s = 0.0              # [s] time the current trial spent paused
        self._paused_at: float | None = None

    @property
    def paused(self) -> bool:
        return not self._resumed.is_set()

    def start(self, trial_id: str) -> None:
        """``trial_id`` runs from now on: nothing paused or pending."""
        with self._lock:
            self.trial, self.pending, self.paused_s, self._paused_at = trial_id, None, 0.0, None
            self._resumed.set()

    def end(self) -> None:
        """No trial runs (between trials): requests are refused."""
        with self._lock:
            self.trial, self.pending, self._paused_at = None, None, None
            self._resumed.set()

    def request(self, action: str, by: str, caller: str = "") -> tuple[bool, str]:
        """The operator asks for ``action`` (``ACTIONS``): (accepted, message). Refused (not
        recorded) when no trial runs, an action ending the trial is already pending, or a
        pause / resume would change nothing. ValueError for an unknown action."""
        if action not in ACTIONS:
            raise ValueError(f"operator action {action!r}: use one of {', '.join(ACTIONS)}")
        with self._lock:
            t = self.trial
            if t is None:
                return False, f"{action}: no trial is running now"
            if self.pending is not None:
                return False, f"{action}: trial {t} already ends ({self.pending.action})"
            if action == "pause" and self.paused:
                return False, f"pause: trial {t} is paused already"
            if action == "resume" and not self.paused:
                return False, f"resume: trial {t} is not paused"
            now = time.monotonic()
            event = {"event": "operator", "action": action, "trial": t, "by": by,
                     "caller": caller or None, "time": time.time()}
            self._record(event)               # recorded before it takes effect
            if action == "pause":
                self._paused_at = now
                self._resumed.clear()
            else:
                if self._paused_at is not None:
                    self.paused_s += now - self._paused_at
                    self._paused_at = None
                if action != "resume":
                    self.pending = OperatorStop(action, by, caller)
                self._resumed.set()        # an abort / skip / redo of a paused trial
        return True, f"trial {t}: {action}" + {
            "pause": " (the press under way ends; no new press until resume)",
            "resume": "", "abort": " (after the press under way; the trial stays resumable)",
            "skip": " (recorded as skipped)",
            "redo": " (starts again; its presses so far stay as superseded)"}[action]

    def gate(self, timeout_s: float, stopping: Callable[[], bool]) -> None:
        """Before a press: wait while paused (up to ``timeout_s`` [s]; TrialError past it or
        when ``stopping()``), then raise the pending ``OperatorStop``, if any."""
        deadline = time.monotonic() + timeout_s
        while not self._resumed.wait(timeout=0.1):
            if stopping():
                raise TrialError("the explorer is stopping")
            if time.monotonic() > deadline:
                raise TrialError(f"trial {self.trial} stayed paused by the operator longer "
                                 f"than pause_timeout_s ({timeout_s:g} s)")
        stop = self.pending
        if stop is not None:
            raise stop
