"""The explorer's study session (``session_file``): the trials of a trial file, in order.

Before each trial the operator is told what to place where (logged, published latched on
``prompt_topic`` as ``std_msgs/String``, written to ``session_events.jsonl``) and confirms with
the explorer's ``~/confirm`` service (``std_srvs/srv/Trigger``: recorded as by ``service``) or
``~/confirm_by`` (``tactex/srv/Confirm``: how and by whom, e.g. ``enter`` or ``yes_flag`` from
``tactex graph run``); ``auto_confirm`` confirms at once (scripted sessions). The confirmation
is recorded with its source and caller and published on ``prompt_topic``, so every place that
shows the prompt shows who confirmed it. A placement not confirmed within ``confirm_timeout_s`` ends the
session: recorded, resumable. In simulation the mock camera's ``placement`` parameter is set
through its SetParameters service (``placement_service``) so it shows the trial's fabrics.
Every trial gets a fresh engine (belief and learner reset; the learner's modules stay
imported) with seed ``seed + position``, its own record ``<session_dir>/trial_<id>``, its
report, and its correctness from the trial file's truth. A session folder that already holds
the same session is continued: finished trials are skipped, an interrupted trial resumes at
the touch where it stopped (``resume``), pending ones run.

``SessionMode`` is a mixin of ``ExplorerNode`` (``explorer_node.py`` imports this module, never
the reverse): its methods use the node's settings, scene ids, record and trial worker.
"""

from __future__ import annotations

import time
from pathlib import Path
from typing import Any

from ...core.errors import TrialError
from ...trial import session as sess


def trial_outcome(trial: sess.SessionTrial, result: dict) -> dict:
    """A session trial's result fields: its id, the true platforms, correctness."""
    return {"session_trial": trial.id, "truth_platforms": list(trial.truth),
            "correct": result.get("prediction") in trial.truth,
            "placement": dict(trial.placement), "seed": trial.seed}



