"""A study session's course, without ROS: the trials of a trial file in order (``SessionRun``).

Before each trial the operator is told what to place where (``Operator.tell``; written to
``session_events.jsonl``) and confirms (``Operator.wait``); a placement not confirmed in time
ends the session: recorded, resumable. Every trial gets a fresh engine with seed
``seed + position``, its own record ``<session_dir>/trial_<id>`` and its correctness from the
trial file's truth. A session folder that already holds the same session is continued:
finished trials are skipped, an interrupted trial resumes at the touch where it stopped
(its placement, confirmed before, is not asked again), pending ones run. The explorer node
(``ros/nodes/explorer_node.py``) runs each trial (``trial/run.py``); its operator is
``ros/nodes/operator.py`` (a service, a latched prompt topic, the mock camera's placement).
"""

from __future__ import annotations

import logging
import os
import time
from pathlib import Path
from typing import Any, Protocol
from collections.abc import Callable

from ..core.errors import TrialError
from . import session as sess
from .library import LibraryKeeper


class Operator(Protocol):
    """Who places the fabrics: told, then waited for."""

    def expect(self, trial_id: str) -> None:
        """A placement of ``trial_id`` is awaited from now on (a quick confirmation counts)."""

    def tell(self, text: str) -> None:
        """Say what to place where."""

    def wait(self) -> tuple[str, str] | None:
        """Wait for the confirmation: (how: 'enter', 'yes_flag', 'service', 'auto_confirm';
        by whom, '' when unknown), None when the deadline passed first. TrialError when the
        process stops meanwhile."""

    def place(self, trial: sess.SessionTrial) -> None:
        """Put the trial's fabrics in place where a machine can (simulation); else nothing."""


def trial_outcome(trial: sess.SessionTrial, result: dict) -> dict:
    """A session trial's result fields: its id, the true platforms, correctness."""
    return {"session_trial": trial.id, "truth_platforms": list(trial.truth),
            "correct": result.get("prediction") in trial.truth,
            "placement": dict(trial.placement), "seed": trial.seed}


def trial_done_text(event: dict) -> str:
    """The terminal's line of a ``trial_done`` session event: the answer, its touches and how
    the trial stopped; "not sure" (with the answer's belief) for a trial that ended below its
    stop confidence, never "correct"; else correct or wrong."""
    head = (f"trial {event.get('trial')}: {event.get('prediction')} after "
            f"{event.get('touches')} touches")
    if event.get("skipped"):
        return f"trial {event.get('trial')}: skipped after {event.get('touches')} touches"
    if event.get("not_sure"):
        b = event.get("confidence")
        return head + ", not sure" + (f" (belief {b:.2f})" if isinstance(b, float) else "")
    return (head + f" ({event.get('stop_reason')}); "
            + ("correct" if event.get("correct") else "wrong"))


def progress_text(summ: dict, asked: list[str] | None, current: str) -> str:
    """Where a session stands as the operator reads it: ``trial k of n in this run`` (``asked``:
    this run's trial ids, None: every trial) and the time left, from the MEASURED times of the
    trials done (their ``elapsed_s``, pauses left out) times the trials left, current one
    included; ``summ``: ``session.summary``."""
    rows = summ["trials"]
    mine = [r for r in rows if asked is None or r["id"] in asked]
    ids = [r["id"] for r in mine]
    k = ids.index(current) + 1 if current in ids else 0
    left = sum(1 for r in mine if not r["done"])
    times = [float(r["elapsed_s"]) for r in rows if r["done"]
             and isinstance(r.get("elapsed_s"), (int, float))]
    text = f"trial {current}: {k} of {len(mine)} in this run"
    if times:
        per = sum(times) / len(times)
        s = int(round(per * left))
        text += (f"; about {s // 60}:{s % 60:02d} left ({left} trial(s) at {per:.0f} s, "
                 f"the mean of {len(times)} done)")
    return text


