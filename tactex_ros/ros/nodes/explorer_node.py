"""explorer_node: runs one trial (``trial/run.py``) or a study session over the ROS graph.

The node keeps what is ROS: the press (action to the motion node), the waits, publishing and
the MCAP copy; the trial's life beside the engine (record, resume, replayed decisions,
checkpoints, report, result) is ``trial.run.TrialRun``, a session's course
``trial.session_run.SessionRun``. The trial runs in a worker thread, so the executor stays free
for action feedback, results and publishing; every wait has a deadline. Publishes
``tactex/ExplorationState`` on ``/tactex/state`` after each decision, rviz markers on
``/tactex/markers`` and the latest touch image on ``/tactex/touch_image``. Every touch is on
disk before it is used; a corrupt or wrongly sized image is recorded as rejected and never
trained on; a failed press is recorded with its reason and the trial goes on.

A press server that leaves the ROS graph, or sends no feedback for ``press_silence_s``, ends
the trial with that reason (the press that was cut off is recorded as ``interrupted``), rather
than waiting out ``press_timeout_s``. A press goal whose answer is lost (Fast DDS can drop a
response sent before the server matched the client's reader) is re-sent after
``goal_answer_s`` and the first one followed by its goal id (``ros/goal.py``); a request none
of whose sends was answered is asked again after ``goal_renew_s``. With ``resume``
(a record folder) the trial continues an interrupted one (``trial/resume.py``).

With ``session_file`` the node runs a study session (``trial.session_run.SessionRun``); the
session's operator is ``operator.SessionOperator`` (the ``~/confirm`` service, the latched
prompt on ``prompt_topic``, in simulation the mock camera's placement).
"""

from __future__ import annotations

import logging
import os
import threading
import time
from pathlib import Path
from typing import TYPE_CHECKING
from collections.abc import Callable

import numpy as np
from action_msgs.msg import GoalStatus
from rclpy.action import ActionClient
from sensor_msgs.msg import Image
from visualization_msgs.msg import MarkerArray

from .. import adapter
from ...core.engine import TouchFailed, TrialSpec
from ...core.schema import nest
from ...core.errors import DeviceError, InputError, TrialError
from ...core.touch import Touch
from ..settings import MARKER_TOPIC, STATE_TOPIC, ExplorerSettings
from ..bag import TOUCH_TOPIC
from ...trial import session as sess
from ...trial.control import OperatorStop
from ...trial.run import TouchInterrupted, TrialRun
from ...trial.session_run import SessionRun, trial_outcome
from ...trial.press_library import LibraryPressing
from ...robot.scene import load_scene
from .lifecycle import TactexNode
from .process import run
from ..goal import GoalRequest, Silence

if TYPE_CHECKING:
    from .operator import SessionOperator


#: Times the explorer asks again for a result after it was stopped (``goal_answer_s`` apart):
#: enough to outlast the few seconds a server takes to find a process again after the DDS
#: lease dropped it.
STALL_REASKS = 4


class PressServerLost(TouchInterrupted):
    """The press action server is gone (left the graph, or silent): the trial cannot go on."""


#: [s] how often ``ExplorerNode._wait`` polls a goal (a press takes seconds; a poll costs the
#: graph query of ``server_is_ready``)
WAIT_POLL_S = 0.05