class SessionMode:
    """The explorer's session methods (mixed into ``ExplorerNode``)."""

    def configure_session(self) -> None:
        """Check the trial file against the scene (row named on error), open the session folder,
        make the confirm service, the prompt publisher and the placement client."""
        import threading

        from rcl_interfaces.srv import SetParameters
        from std_msgs.msg import String
        from std_srvs.srv import Trigger

        from .. import adapter
        s = self.settings
        self.session = sess.load_session(s.session_file, self.ids, seed=s.seed)
        d = Path(s.session_dir or Path(s.record_dir) /
                 f"{self.session.name}_{time.strftime('%Y%m%d_%H%M%S')}").resolve()
        self.session_dir = d
        resumed = sess.open_session(d, self.session, {
            "seed": s.seed, "config": s.config, "strategy": s.trial.strategy,
            "scene_file": str(Path(s.scene_file).resolve())})
        sess.add_event(d, {"event": "resumed" if resumed else "started", "time": time.time(),
                           "trials": len(self.session.trials)})
        self._confirmed = threading.Event()
        self._awaiting: str | None = None
        from tactex.srv import Confirm
        self._confirmed_by: tuple[str, str] = ("", "")
        self.confirm_srv = self.create_service(Trigger, "~/confirm",
                                               lambda req, res: self._on_confirm(res))
        self.confirm_by_srv = self.create_service(
            Confirm, "~/confirm_by",
            lambda req, res: self._on_confirm(res, req.by or "service", req.caller))
        self.prompt_pub = self.create_publisher(String, s.prompt_topic, adapter.latched_qos())
        self.placement_client = (self.create_client(SetParameters, s.placement_service)
                                 if s.placement_service else None)
        self.get_logger().info(f"session {self.session.name}: {len(self.session.trials)} trials, "
                               f"folder {d}{' (resumed)' if resumed else ''}")


    def _on_confirm(self, res: Any, by: str = "service", caller: str = "") -> Any:
        """``~/confirm`` / ``~/confirm_by``: the operator has placed the fabrics of the trial
        being prompted; ``by`` / ``caller``: how and by whom (recorded)."""
        if self._awaiting is None or self._confirmed.is_set():
            res.success, res.message = False, "nothing to confirm: no placement is awaited now"
            return res
        res.success, res.message = True, f"trial {self._awaiting}: placement confirmed"
        self._confirmed_by = (by, caller)
        self._confirmed.set()
        return res


    def _prompt(self, trial: sess.SessionTrial, k: int, n: int) -> bool:
        """Tell the operator what to place where and wait for the confirmation; False when
        ``confirm_timeout_s`` passed first. TrialError when the node stops meanwhile."""
        from std_msgs.msg import String
        s = self.settings
        text = (f"session {self.session.name}, trial {trial.id} ({k}/{n}): place "
                + "; ".join(trial.instructions()) + " -- then confirm")
        self._confirmed.clear()
        self._awaiting = trial.id          # before the prompt goes out: a quick confirm is taken
        self.get_logger().info(text)
        sess.add_event(self.session_dir, {"event": "awaiting_confirmation", "trial": trial.id,
                                          "position": trial.position, "number": k, "of": n,
                                          "placement": trial.placement, "text": text,
                                          "time": time.time()})
        self.prompt_pub.publish(String(data=text))
        self._confirmed_by = ("", "")
        if s.auto_confirm:
            self._confirmed_by = ("auto_confirm", "the explorer's auto_confirm parameter")
            self._confirmed.set()
        deadline = time.monotonic() + s.confirm_timeout_s
        try:
            while not self._confirmed.wait(timeout=0.1):
                if self._stopping or not self.context.ok():
                    raise TrialError("the explorer is stopping")
                if time.monotonic() > deadline:
                    return False
        finally:
            self._awaiting = None
        by, caller = self._confirmed_by
        sess.add_event(self.session_dir, {"event": "confirmed", "trial": trial.id,
                                          "by": by, "caller": caller or None,
                                          "time": time.time()})
        said = f"trial {trial.id}: placement confirmed by {by}" + \
            (f" ({caller})" if caller else "")
        self.get_logger().info(said)
        self.prompt_pub.publish(String(data=said))
        return True


    def _place(self, trial: sess.SessionTrial) -> None:
        """Simulation: set the mock camera's ``placement`` (SetParameters), within
        ``server_timeout_s``; TrialError with the camera's reason when it refuses."""
        from rcl_interfaces.msg import Parameter, ParameterType, ParameterValue
        from rcl_interfaces.srv import SetParameters
        client, s = self.placement_client, self.settings
        if client is None:
            return
        if not client.wait_for_service(timeout_sec=s.server_timeout_s):
            raise TrialError(f"placement service {s.placement_service!r} not available within "
                              f"server_timeout_s ({s.server_timeout_s} s)")
        value = ParameterValue(type=ParameterType.PARAMETER_STRING,
                               string_value=sess.placement_text(trial.placement))
        fut = client.call_async(SetParameters.Request(
            parameters=[Parameter(name="placement", value=value)]))
        deadline = time.monotonic() + s.server_timeout_s
        while not fut.done():
            if time.monotonic() > deadline:
                raise TrialError(f"placement service {s.placement_service!r}: no answer within "
                                  f"server_timeout_s ({s.server_timeout_s} s)")
            if self._stopping:
                raise TrialError("the explorer is stopping")
            time.sleep(0.01)
        r = fut.result().results[0]
        if not r.successful:
            raise TrialError(f"the mock camera refused the placement of trial {trial.id}: "
                              f"{r.reason}")


    def run_session(self) -> None:
        """The session's worker thread: every trial not yet done, in order; then the session's
        result and report. Ends the node's work (``exit_when_done``) in every case."""
        d, trials = self.session_dir, self.session.trials
        try:
            for k, trial in enumerate(trials, 1):
                state = sess.trial_state(d, trial)
                if state == "done":
                    continue
                if not self._prompt(trial, k, len(trials)):
                    why = (f"placement of trial {trial.id} not confirmed within "
                           f"confirm_timeout_s ({self.settings.confirm_timeout_s:g} s)")
                    self.get_logger().error(f"session ended: {why}")
                    sess.add_event(d, {"event": "session_ended", "reason": why,
                                       "trial": trial.id, "time": time.time()})
                    self.exit_code = 1
                    return
                self._place(trial)
                self.session_trial, self.result = trial, None
                self._open_trial(trial.seed, str(d / trial.record_name) if state == "started"
                                 else None, trial.record_name, str(d),
                                 placed_scene=sess.placed_scene(self.settings.scene_file,
                                                                trial.placement),
                                 extra={"session": {"name": self.session.name, "trial": trial.id,
                                                    "placement": trial.placement,
                                                    "truth": trial.truth}})
                sess.add_event(d, {"event": "trial_started", "trial": trial.id,
                                   "resumed": state == "started",
                                   "after_touch": self.record.n_touches, "time": time.time()})
                self._trial(finish_node=False)
                res = self.result
                if res is None:          # the node is being stopped: the trial stays resumable
                    return
                if "error" in res:
                    sess.add_event(d, {"event": "session_ended", "trial": trial.id,
                                       "reason": f"trial {trial.id} failed: {res['error']}",
                                       "time": time.time()})
                    return
                sess.add_event(d, {"event": "trial_done", "trial": trial.id,
                                   "prediction": res.get("prediction"),
                                   "correct": res.get("correct"), "touches": res.get("touches"),
                                   "stop_reason": res.get("stop_reason"), "time": time.time()})
            out = sess.summary(d)
            sess.finish_session(d, out)
            sess.add_event(d, {"event": "session_done", "accuracy": out["accuracy"],
                               "time": time.time()})
            self.get_logger().info(f"session {self.session.name}: {out['done']} trials, accuracy "
                                   f"{out['accuracy']:.3f}; folder {d}")
        except Exception as exc:  # the session must end in an explicit, recorded state
            if self._stopping or not self.context.ok():
                return
            self.get_logger().error(f"session failed: {type(exc).__name__}: {exc}")
            sess.add_event(d, {"event": "session_ended", "reason": f"{type(exc).__name__}: {exc}",
                               "time": time.time()})
            self.exit_code = 1
        finally:
            if not self._stopping:
                try:
                    from ...trial.report import write_session_report
                    write_session_report(d)
                except Exception as exc:  # noqa: BLE001 - the records are the ground truth
                    self.get_logger().warning(f"session report not written: {exc}")
            if self.settings.exit_when_done:
                self.finished.set()