class SessionRun:
    """The session ``session`` in folder ``session_dir`` (opened, or continued when it holds the
    same session; ``settings``: what ``session.json`` keeps). ``confirm_timeout_s``: for the
    message of a placement not confirmed in time. ``only``: the ids of the trials this run
    is asked for (``session.select_trials``; None: every trial), recorded in the start event;
    the others are left as they are, and the session's result waits for all of them."""

    def __init__(self, session: sess.Session, session_dir: str | Path,
                 settings: dict[str, Any], confirm_timeout_s: float,
                 log: Callable[[int, str], None] | None = None,
                 library: LibraryKeeper | None = None,
                 only: list[str] | None = None) -> None:
        self.session = session
        self.library = library
        self.dir = Path(session_dir).resolve()
        self.confirm_timeout_s = confirm_timeout_s
        self.only = only
        self.log = log or (lambda level, text: logging.getLogger("tactex.session").log(level,
                                                                                       text))
        self.resumed = sess.open_session(self.dir, session, settings)
        sess.add_event(self.dir, {"event": "resumed" if self.resumed else "started",
                                  "time": time.time(), "trials": len(session.trials),
                                  "trials_asked": only})

    def done(self) -> int:
        """How many of the session's trials are done."""
        return sum(sess.trial_state(self.dir, t) == "done" for t in self.session.trials)

    def confirmed(self, trial: sess.SessionTrial) -> bool:
        """True when the session's events hold the confirmed placement of ``trial`` (a
        resumed trial's fabrics are in place: not asked again)."""
        return any(e.get("event") == "confirmed" and e.get("trial") == trial.id
                   for e in sess.events(self.dir))

    def _prompt(self, operator: Operator, trial: sess.SessionTrial, k: int, n: int) -> bool:
        text = (f"session {self.session.name}, trial {trial.id} ({k}/{n}): place "
                + "; ".join(trial.instructions()) + " -- then confirm")
        operator.expect(trial.id)       # before the prompt goes out: a quick confirm is taken
        self.log(logging.INFO, text)
        sess.add_event(self.dir, {"event": "awaiting_confirmation", "trial": trial.id,
                                  "position": trial.position, "number": k, "of": n,
                                  "placement": trial.placement, "text": text,
                                  "time": time.time()})
        operator.tell(text)
        got = operator.wait()
        if got is None:
            return False
        by, caller = got
        sess.add_event(self.dir, {"event": "confirmed", "trial": trial.id, "by": by,
                                  "caller": caller or None, "time": time.time()})
        return True

    def run(self, operator: Operator,
            run_trial: Callable[[sess.SessionTrial, str | None], dict | None],
            stopping: Callable[[], bool]) -> int:
        """Every trial not yet done, in order; then the session's result and report.
        ``run_trial(trial, resume)``: the trial's result (None: the process is being stopped,
        the trial stays resumable); ``resume``: its record folder when it was started before.
        Returns the exit status: 0, or 1 when the session ended without its result or its
        report could not be written (the file named on the log)."""
        code = self._trials(operator, run_trial, stopping)
        if not stopping():
            try:
                from .report import write_session_report
                write_session_report(self.dir)
            except Exception as exc:  # noqa: BLE001 - the records are the ground truth
                self.log(logging.ERROR, f"session report {str(self.dir / 'report.html')!r} "
                                        f"not written: {exc}")
                return 1
        return code

    def _trials(self, operator: Operator,
                run_trial: Callable[[sess.SessionTrial, str | None], dict | None],
                stopping: Callable[[], bool]) -> int:
        """``run`` without the report: the trials, the result; the exit status."""
        d, trials = self.dir, self.session.trials
        try:
            for k, trial in enumerate(trials, 1):
                state = sess.trial_state(d, trial)
                if state == "done":
                    self._learn(trial)        # idempotent: a press is filed once
                    continue
                if self.only is not None and trial.id not in self.only:
                    continue
                if not (state == "started" and self.confirmed(trial)) and \
                        not self._prompt(operator, trial, k, len(trials)):
                    why = (f"placement of trial {trial.id} not confirmed within "
                           f"confirm_timeout_s ({self.confirm_timeout_s:g} s)")
                    self.log(logging.ERROR, f"session ended: {why}")
                    sess.add_event(d, {"event": "session_ended", "reason": why,
                                       "trial": trial.id, "time": time.time()})
                    return 1
                operator.place(trial)
                resume = str(d / trial.record_name) if state == "started" else None
                while True:
                    res = run_trial(trial, resume)
                    if res is None or res.get("operator") != "redo":
                        break
                    self.supersede(trial, res)     # the trial starts again, same placement
                    resume = None
                if res is None:          # the process is being stopped: the trial stays resumable
                    return 0
                if res.get("operator") == "abort":   # resumable: every press is on disk
                    why = f"trial {trial.id} aborted by the operator ({res.get('by')})"
                    self.log(logging.INFO, f"session ended: {why}")
                    sess.add_event(d, {"event": "session_ended", "reason": why,
                                       "trial": trial.id, "aborted": True,
                                       "by": res.get("by"), "caller": res.get("caller"),
                                       "time": time.time()})
                    return 0
                if "error" in res:
                    sess.add_event(d, {"event": "session_ended", "trial": trial.id,
                                       "reason": f"trial {trial.id} failed: {res['error']}",
                                       "time": time.time()})
                    return 0
                self._learn(trial)
                from .record import result_not_sure
                sess.add_event(d, {"event": "trial_done", "trial": trial.id,
                                   "skipped": bool(res.get("skipped")),
                                   "prediction": res.get("prediction"),
                                   "correct": res.get("correct"), "touches": res.get("touches"),
                                   "stop_reason": res.get("stop_reason"),
                                   "not_sure": result_not_sure(d / trial.record_name, res),
                                   "confidence": res.get("confidence"), "time": time.time()})
            self.current_library()            # the last trial's presses are filed first
            out = sess.summary(d)
            if out["done"] < out["total"]:     # a part (``only``): the rest is for a later run
                sess.add_event(d, {"event": "part_done", "trials_asked": self.only,
                                   "done": out["done"], "of": out["total"],
                                   "time": time.time()})
                self.log(logging.INFO, f"session {self.session.name}: trials "
                                       f"{', '.join(self.only or [])} done; {out['done']} of "
                                       f"{out['total']} trials done; folder {d}")
                return 0
            sess.finish_session(d, out)
            sess.add_event(d, {"event": "session_done", "accuracy": out["accuracy"],
                               "time": time.time()})
            self.log(logging.INFO, f"session {self.session.name}: {out['done']} trials, "
                                   f"accuracy {sess.accuracy_text(out)}; folder {d}")
            return 0
        except Exception as exc:  # the session must end in an explicit, recorded state
            if stopping():
                return 0
            self.log(logging.ERROR, f"session failed: {type(exc).__name__}: {exc}")
            try:
                sess.add_event(d, {"event": "session_ended",
                                   "reason": f"{type(exc).__name__}: {exc}", "time": time.time()})
            except TrialError as why:   # a full disk may refuse the event too
                self.log(logging.ERROR, f"session end not recorded: {why}")
            return 1

    def supersede(self, trial: sess.SessionTrial, why: dict) -> Path:
        """A redo: the trial's record folder becomes ``<record>.superseded.<k>`` (its presses
        kept, marked in its events and the session's); the trial then starts afresh."""
        from .record import append_event
        d = self.dir
        k = 1 + sum(1 for _ in d.glob(trial.record_name + ".superseded.*"))
        old = d / f"{trial.record_name}.superseded.{k}"
        event = {"event": "superseded", "trial": trial.id, "record": old.name,
                 "by": why.get("by"), "caller": why.get("caller"), "time": time.time()}
        append_event(d / trial.record_name, event)
        os.replace(d / trial.record_name, old)
        sess.add_event(d, event)
        self.log(logging.INFO, f"trial {trial.id}: redone; its presses so far kept in {old}")
        return old

    def _learn(self, trial: sess.SessionTrial) -> None:
        """A finished trial's presses join the fabric library (background; its placement is
        the trial file's)."""
        if self.library is not None:
            sid = sess.load_started(self.dir)["session_id"]
            self.library.learn(self.dir / trial.record_name, trial.placement,
                               f"{sid}/{trial.id}")

    def current_library(self):
        """The fabric library the next trial sees (None: off): after the update under way."""
        return None if self.library is None else self.library.current()

    def trial_started(self, trial: sess.SessionTrial, resumed: bool, after_touch: int) -> None:
        """Note in the session's events that ``trial`` began (``after_touch``: its record's
        touches so far)."""
        sess.add_event(self.dir, {"event": "trial_started", "trial": trial.id,
                                  "resumed": resumed, "after_touch": after_touch,
                                  "time": time.time()})

    def trial_inputs(self, trial: sess.SessionTrial, scene_file: str | Path) -> dict[str, Any]:
        """What a session trial's record keeps beside the settings: its placed scene text and
        the session's part of config.json."""
        return {"placed_scene": sess.placed_scene(scene_file, trial.placement),
                "extra": {"session": {"name": self.session.name, "trial": trial.id,
                                      "placement": trial.placement, "truth": trial.truth}}}