class ExplorerNode(TactexNode):
    settings_cls = ExplorerSettings

    def __init__(self, **kw) -> None:
        super().__init__("explorer", **kw)
        # what configure opens and cleanup closes (None: not open)
        self.trial: TrialRun | None = None
        self.bag = None
        self.worker: threading.Thread | None = None
        self.trial_id: str | None = None
        self._running = threading.Event()   # set while active: the trial presses
        self._stopping = False
        self._bag_warned = False

    # ------------------------------------------------------------------ lifecycle
    def configure(self) -> None:
        from tactex.action import Press
        from tactex.msg import ExplorationState
        s = self.settings
        if s.nice:
            os.nice(s.nice)  # before torch starts its worker threads, which inherit it
        self.scene = load_scene(s.scene_file)
        self.ids = [p.id for p in self.scene.ordered]
        self.session: SessionRun | None = None
        self.library: LibraryPressing | None = None      # a press library's run
        self.operator: SessionOperator | None = None     # a session's or a library's
        self.trial = None
        self.bag = self.last_state = None
        self._bag_warned = False
        if s.session_file:
            self._configure_session()    # checks the trial file, opens the session folder
        elif s.library_materials:
            self._configure_library()    # checks the materials, opens the library folder
        else:
            self._open_trial(s.seed, s.resume or None, s.trial_id, s.record_dir)
        import uuid
        self.run_id = s.run_id or uuid.uuid4().hex      # this graph's identity on every goal
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
        self.incomplete: str | None = None     # a finished trial's missing files (``_trial``)
        self.session_trial = None
        self._t_trial = None
        self._silence = Silence()        # of the press server, since the last message
        self._stopping = False
        self._running = threading.Event()   # set while active: the trial presses
        self.worker: threading.Thread | None = None

    def load_settings(self) -> ExplorerSettings:
        """The parameters' settings, resolved as the launch file and ``tactex graph run``
        resolve a run's (``run_settings.resolve_run``, validated once): with ``resume`` (a
        trial record), the record's settings (preset, seed, every learner and trial setting,
        record folder), so the node needs no other parameter; a parameter given with another
        value than the record's is refused (InputError, exit status 2, both values named)."""
        from ..run_settings import resolve_run
        from .lifecycle import given_parameters, parameter_values
        values = parameter_values(self, ExplorerSettings)
        given = given_parameters(self)
        return resolve_run(explorer=nest({k: v for k, v in values.items() if k in given}),
                           defaults=values, origin="explorer parameters").explorer

    def _is_stopping(self) -> bool:
        """The node is being stopped (cleanup, or the process's context shut down)."""
        return self._stopping or not self.context.ok()

    def _log(self, level: int, text: str) -> None:
        """``TrialRun`` / ``SessionRun`` log lines, on the node's logger."""
        lg = self.get_logger()     # rclpy: one severity per call site, so three calls
        if level >= logging.ERROR:
            lg.error(text)
        elif level >= logging.WARNING:
            lg.warning(text)
        else:
            lg.info(text)

    def _spec(self, seed: int) -> TrialSpec:
        s = self.settings
        lib = self.session.current_library() if self.session is not None else None
        return TrialSpec(len(self.ids) - 1, s.learner, s.trial, seed=seed,
                         platform_ids=tuple(self.ids), library=lib)

    def _open_trial(self, seed: int, resume: str | None, trial_id: str, record_dir: str,
                    placed_scene: str | None = None, extra: dict | None = None) -> None:
        """A fresh engine (belief and learner reset; nothing re-imported) and the trial's
        record (``trial/run.py``): new in ``record_dir/trial_id``, or the interrupted one in
        ``resume``. ``placed_scene``: the scene text written into the record (a session's
        placement); ``extra``: more inputs for config.json (a session trial's placement and
        truth)."""
        s = self.settings
        inputs = s.record_inputs(seed)
        from ...trial.report import changed_settings, run_info
        base = type(s)(config=s.config).model_dump(exclude={"learner", "trial"})
        inputs["run"] = dict(run_info(), non_default=changed_settings(inputs["explorer"], base,
                                                                      "explorer."))
        if extra:
            inputs.update(extra)
        self.trial = TrialRun(self._spec(seed), record_dir, trial_id, press=self._press,
                              inputs=inputs, resume=resume, scene_file=s.scene_file,
                              placed_scene=placed_scene, check_record=self._check_scene,
                              log=self._log, min_free_mb=s.min_free_mb)
        self.trial_id = self.trial.trial_id
        self._not_written: list[str] = []    # the trial's writes besides its record's that failed
        self.bag = self._open_bag()
        self._bag_warned = False
        self.last_state = None

    def _check_scene(self, d: Path) -> None:
        """A record to resume was made on a scene with the same platforms."""
        was = load_scene(d / "scene.yaml") if (d / "scene.yaml").is_file() else None
        if was is not None and [p.id for p in was.ordered] != self.ids:
            raise InputError(f"resume: the scene's platforms {self.ids} are not the record's "
                             f"{[p.id for p in was.ordered]}")

    @property
    def record(self):
        """The open trial's record (None between a session's trials)."""
        return self.trial.record if self.trial is not None else None

    @property
    def engine(self):
        return self.trial.engine

    def _open_bag(self):
        """``topics.mcap`` in the record; a resumed run writes ``topics.<k>.mcap`` beside it
        (the parts of interrupted runs made one ``topics.mcap`` first), merged into
        ``topics.mcap`` when the trial ends (``bag.merge_bags``)."""
        from ..bag import BagWriter
        self._merge_bags()
        k = len(list(self.record.dir.glob("topics*.mcap")))
        return BagWriter(self.record.dir / ("topics.mcap" if k == 0 else f"topics.{k}.mcap"))

    def _merge_bags(self) -> None:
        """The record's bags as one ``topics.mcap``; a merge that fails keeps every part and
        lists why in ``events.jsonl`` (warned here; the trial goes on)."""
        from ..bag import merge_bags, recorded_bags
        try:
            if len(recorded_bags(self.record.dir)) > 1 and merge_bags(self.record.dir) is None:
                self.get_logger().warning("the MCAP parts of the trial could not be merged; "
                                          "each is kept (events.jsonl: mcap_merge_failed)")
        except TrialError as why:        # the event could not be written (the disk is full)
            self._not_written.append(str(why))

    def _bag_write(self, topic: str, msg) -> None:
        """Copy a message into the MCAP file; a failure there never stops the trial."""
        if self.bag is None:         # a session between trials: no trial record open
            return
        try:
            self.bag.write_all(topic, msg, self.get_clock().now().nanoseconds)
        except Exception as exc:  # noqa: BLE001 - the PNG+JSONL record is the ground truth
            if not self._bag_warned:
                self._bag_warned = True    # the trial goes on; it ends with exit status 1
                self.get_logger().warning(f"MCAP copy of the record failed: {exc}")
                try:
                    from ...trial.record import append_event
                    append_event(self.record.dir, {"event": "mcap_failed", "reason": str(exc),
                                                   "time": time.time()})
                except TrialError as why:  # the disk is full: the next touch ends the trial
                    self._not_written.append(str(why))

    def activate(self) -> None:
        """Start the trial (first activation) or let a paused one press again."""
        self.create_timer(1.0, self._publish_markers)
        self._running.set()
        if self.worker is None:
            target: Callable[[], None] = self._trial
            if self.session is not None:
                target = self._run_session
            elif self.library is not None:
                target = self._run_library
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
        self._running.set()             # a paused trial wakes up and sees the stop
        if self.record is not None:
            self.record.close()
        if self.bag is not None:
            self.bag.close()
        worker = self.worker
        if worker is not None and worker is not threading.current_thread():
            worker.join(timeout=3.0)
        self.worker = None

    def _health(self) -> tuple[int, str, dict]:
        """/diagnostics: the trial (and session) progress, the belief, the stop reason."""
        from ..diagnostics import ERROR, OK
        st, res = self.last_state, self.result or {}
        values: dict = {"trial": self.trial_id,
                        "touches": sum(st.touches) if st is not None else 0,
                        "belief": (" ".join(f"{p} {b:.2f}" for p, b in
                                            zip(self.ids[1:], st.belief, strict=True))
                                   if st is not None else ""),
                        "next": st.next_platform if st is not None else "",
                        "stop reason": res.get("stop_reason", ""),
                        "prediction": res.get("prediction", "")}
        msg = "trial running" if self.result is None else "trial done"
        if self.library is not None:
            lib = self.library
            waiting = self._op.awaiting
            msg = (f"library {lib.done()}/{len(lib.materials) * lib.presses} presses"
                   + (f"; waiting for the operator to confirm material {waiting}" if waiting
                      else ""))
            values.update(library=str(lib.out), **{"presses done": lib.done()})
        if self.result is None and not self.press.server_is_ready():
            msg = "starting: waiting for the press server (motion node)"
            values["state"] = "starting"
        if self.session is not None:
            done, n = self.session.done(), len(self.session.session.trials)
            values.update(session=self.session.session.name, **{"trials done": done,
                                                                 "trials": n})
            waiting = self._op.awaiting
            paused = self._op.control.paused
            values["operator"] = "paused" if paused else ""
            msg = (f"session {done}/{n} trials done"
                   + (f"; waiting for the operator to confirm trial {waiting}" if waiting
                      else "")
                   + (f"; trial {self._op.control.trial} paused by the operator"
                      if paused else ""))
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

    def _publish_state(self, rec, line: dict) -> None:
        """The decision ``line`` (already recorded by the trial) on ``state_topic``, the
        markers and the bag."""
        msg = adapter.state_msg(rec, trial_id=self.trial_id, sure=bool(self.engine.sure),
                                strategy=self.engine.trial_cfg.strategy,
                                platform_ids=self.ids[1:], reference_id=self.ids[0],
                                reference_touches=self.engine.reference_touches,
                                done=line["done"], prediction=line["prediction"],
                                t=self._now(), frame_id=self.scene.frame_id)
        self.last_state = msg
        self.state_pub.publish(msg)
        self._bag_write(STATE_TOPIC, msg)
        self._publish_markers()

    # ------------------------------------------------------------------ the trial
    def _wait(self, ready, deadline: float, watch: bool = False,
              on_stall=None) -> bool:
        """Poll ``ready()`` (a ``GoalRequest`` is polled by design, ros/goal.py) until it is
        True or ``deadline``; with ``watch``, raise PressServerLost once the press server is
        gone (left the graph for 1 s, or silent for ``press_silence_s``). Time this process
        was stopped counts for neither (``goal.Silence``); after such a stall ``on_stall()`` is
        called once the server is visible again and up to ``STALL_REASKS`` times in all,
        ``goal_answer_s`` apart, until ready (the answer may have been dropped meanwhile),
        and for ``press_silence_s`` an absent server counts as gone only after that long: a
        stall longer than the DDS participant lease (Fast DDS: 20 s) makes this process forget
        the other participants until they announce themselves again."""
        absent_since = None
        reasks, reask_at = 0, 0.0            # re-asks left after the last stall, next one at
        rediscover_until = -1.0              # monotonic [s]: end of the grace after a stall
        while not ready():
            stall = self._silence.tick()     # this process was stopped: not the server's fault
            deadline += stall
            now = time.monotonic()
            if stall > 0:
                rediscover_until = now + self.settings.press_silence_s
                if on_stall is not None:
                    reasks, reask_at = STALL_REASKS, now
            if reasks and now >= reask_at and self.press.server_is_ready():
                # an answer dropped while we were away: ask again, and again goal_answer_s
                # later, since a request sent before the server has found this process
                # again (after the DDS lease) is answered into the void
                on_stall()
                reasks, reask_at = reasks - 1, now + self.settings.goal_answer_s
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
                elif now - absent_since > (self.settings.press_silence_s
                                           if now < rediscover_until else 1.0):
                    raise PressServerLost("the press server left the ROS graph")
            time.sleep(WAIT_POLL_S)
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

    def _press(self, platform: int, meta: dict) -> Touch:
        """The trial's live touch (``TrialRun``): press ``platform`` (index), return the touch
        (contact image, the sensor's no-contact frame, the burst's further in-contact frames as
        ``Touch.extra``), ``meta`` filled for the record. A failed press (already retried by
        the motion node) or an unreadable image (any frame of the burst) raises
        ``TouchFailed(retry=False)``; a press server that is gone, ``PressServerLost``."""
        from tactex.action import Press
        self._wait_running()
        if self.operator is not None:     # a session: paused, or the trial ends (abort, ...)
            self._op.control.gate(self.settings.pause_timeout_s, self._is_stopping)
        pid = self.ids[platform]
        deadline = time.monotonic() + self.settings.press_timeout_s
        # a simulated clock that has not ticked yet (no /clock received: ROS time 0, the
        # first press right after the nodes came up) would make the request time 0
        if not self._wait(lambda: self._now() > 0.0, deadline):
            self._failed(meta, "no simulated clock (/clock) before the press deadline "
                               "(press_timeout_s)")
        meta["requested"] = self._now()
        self._silence.reset()
        # a goal whose answer is lost is re-sent after goal_answer_s, and the first one is
        # followed by its id when it runs (ros/goal.py): a lost response costs no touch; a
        # request whose every send went unanswered is asked again after goal_renew_s
        req = GoalRequest(self.press, Press.Goal(platform_id=pid, run_id=self.run_id),
                          answer_s=self.settings.goal_answer_s,
                          renew_s=self.settings.goal_renew_s,
                          feedback_callback=self._on_feedback)
        if not self._wait(req.answered, deadline, watch=True):
            self._failed(meta, "press goal not answered before the deadline")
        if req.refused:
            self._failed(meta, "press goal rejected by the motion node (busy, inactive, or "
                               f"serving another run than {self.run_id}: its log names which)")
        if not self._wait(req.finished, deadline, watch=True, on_stall=req.ask_again):
            req.cancel()
            self._failed(meta, f"press not finished within press_timeout_s "
                               f"({self.settings.press_timeout_s} s)")
        if req.resent:
            meta["goal_resent"] = req.resent
            self.get_logger().warning(f"press goal for {pid} re-sent {req.resent} time(s): "
                                      "its answer was lost")
        if req.result.status == GoalStatus.STATUS_UNKNOWN:
            self._failed(meta, "press goal lost: the motion node never took it"
                         + (f" (the explorer was stopped for {req.stalled_s:.1f} s while it "
                            "waited)" if req.stalled_s else ""))
        if req.stalled_s:
            meta["explorer_stalled_s"] = round(req.stalled_s, 3)
        res = req.result.result
        if not res.success:
            self._failed(meta, res.reason or "press failed", res.attempts)
        touch = res.touch
        if res.reason:        # attempts that failed before this one (motion node)
            meta["attempt_failures"] = res.reason
        meta.update(attempts=int(res.attempts), force_n=touch.contact_force_n,
                    depth_m=touch.depth_m, stamp=adapter.seconds(touch.header.stamp),
                    tare={"offset_n": touch.tare_offset_n, "spread_n": touch.tare_spread_n,
                          "samples": int(touch.tare_samples)},
                    surface={"z_m": touch.surface_z, "error_m": touch.surface_error_m,
                             "warning": touch.warning},
                    pose=[touch.pose.position.x, touch.pose.position.y, touch.pose.position.z],
                    press_s=touch.press_s,
                    phase_s=dict(zip(touch.phase_names, touch.phase_s, strict=True)))
        try:
            img = adapter.image_to_array(touch.image, f"touch of {pid}")
        except InputError as exc:
            meta.update(encoding=touch.image.encoding, width=touch.image.width,
                        height=touch.image.height)
            raise TouchFailed(str(exc), retry=False) from exc
        try:
            extra = adapter.images_to_frames(touch.extra_images, f"touch of {pid}")
        except InputError as exc:
            raise TouchFailed(str(exc), retry=False) from exc
        self.image_pub.publish(touch.image)
        self._bag_write(TOUCH_TOPIC, touch)
        return Touch(frame=img, no_contact=self._no_contact(touch), extra=extra)

    def _no_contact(self, touch) -> np.ndarray | None:
        """The touch's no-contact frame as an array (None when absent or unusable)."""
        if not touch.no_contact_image.data:
            return None
        try:
            return adapter.image_to_array(touch.no_contact_image, "no-contact frame")
        except InputError as exc:
            self.get_logger().warning(f"no-contact frame unusable: {exc}")
            return None

    @staticmethod
    def _failed(meta: dict, reason: str, attempts: int = 0) -> None:
        meta["attempts"] = attempts
        raise TouchFailed(reason, retry=False)

    def _trial(self, finish_node: bool = True) -> None:
        """Run the open trial to its result (or its error, recorded); ``finish_node``: the
        node's work is over afterwards (one trial; a session runs several)."""
        self.operator_stop: OperatorStop | None = None
        try:
            self._run_trial()
        except OperatorStop as stop:      # the session decides (abort, skip, redo)
            self.operator_stop = stop
        except Exception as exc:  # the trial must end in an explicit result
            if not self.context.ok() or self.record.closed:
                return   # the node is being stopped (SIGINT/SIGTERM): no result, resumable
            self.get_logger().error(f"trial failed: {type(exc).__name__}: {exc}")
            self.result = self.trial.fail(exc)
            self.exit_code = 1
        finally:
            self.bag.close()              # never raises (ros/bag.py)
            if self.bag is not None and not self.bag.failed:
                self._merge_bags()        # a resumed trial: one topics.mcap
            self.incomplete = self._incomplete()
            if finish_node and self.settings.exit_when_done:
                self.finished.set()

    def _incomplete(self) -> str | None:
        """A trial that has its result but not every file that completes it (its MCAP copy,
        report.html, an event): why, naming each file, logged as an error; the node then ends
        with exit status 1 (a run-time failure: ``tactex graph run`` prints it and no
        success). None when the trial failed (its error is the result) or nothing is missing."""
        if self.result is None or "error" in self.result or self.trial is None:
            return None
        missing = list(self.trial.write_failures) + self._not_written
        if self.bag is not None and self.bag.failed:
            missing.insert(0, f"the MCAP copy {str(self.bag.path)!r} stopped: {self.bag.failed} "
                              "(whole messages before stay readable)")
        if not missing:
            return None
        why = (f"trial {self.trial_id}: its result is in {str(self.record.dir / 'result.json')!r}"
               f" but not every file was written: {'; '.join(missing)}")
        self.get_logger().error(why)
        self.exit_code = 1
        return why

    def _run_trial(self) -> None:
        s = self.settings
        self._t_trial = time.monotonic()
        if not self.press.server_is_ready() and \
                not self.press.wait_for_server(timeout_sec=s.server_timeout_s):
            raise DeviceError(f"press action {s.press_action!r} not available within "
                              f"server_timeout_s ({s.server_timeout_s} s)")
        st = self.session_trial
        out = self.trial.run(on_decision=self._publish_state, t0=self._t_trial,
                             extra=None if st is None else lambda r: self._outcome(st, r))
        self.result = out
        self.get_logger().info(f"trial {self.trial_id}: reference matches "
                               f"{out['prediction']} after {out['touches']} touches "
                               f"(stopped: {out['stop_reason']}"
                               f"{'' if out['sure'] is not False else ', NOT SURE: best guess'}"
                               f", belief {out['confidence']:.2f}); record {self.record.dir}")

    # ------------------------------------------------------------------ the session
    def _configure_session(self) -> None:
        """Check the trial file against the scene (row named on error), open the session folder
        (``trial/session_run.py``) and make its operator (``operator.SessionOperator``: the
        confirm services, the prompt publisher, the placement client)."""
        s = self.settings
        session = sess.load_session(s.session_file, self.ids, seed=s.seed)
        d = Path(s.session_dir or Path(s.record_dir) /
                 f"{session.name}_{time.strftime('%Y%m%d_%H%M%S')}").resolve()
        keeper = None
        if getattr(s.learner, "fabric_library", False):     # a lab session learns its fabrics
            from ...core.library import LIBRARY_FILE        # in its own folder, with the rest
            from ...trial.library import LibraryKeeper
            keeper = LibraryKeeper(d / LIBRARY_FILE, s.learner, log=self._log)
        self.session = SessionRun(session, d, {
            "seed": s.seed, "config": s.config, "strategy": s.trial.strategy,
            "scene_file": str(Path(s.scene_file).resolve())}, s.confirm_timeout_s,
            log=self._log, library=keeper, only=sess.select_trials(session, s.trials))
        self.session_dir = d
        from .operator import SessionOperator
        self.operator = SessionOperator(self, s, self._is_stopping, record=self._record_operator)
        self.get_logger().info(f"session {session.name}: {len(session.trials)} trials, "
                               f"folder {d}{' (resumed)' if self._sess.resumed else ''}")

    def _configure_library(self) -> None:
        """Check the materials and the platform, open the library folder
        (``trial/press_library.py``: new, empty or a press library to continue) and make its
        operator (``operator.SessionOperator``, as a session's)."""
        from ...trial.press_library import LibraryPressing, parse_materials
        s = self.settings
        sim = bool(s.placement_service)          # the mock camera shows catalogue fabrics
        materials = parse_materials(s.library_materials,
                                    sess.catalogue_names() if sim else None)
        pid = s.library_platform or self.ids[0]
        if pid not in self.ids:
            raise InputError(f"library_platform {pid!r}: not a platform of the scene (its "
                             f"platforms: {', '.join(self.ids)})")
        self.library = LibraryPressing(Path(s.library_dir), materials, s.library_presses, pid,
                                       sim=sim, log=self._log)
        from .operator import SessionOperator
        self.operator = SessionOperator(self, s, self._is_stopping, record=self._record_operator)
        self.get_logger().info(f"press library {self.library.out}: {len(materials)} materials "
                               f"x {s.library_presses} presses on platform {pid}"
                               f"{' (continued)' if self.library.resumed else ''}")

    def _run_library(self) -> None:
        """The library's worker thread: every material's missing presses (``_press`` on the
        library's platform), each kept only when the contact guard accepts it. Ends the
        node's work (``exit_when_done``) in every case."""
        from ...core.guards import press_verdict
        lib, learner = self.library, self.settings.learner
        if lib is None:
            raise TrialError("explorer: no press library is open")
        index = self.ids.index(lib.platform)

        def accept(touch: Touch) -> tuple[bool, str]:
            if not learner.guards:
                return True, ""
            return press_verdict(touch, learner.contact_flat_min, learner.contact_min)
        try:
            if not self.press.server_is_ready() and not self.press.wait_for_server(
                    timeout_sec=self.settings.server_timeout_s):
                raise DeviceError(f"press action {self.settings.press_action!r} not "
                                  "available within server_timeout_s "
                                  f"({self.settings.server_timeout_s} s)")
            code = lib.run(self._op, lambda meta: self._press(index, meta), self._is_stopping,
                           accept=accept, control=self._op.control)
            if code:
                self.exit_code = code
        except DeviceError as exc:
            self.get_logger().error(str(exc))
            self.exit_code = 1
        finally:
            if self.settings.exit_when_done:
                self.finished.set()

    @property
    def _sess(self) -> SessionRun:
        """The running session (only in a session's methods)."""
        if self.session is None:
            raise TrialError("explorer: no session is running")
        return self.session

    @property
    def _op(self) -> SessionOperator:
        """The session's operator (only in a session's methods)."""
        if self.operator is None:
            raise TrialError("explorer: no session operator")
        return self.operator

    @property
    def _trial_run(self) -> TrialRun:
        """The running trial."""
        if self.trial is None:
            raise TrialError("explorer: no trial is running")
        return self.trial

    def _outcome(self, trial: sess.SessionTrial, result: dict) -> dict:
        """A session trial's result fields (``trial_outcome``); the time the operator held it
        paused is not part of its ``elapsed_s`` (kept as ``paused_s``)."""
        out = trial_outcome(trial, result)
        paused = self._op.control.paused_s
        if paused > 0 and isinstance(result.get("elapsed_s"), float):
            out.update(elapsed_s=result["elapsed_s"] - paused, paused_s=paused)
        return out

    def _say_progress(self, trial: sess.SessionTrial) -> None:
        """Session progress (trial k of n in this run, time left from the measured trial
        times) on the log and ``progress_topic``."""
        from std_msgs.msg import String
        from ...trial.session_run import progress_text
        text = progress_text(sess.summary(self._sess.dir), self._sess.only, trial.id)
        self.get_logger().info(text)
        self._op.progress_pub.publish(String(data=text))

    def _record_operator(self, event: dict) -> None:
        """An operator's request: into the session's (or the library's) events and the
        running trial's."""
        if self.library is not None:
            from ...trial.press_library import add_event
            add_event(self.library.out, event)
            return
        sess.add_event(self._sess.dir, event)
        if self.record is not None:
            from ...trial.record import append_event
            try:
                append_event(self.record.dir, event)
            except TrialError as why:        # the session's events hold it
                self.get_logger().warning(f"operator event not in the trial's events: {why}")

    def _session_trial(self, trial: sess.SessionTrial, resume: str | None) -> dict | None:
        """One trial of the session, to its result (None: the node is being stopped). Ended
        by the operator: a skip's result (``skipped``) is recorded; an abort or a redo gives
        ``{"operator": action, "by": ..., "caller": ...}`` and the record stays resumable."""
        self.session_trial, self.result = trial, None
        self._open_trial(trial.seed, resume, trial.record_name, str(self._sess.dir),
                         **self._sess.trial_inputs(trial, self.settings.scene_file))
        self._sess.trial_started(trial, resume is not None, self.record.n_touches)
        self._op.control.start(trial.id)
        self._say_progress(trial)
        try:
            self._trial(finish_node=False)
        finally:
            self._op.control.end()
        stop = self.operator_stop
        if stop is not None:
            said = {"by": stop.by, "caller": stop.caller or None}
            if stop.action == "skip":
                self.result = self._trial_run.skip(said)
                return self.result
            self.record.close()           # every press made is on disk
            return {"operator": stop.action, **said}
        if self.incomplete:              # the session ends: exit status 1, the file named
            raise TrialError(self.incomplete)
        return self.result

    def _run_session(self) -> None:
        """The session's worker thread: every trial not yet done, in order; then the session's
        result and report. Ends the node's work (``exit_when_done``) in every case."""
        try:
            code = self._sess.run(self._op, self._session_trial, self._is_stopping)
            if code:
                self.exit_code = code
        finally:
            if self.settings.exit_when_done:
                self.finished.set()


def main(args: list[str] | None = None) -> int:
    return run(ExplorerNode, args)


if __name__ == "__main__":
    raise SystemExit(main())
