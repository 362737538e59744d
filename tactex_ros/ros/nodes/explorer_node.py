"""explorer_node: runs the core trial engine over the ROS graph.

press (action to the motion node) -> record the touch on disk -> validate -> learn -> choose.
The trial runs in a worker thread, so the executor stays free for action feedback, results
and publishing; every wait has a deadline. Publishes ``tactex/ExplorationState`` on
``/tactex/state`` after each decision, rviz markers on ``/tactex/markers`` and the latest touch
image on ``/tactex/touch_image``. The record (``record.TrialRecord``) receives each touch
before it is used; a corrupt or wrongly sized image is recorded as rejected and never trained
on; a failed press is recorded with its reason and the trial goes on.

A press server that leaves the ROS graph, or sends no feedback for ``press_silence_s``, ends
the trial with that reason (the press that was cut off is recorded as ``interrupted``), rather
than waiting out ``press_timeout_s``. A press goal whose answer is lost (Fast DDS can drop a
response sent before the server matched the client's reader) is re-sent after
``goal_answer_s`` and the first one followed by its goal id (``ros/goal.py``). With ``resume`` (a record folder) the trial continues an
interrupted one: the recorded touches are handed to the engine again in order
(``resume.Replay``), then live presses take over.
"""

from __future__ import annotations

import os
import threading
import time

import numpy as np
from action_msgs.msg import GoalStatus
from rclpy.action import ActionClient
from sensor_msgs.msg import Image
from visualization_msgs.msg import MarkerArray

from .. import adapter
from ...core.engine import TouchFailed, TrialSpec, run_trial
from ...core.errors import InputError, TrialError
from ...core.touch import Touch
from ..settings import MARKER_TOPIC, STATE_TOPIC, ExplorerSettings
from ..bag import TOUCH_TOPIC
from ...trial.record import TrialRecord
from ...robot.scene import load_scene
from .lifecycle import TactexNode
from .process import run
from .session_mode import SessionMode, trial_outcome
from ..goal import GoalRequest, Silence


class PressServerLost(InputError):
    """The press action server is gone (left the graph, or silent): the trial cannot go on."""


class ExplorerNode(SessionMode, TactexNode):
    settings_cls = ExplorerSettings

    def __init__(self, **kw) -> None:
        super().__init__("explorer", **kw)

    # ------------------------------------------------------------------ lifecycle
    def configure(self) -> None:
        from tactex.action import Press
        from tactex.msg import ExplorationState
        s = self.settings
        if s.nice:
            os.nice(s.nice)  # before torch starts its worker threads, which inherit it
        self.scene = load_scene(s.scene_file)
        self.ids = [p.id for p in self.scene.ordered]
        self.session = None
        self.record = self.bag = self.last_state = None
        if s.session_file:
            self.configure_session()    # checks the trial file, opens the session folder
            TrialSpec(len(self.ids) - 1, s.learner, s.trial, seed=s.seed,
                      platform_ids=tuple(self.ids)).engine()   # settings refused here
        else:
            self._open_trial(s.seed, s.resume or None, s.trial_id, s.record_dir)
        self.press = ActionClient(self, Press, s.press_action)
        latched = adapter.latched_qos()     # late joiners (rviz, foxglove) get the last one
        self.state_pub = self.create_lifecycle_publisher(ExplorationState, s.state_topic,
                                                         latched)
        self.marker_pub = self.create_lifecycle_publisher(MarkerArray, s.marker_topic, latched)
        self.image_pub = self.create_lifecycle_publisher(Image, s.touch_image_topic, latched)
        from ..diagnostics import Diagnostics
        self.diag = Diagnostics(self, s.diag_period_s)
        self.diag.add("trial", "tactex explorer", self._health)
        self.result: dict | None = None
        self.session_trial = None
        self._t_trial = None
        self._silence = Silence()        # of the press server, since the last message
        self._stopping = False
        self._running = threading.Event()   # set while active: the trial presses
        self.worker: threading.Thread | None = None

    def _open_trial(self, seed: int, resume: str | None, trial_id: str, record_dir: str,
                    placed_scene: str | None = None, extra: dict | None = None) -> None:
        """A fresh engine (belief and learner reset; nothing re-imported) and the trial's
        record: new in ``record_dir/trial_id``, or the interrupted one in ``resume``.
        ``placed_scene``: the scene text written into the record (a session's placement);
        ``extra``: more inputs for config.json (a session trial's placement and truth)."""
        s = self.settings
        self.spec = TrialSpec(len(self.ids) - 1, s.learner, s.trial, seed=seed,
                              platform_ids=tuple(self.ids))
        self.engine = self.spec.engine()       # settings refused here, at configure
        explorer = s.model_dump(exclude={"learner", "trial"})
        explorer["seed"] = seed
        inputs = {"explorer": explorer, "learner": s.learner.model_dump(),
                  "trial": s.trial.model_dump()}
        if extra:
            inputs.update(extra)
        self.replay = None
        if resume:
            self._open_resume(resume, inputs)
        else:
            self.trial_id = trial_id or time.strftime("trial_%Y%m%d_%H%M%S")
            self.record = TrialRecord(record_dir, self.trial_id)
            self.record.save_inputs(s.scene_file, inputs)
            if placed_scene is not None:
                (self.record.dir / "scene.yaml").write_text(placed_scene)
        self.bag = self._open_bag()
        self.last_state = None

    def _open_bag(self):
        """``topics.mcap`` in the record (``topics.<k>.mcap`` for the k-th resume)."""
        from ..bag import BagWriter
        k = len(list(self.record.dir.glob("topics*.mcap")))
        return BagWriter(self.record.dir / ("topics.mcap" if k == 0 else f"topics.{k}.mcap"))

    def _bag_write(self, topic: str, msg) -> None:
        """Copy a message into the MCAP file; a failure there never stops the trial."""
        if self.bag is None:         # a session between trials: no trial record open
            return
        try:
            self.bag.write(topic, msg, self.get_clock().now().nanoseconds)
        except Exception as exc:  # noqa: BLE001 - the PNG+JSONL record is the ground truth
            if not getattr(self, "_bag_warned", False):
                self._bag_warned = True
                self.get_logger().warning(f"MCAP copy of the record failed: {exc}")

    def _open_resume(self, folder: str, inputs: dict) -> None:
        """Continue the interrupted trial recorded in ``folder`` (settings must match)."""
        from pathlib import Path

        from ...trial.record import append_event
        from ...trial.resume import check_settings, load_replay, restore_engine
        d = Path(folder).resolve()
        self.record = TrialRecord(d.parent, d.name, resume=True)
        self.trial_id = d.name
        check_settings(d, inputs)
        was = load_scene(d / "scene.yaml") if (d / "scene.yaml").is_file() else None
        if was is not None and [p.id for p in was.ordered] != self.ids:
            raise InputError(f"resume: the scene's platforms {self.ids} are not the record's "
                             f"{[p.id for p in was.ordered]}")
        self.replay, rec = load_replay(d, self._press, self.ids)
        self.engine, after, how = restore_engine(self.spec, d, self.replay.recorded)
        self.replay.recorded = [r for r in self.replay.recorded if r.seq > after]
        self._replay_decisions = rec["decisions"]
        self._decisions = len(self.engine.records)     # decisions restored, not re-made
        self.get_logger().info(f"resume: {how}")
        append_event(d, {"event": "resumed", "after_touch": self.record.n_touches,
                         "touches_replayed": len(self.replay.recorded),
                         "decisions_on_disk": len(rec["decisions"]),
                         "checkpoint_round": len(self.engine.records), "how": how,
                         "time": time.time()})

    def activate(self) -> None:
        """Start the trial (first activation) or let a paused one press again."""
        self.create_timer(1.0, self._publish_markers)
        self._running.set()
        if self.worker is None:
            target = self._trial
            if self.session is not None:
                target = self.run_session
            self.worker = threading.Thread(target=target, name="trial", daemon=True)
            self.worker.start()

    def deactivate(self) -> None:
        """Pause the trial: the press under way ends, the next waits for re-activation (up to
        ``pause_timeout_s``)."""
        self._running.clear()

    def cleanup(self) -> None:
        """Stopped mid-trial: let a touch being written finish, then write nothing more; give
        the trial thread a moment to leave its wait before the action client goes away."""
        self._stopping = True
        if getattr(self, "_running", None) is not None:
            self._running.set()             # a paused trial wakes up and sees the stop
        record = getattr(self, "record", None)
        if record is not None:
            record.close()
        if getattr(self, "bag", None) is not None:
            self.bag.close()
        worker = getattr(self, "worker", None)
        if worker is not None and worker is not threading.current_thread():
            worker.join(timeout=3.0)
        self.worker = None

    def _health(self) -> tuple[int, str, dict]:
        """/diagnostics: the trial (and session) progress, the belief, the stop reason."""
        from ..diagnostics import ERROR, OK
        st, res = self.last_state, self.result or {}
        values: dict = {"trial": getattr(self, "trial_id", None),
                        "touches": sum(st.touches) if st is not None else 0,
                        "belief": (" ".join(f"{p} {b:.2f}" for p, b in
                                            zip(self.ids[1:], st.belief))
                                   if st is not None else ""),
                        "next": st.next_platform if st is not None else "",
                        "stop reason": res.get("stop_reason", ""),
                        "prediction": res.get("prediction", "")}
        msg = "trial running" if self.result is None else "trial done"
        if self.session is not None:
            from ...trial import session as sess
            done = sum(sess.trial_state(self.session_dir, t) == "done"
                       for t in self.session.trials)
            values.update(session=self.session.name, **{"trials done": done,
                                                         "trials": len(self.session.trials)})
            waiting = getattr(self, "_awaiting", None)
            msg = (f"session {done}/{len(self.session.trials)} trials done"
                   + (f"; waiting for the operator to confirm trial {waiting}" if waiting
                      else ""))
        if "error" in res:
            return ERROR, f"trial failed: {res['error']}", values
        return OK, msg, values

    # ------------------------------------------------------------------ publishing
    def _now(self) -> float:
        return self.get_clock().now().nanoseconds * 1e-9

    def _publish_markers(self) -> None:
        msg = adapter.markers(self.scene, self.last_state, self._now())
        self.marker_pub.publish(msg)
        self._bag_write(MARKER_TOPIC, msg)

    def _publish_state(self, rec, done: bool, prediction: str) -> None:
        msg = adapter.state_msg(rec, trial_id=self.trial_id, sure=bool(self.engine.sure),
                                strategy=self.engine.trial_cfg.strategy,
                                platform_ids=self.ids[1:], reference_id=self.ids[0],
                                reference_touches=self.engine.reference_touches, done=done,
                                prediction=prediction, t=self._now(),
                                frame_id=self.scene.frame_id)
        self.last_state = msg
        self.state_pub.publish(msg)
        self._bag_write(STATE_TOPIC, msg)
        self._publish_markers()
        if self.replay is not None and self._replayed_decision(msg):
            return                            # already on disk before the interruption
        self.record.add_decision({"round": rec.round, "next": msg.next_platform,
                                  "belief": list(msg.belief),
                                  "uncertainty": list(msg.uncertainty),
                                  "touches": list(msg.touches), "model": rec.model,
                                  "decision_s": rec.decision_s, "done": done,
                                  "prediction": prediction,
                                  "sure": self.engine.sure if done else None})

    def _replayed_decision(self, msg) -> bool:
        """True for a decision a resumed trial re-made that the record already holds (a
        recomputed belief that differs from the recorded one is noted in events.jsonl)."""
        i, self._decisions = self._decisions, self._decisions + 1
        if i >= len(self._replay_decisions):
            return False
        was = self._replay_decisions[i].get("belief") or []
        diff = float(np.max(np.abs(np.subtract(was, list(msg.belief))))) \
            if len(was) == len(msg.belief) else float("inf")
        if diff > 1e-4:
            from ...trial.record import append_event
            append_event(self.record.dir, {"event": "replay_differs", "decision": i + 1,
                                           "max_belief_diff": diff})
            self.get_logger().warning(f"resume: decision {i + 1} differs from the record "
                                      f"(belief by up to {diff:.3g})")
        return True

    # ------------------------------------------------------------------ the trial
    def _wait(self, ready, deadline: float, watch: bool = False,
              on_stall=None) -> bool:
        """Poll ``ready()`` (a ``GoalRequest`` is polled by design, ros/goal.py) until it is
        True or ``deadline``; with ``watch``, raise PressServerLost once the press server is
        gone (left the graph for 1 s, or silent for ``press_silence_s``). Time this process
        was stopped counts for neither (``goal.Silence``); after such a stall ``on_stall()`` is
        called once the server is visible again (the answer may have been dropped meanwhile)."""
        absent_since = None
        reask = False
        while not ready():
            stall = self._silence.tick()     # this process was stopped: not the server's fault
            deadline += stall
            reask = reask or (stall > 0 and on_stall is not None)
            if reask and self.press.server_is_ready():
                on_stall()                   # an answer dropped while we were away: ask again
                reask = False
            now = time.monotonic()
            if absent_since is not None:
                absent_since += stall
            if now > deadline:
                return False
            if self._stopping or not self.context.ok():
                raise TrialError("the explorer is stopping")
            if watch:
                silent = self._silence.silent_s()
                if silent > self.settings.press_silence_s:
                    raise PressServerLost(f"no answer or feedback from the press server for "
                                          f"{silent:.1f} s (press_silence_s)")
                if self.press.server_is_ready():
                    absent_since = None
                elif absent_since is None:
                    absent_since = now
                elif now - absent_since > 1.0:
                    raise PressServerLost("the press server left the ROS graph")
            time.sleep(0.01)
        return True

    def _wait_running(self) -> None:
        """Before a press: wait while the node is deactivated (paused), up to
        ``pause_timeout_s``; TrialError when stopping or paused too long."""
        if not self._running.wait(timeout=self.settings.pause_timeout_s):
            raise TrialError(f"the explorer stayed inactive longer than pause_timeout_s "
                              f"({self.settings.pause_timeout_s} s)")
        if self._stopping:
            raise TrialError("the explorer is stopping")

    def _on_feedback(self, _msg) -> None:
        self._silence.heard()

    def _touch(self, platform: int) -> Touch:
        """The engine's ``touch_fn`` of a resumed trial: recorded touches, then presses."""
        touch = self.replay(platform)
        if self.replay.current is not None and isinstance(touch, Touch):
            self._set_guard_reference(touch.no_contact)
        return touch

    def _press(self, platform: int) -> Touch:
        """The engine's ``touch_fn``: press ``platform`` (index), put the touch on disk, return
        it (contact image and the sensor's no-contact frame). A failed press (already retried by the motion node) or an unreadable image is
        recorded and raised as ``TouchFailed(retry=False)``."""
        from tactex.action import Press
        self._wait_running()
        pid = self.ids[platform]
        deadline = time.monotonic() + self.settings.press_timeout_s
        meta = {"platform_id": pid, "platform_index": platform, "requested": self._now()}
        self._silence.reset()
        # a goal whose answer is lost is re-sent after goal_answer_s, and the first one is
        # followed by its id when it runs (ros/goal.py): a lost response costs no touch
        req = GoalRequest(self.press, Press.Goal(platform_id=pid),
                          answer_s=self.settings.goal_answer_s,
                          feedback_callback=self._on_feedback)
        try:
            if not self._wait(req.answered, deadline, watch=True):
                self._failed(platform, meta, "press goal not answered before the deadline")
            if req.refused:
                self._failed(platform, meta, "press goal rejected by the motion node")
            if not self._wait(req.finished, deadline, watch=True, on_stall=req.ask_again):
                req.cancel()
                self._failed(platform, meta, f"press not finished within press_timeout_s "
                                             f"({self.settings.press_timeout_s} s)")
        except PressServerLost as exc:   # the press never ended: a resume makes it again
            self.record.add_touch(None, dict(meta, accepted=False, reason=str(exc),
                                             interrupted=True))
            raise
        if req.resent:
            meta["goal_resent"] = req.resent
            self.get_logger().warning(f"press goal for {pid} re-sent {req.resent} time(s): "
                                      "its answer was lost")
        if req.result.status == GoalStatus.STATUS_UNKNOWN:
            self._failed(platform, meta, "press goal lost: the motion node never took it")
        res = req.result.result
        if not res.success:
            self._failed(platform, meta, res.reason or "press failed", res.attempts)
        touch = res.touch
        meta.update(attempts=int(res.attempts), force_n=touch.contact_force_n,
                    depth_m=touch.depth_m, stamp=adapter.seconds(touch.header.stamp),
                    tare={"offset_n": touch.tare_offset_n, "spread_n": touch.tare_spread_n,
                          "samples": int(touch.tare_samples)},
                    pose=[touch.pose.position.x, touch.pose.position.y, touch.pose.position.z])
        try:
            img = adapter.image_to_array(touch.image, f"touch of {pid}")
        except InputError as exc:
            meta.update(accepted=False, reason=str(exc), encoding=touch.image.encoding,
                        width=touch.image.width, height=touch.image.height)
            self.record.add_touch(None, meta)
            self.get_logger().warning(f"touch rejected: {exc}")
            raise TouchFailed(str(exc), retry=False) from exc
        no_contact = self._no_contact(touch)
        self.record.add_touch(img, dict(meta, accepted=True),   # on disk before it is used
                              no_contact=no_contact)
        self._set_guard_reference(no_contact)
        self.image_pub.publish(touch.image)
        self._bag_write(TOUCH_TOPIC, touch)
        return Touch(frame=img, no_contact=no_contact)

    def _no_contact(self, touch) -> np.ndarray | None:
        """The touch's no-contact frame as an array (None when absent or unusable)."""
        if not touch.no_contact_image.data:
            return None
        try:
            return adapter.image_to_array(touch.no_contact_image, "no-contact frame")
        except InputError as exc:
            self.get_logger().warning(f"no-contact frame unusable: {exc}")
            return None

    def _on_rejected(self, platform: int, exc: InputError) -> None:
        """The engine refused the last recorded touch (e.g. the guard: a blank frame)."""
        cur = self.replay.current if self.replay is not None else None
        if cur is not None:              # a replayed touch: marked already, unless cut off
            if not cur.rejected:
                self.record.reject_touch(cur.seq, str(exc))
            return
        self.record.reject_touch(self.record.n_touches, str(exc))
        self.get_logger().warning(f"touch rejected: {exc}")

    def _set_guard_reference(self, no_contact: np.ndarray | None) -> None:
        """Give the core's contact guard the sensor's no-contact frame (first valid one)."""
        guard = self.engine.guard
        if guard is None or guard.has_reference or no_contact is None:
            return
        guard.set_reference(no_contact)

    def _failed(self, platform: int, meta: dict, reason: str, attempts: int = 0) -> None:
        self.record.add_touch(None, dict(meta, accepted=False, reason=reason,
                                         attempts=attempts))
        self.get_logger().warning(f"touch of {self.ids[platform]} failed: {reason}")
        raise TouchFailed(reason, retry=False)

    def _trial(self, finish_node: bool = True) -> None:
        """Run the open trial to its result (or its error, recorded); ``finish_node``: the
        node's work is over afterwards (one trial; a session runs several)."""
        try:
            self._run_trial()
        except Exception as exc:  # the trial must end in an explicit result
            if not self.context.ok() or self.record.closed:
                return   # the node is being stopped (SIGINT/SIGTERM): no result, resumable
            self.get_logger().error(f"trial failed: {type(exc).__name__}: {exc}")
            self.result = {"error": f"{type(exc).__name__}: {exc}", "trial_id": self.trial_id}
            self.record.finish(self.result)
            self.exit_code = 1
        finally:
            self.bag.close()
            if finish_node and self.settings.exit_when_done:
                self.finished.set()

    def _checkpoint(self, eng) -> None:
        """After a round that asked for a touch: the learner's state into the record, so a
        resume continues from it instead of re-training (a learner without the hook, e.g. the
        descriptor, writes none). A failure here never stops the trial: a resume re-trains."""
        ck = eng.checkpoint()
        if ck is None:
            return
        rp = self.replay
        after = rp.recorded[rp.pos - 1].seq if rp is not None and rp.replaying and rp.pos \
            else self.record.n_touches
        try:
            self.record.write_checkpoint(ck[0], ck[1], after)
        except (OSError, TrialError) as exc:
            if not getattr(self, "_ckpt_warned", False):
                self._ckpt_warned = True
                self.get_logger().warning(f"learner checkpoint not written: {exc}")

    def _write_report(self) -> None:
        """``report.html`` beside the result; a failure there never loses the trial."""
        try:
            from ...trial.report import write_trial_report
            write_trial_report(self.record.dir)
        except Exception as exc:  # noqa: BLE001 - the record is the ground truth
            self.get_logger().warning(f"report.html not written: {exc}")

    def _run_trial(self) -> None:
        s = self.settings
        self._t_trial = time.monotonic()
        if not self.press.server_is_ready() and \
                not self.press.wait_for_server(timeout_sec=s.server_timeout_s):
            raise InputError(f"press action {s.press_action!r} not available within "
                             f"server_timeout_s ({s.server_timeout_s} s)")
        eng = self.engine

        def on_round(rec) -> None:
            pred = self.ids[int(np.argmax(rec.probs)) + 1] if eng.done else ""
            self._publish_state(rec, eng.done, pred)
            self._checkpoint(eng)

        touch_fn = self._press if self.replay is None else self._touch
        res = run_trial(self.spec, touch_fn, on_round=on_round, on_rejected=self._on_rejected,
                        engine=eng)
        out = res.to_dict()
        out.update(trial_id=self.trial_id, record=str(self.record.dir),
                   strategy=eng.trial_cfg.strategy, model=eng.learner.model_name,
                   seed=self.spec.seed)
        if self.replay is not None:
            from ...trial.record import read_record
            out["resumed"] = [e for e in read_record(self.record.dir, images=False)["events"]
                              if e.get("event") == "resumed"]
        if self._t_trial is not None:
            out["elapsed_s"] = time.monotonic() - self._t_trial
        if self.session_trial is not None:
            out.update(trial_outcome(self.session_trial, out))
        self.result = out
        path = self.record.finish(out)
        self._write_report()
        self.get_logger().info(f"trial {self.trial_id}: reference matches "
                               f"{out['prediction']} after {out['touches']} touches "
                               f"(stopped: {out['stop_reason']}"
                               f"{'' if out['sure'] is not False else ', NOT SURE: best guess'}"
                               f", belief {out['confidence']:.2f}); record {path.parent}")


def main(args: list[str] | None = None) -> int:
    return run(ExplorerNode, args)


if __name__ == "__main__":
    raise SystemExit(main())
