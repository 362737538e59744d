"""motion_node: presses the GelSight on a platform through a Cartesian impedance controller.

Serves the ``tactex/action/Press`` action (goal: platform id from the scene). The robot profile
(``robot``: ``config/robots/<name>.yaml``, see ``tactex_ros/robot/robots.py``) names the controller's
equilibrium topic and type (PoseStamped, or multipanda_ros2's Float64MultiArray), the state
(PoseStamped + WrenchStamped of franka_robot_state_broadcaster, or a franka state message), the
controller stiffness, the wrench sign and the recovery interface. The press sequence is
``robot.press.PressController``: approach, descend (guarded: the equilibrium goes on past the
scene's surface until the tared force finds it, then to the force threshold), hold the force by
feedback during settle and capture (GelSight capture service), retract; where the surface was
found, and a warning if it moved, go into the touch. Always enforced: workspace box, force magnitude limit, speed limit, a deadline for
every phase. A failed attempt (no contact, no image, force limit) is retried up to
``press.retries`` times. A robot error (the state stops arriving during a press, or the franka
state reports a reflex or a user stop) ends the attempt at once; if fresh state does not come
back by itself within ``state_timeout_s`` (a gap on a loaded machine does), the node runs the
profile's recovery (a hold target where the controller stays active through it, the calls
that must come first, e.g. deactivating controllers on Humble, the error recovery action or
service and its result, then re-activation of hardware and controllers by the profile's
service calls, then fresh state) and retries, or ends the goal with the reason (also when
recovery is off, e.g. franka_msgs is not installed). Every state subscription asks for its
upstream publisher's QoS (the profile's).

Pre-flight (``preflight``, at the end of the configuration, before any target is published):
the robot state arrives at the profile's ``state.min_rate_hz`` (or ``min_state_rate_hz``) or
faster, franka's ``robot_mode`` (where it is
read) is move, and franka's collision thresholds are set to what the press needs through the
profile's collision service (or the start is refused with the ``ros2 service call`` to run).
Any failure refuses the configuration with the reason (``robot/preflight.py``,
docs/hardware_checks.md): exit status 1 for a robot whose state is silent or too slow
(``DeviceError``) or not in move mode (``DeviceNotReady``), 2 for collision thresholds that
do not fit the press (``InputError``). One graph per arm (no second publisher of
the target, the action's status or the robot state) is checked in the pre-flight and again
until the node takes its first goal, since DDS discovery has no deadline: exit status 2.
"""

from __future__ import annotations

import dataclasses
import os
import threading
import time

import numpy as np
from action_msgs.msg import GoalStatus
from geometry_msgs.msg import PoseStamped, WrenchStamped
from rclpy.action import ActionClient, ActionServer, CancelResponse, GoalResponse
from rclpy.serialization import deserialize_message
from rclpy.subscription_content_filter_options import ContentFilterOptions

from .. import adapter
from ...core.errors import InputError, TrialError
from ...robot import preflight as checks
from ...robot.press import PressController, check_press
from ..preflight import Probe, arm_topics, other_graph, robot_preflight
from ..settings import MotionSettings
from ...robot.robots import (fill_message, hold_target, import_interface, load_profile,
                             with_profile)
from ...robot.scene import load_scene
from .lifecycle import TactexNode, in_thread, wait_for
from .process import run


# only franka states not in move mode (libfranka RobotMode 2), where the middleware filters
MODE_FILTER = ContentFilterOptions(filter_expression="robot_mode <> %0",
                                   expression_parameters=["2"])
MODE_HOLD_S = 0.25   # [s] a robot_mode read from the mode topic counts this long
BURST_RETRY_S = 0.05  # [s] a short burst is asked for again after this (the press held)
SIM_BEHIND_S = 2.0    # [s wall] a simulated clock standing still this long: "simulation behind"
SIM_BEHIND_RTF = 0.5  # below this real-time factor the simulation is behind (WARN)
GRAPH_CHECK_S = 0.5   # [s] one graph per arm is checked this often until the first goal
#: [s] press feedback goes out at a phase change and at most this often otherwise (10 Hz: a
#: display's rate and 100 times inside press_silence_s; every 10 ms control step cost the
#: explorer a wake-up per step for a message it only counts)
FEEDBACK_PERIOD_S = 0.1
#: the wrench subscription's own keep-last depth: the upstream publisher's reliability
#: (best effort) with room for 64 ms of franka's 1 kHz stream between two callbacks, so the
#: force limit sees every sample (a depth of 1 keeps only the newest when a callback is late)
WRENCH_DEPTH = 64


class Burst:
    """One capture of a press, asked for without blocking the press loop (which goes on
    stepping, so its force limit holds at every sample): the strongest-contact frame of the
    last ``window_s`` [s] and ``frames`` in-contact frames in all. A burst with fewer frames (a
    camera that dropped or delayed frames, a short hold) is asked for again every
    ``BURST_RETRY_S`` until it is whole or ``deadline_s`` [s] is near; a burst still short then
    is kept (``short``: its frame count). ``poll`` returns None while it runs, then
    (ok, reason, the Capture response or None)."""

    def __init__(self, client, window_s: float, frames: int, deadline_s: float,
                 min_contact_score: float, now: float) -> None:
        self.client, self.window_s, self.frames = client, window_s, frames
        self.deadline_s, self.min_score = deadline_s, min_contact_score
        self.end, self.fut, self.next_t, self.short = now + deadline_s, None, now, 0

    def poll(self, now: float):
        from tactex.srv import Capture
        if self.fut is None:
            if now < self.next_t:
                return None
            if not self.client.service_is_ready():
                return ((False, "capture service not available", None) if now > self.end
                        else None)
            self.fut = self.client.call_async(Capture.Request(window_s=self.window_s,
                                                              frames=self.frames))
            return None
        if not self.fut.done():
            if now <= self.end:
                return None
            self.cancel()
            return False, f"no image within capture_deadline_s ({self.deadline_s} s)", None
        resp, self.fut = self.fut.result(), None
        if not resp.success:
            return False, resp.reason, None
        if resp.contact_score < self.min_score:
            return False, (f"no contact in the captured frames: score {resp.contact_score:.2f}"
                           f" < min_contact_score {self.min_score}"), None
        got = 1 + len(resp.extra_images)
        if got >= self.frames:
            return True, "", resp
        if now + 2 * BURST_RETRY_S > self.end:
            self.short = got
            return True, "", resp
        self.next_t = now + BURST_RETRY_S
        return None

    def cancel(self) -> None:
        """Forget the request in flight (its answer, if any, is dropped)."""
        if self.fut is not None:
            self.client.remove_pending_request(self.fut)
            self.fut = None


class RobotError(Exception):
    """The robot stopped (reflex, controllers down): recovery is needed before a retry."""


class MotionNode(TactexNode):
    settings_cls = MotionSettings

    def __init__(self, **kw) -> None:
        super().__init__("motion", **kw)

    def configure(self) -> None:
        from tactex.action import Press
        from tactex.srv import Capture

        from ..simclock import NodeClock, RealTimeFactor
        # deadlines, rates and staleness on the node's clock: simulated time in a simulated
        # graph (use_sim_time, ros/simclock.py), else monotonic wall time
        self.dclock = NodeClock(self)
        self._rtf = RealTimeFactor()
        self.scene = load_scene(self.settings.scene_file)
        prof = self.profile = load_profile(self.settings.robot)
        s = self.settings = with_profile(self.settings, prof)
        if self.scene.frame_id != prof.frame_id:
            raise InputError(f"scene frame_id {self.scene.frame_id!r} is not robot profile "
                             f"{prof.name!r}'s base frame {prof.frame_id!r}")
        self.k = s.stiffness
        self.sign = s.force_sign
        check_press(self.scene, self.k, f"scene with robot {prof.name!r}", prof.law.error_clip)
        self.quat = np.array(self.scene.tool_orientation)
        self.position: np.ndarray | None = None
        self.pose_t = -1.0
        self.force = 0.0            # signed normal force [N]
        self.force_mag = 0.0        # force magnitude [N]
        self.wrench_t = -1.0
        self._samples: list[tuple[float, float]] = []   # (normal, magnitude) since the tick
        self._samples_lock = threading.Lock()
        self.samples_seen = 0        # wrench samples the press loop checked
        self.held_ticks = 0         # press-loop ticks that held the target on stale state
        self.robot_mode = 0
        self.busy = threading.Lock()
        self.found: dict[str, float] = {}   # platform id -> surface z its last press found [m]
        self.last_phases: dict[str, float] = {}   # the last press's time per phase [s]
        self.took_goal = False      # a press goal was taken: this graph drives the arm
        self._setup_diagnostics()
        # every state subscription asks for its upstream publisher's QoS (the profile's)
        if prof.franka_state:
            self.create_subscription(import_interface(prof.state_type),
                                     s.state_topic, self._on_state,
                                     adapter.qos_profile(prof.state_qos))
        else:
            self.create_subscription(PoseStamped, s.pose_topic,
                                     self._on_pose, adapter.qos_profile(prof.pose_qos))
            self.create_subscription(WrenchStamped, s.wrench_topic,
                                     self._on_wrench,
                                     adapter.qos_profile(dataclasses.replace(
                                         prof.wrench_qos,
                                         depth=max(prof.wrench_qos.depth, WRENCH_DEPTH))))
        if prof.mode_topic:
            # franka's full state comes at 1 kHz (franka_ros2 v3.4.0
            # franka_robot_state_broadcaster.cpp:149-150, reliable, depth 10) and only
            # robot_mode is wanted. Where the middleware filters content (Fast DDS), only
            # messages whose robot_mode is not move reach this process at all; otherwise they
            # are taken raw and decoded at most mode_rate_hz times a second. A mode counts for
            # MODE_HOLD_S after the last message.
            try:
                self._mode_type = import_interface(prof.mode_type)
                self._mode_next, self._mode_t, self.topic_mode = 0.0, float("-inf"), None
                try:
                    sub = self.create_subscription(
                        self._mode_type, s.mode_topic, self._on_mode_raw,
                        adapter.qos_profile(prof.mode_qos), raw=True,
                        content_filter_options=MODE_FILTER)
                except TypeError:           # an rclpy without content filters
                    sub = self.create_subscription(
                        self._mode_type, s.mode_topic, self._on_mode_raw,
                        adapter.qos_profile(prof.mode_qos), raw=True)
                cft = getattr(sub, "is_cft_enabled", False)   # a property or a method
                self.get_logger().info(
                    "robot mode: " + ("only non-move states delivered (content filter)"
                                      if (cft() if callable(cft) else cft)
                                      else f"decoded at most {s.mode_rate_hz:g} Hz"))
            except InputError as exc:
                self.get_logger().warning(f"robot mode not read (reflex seen only as the state "
                                          f"stopping): {exc}")
        self.target_type = prof.target_type
        self.target_pub = self.create_lifecycle_publisher(import_interface(prof.target_type),
                                                          s.target_topic,
                                                          10)
        self.capture = self.create_client(Capture, s.capture_service)
        self._setup_recovery()
        self._Press = Press
        self._abort = threading.Event()   # set on deactivation: the running press retracts
        # created once; goals are accepted only while the node is active (``_on_goal``)
        self.server = ActionServer(
            self, Press, s.press_action, execute_callback=self._execute_async,
            goal_callback=self._on_goal, cancel_callback=lambda _: CancelResponse.ACCEPT,
            result_timeout=s.result_timeout)
        if s.preflight:
            self._preflight()
        else:
            self.get_logger().warning("pre-flight off (preflight: false): robot state, robot "
                                      "mode and collision thresholds not checked")

    def _preflight(self) -> None:
        """The robot's pre-flight (module doc; ``ros.preflight.robot_preflight``): the first
        problem raised as DeviceError (state silent), DeviceNotReady (state slow, not in move
        mode) or InputError (another graph, collision thresholds, no robot_mode message)."""
        probe = Probe(self.context, f"{self.get_name()}_preflight", sim_time=self.dclock.sim)
        try:
            robot_preflight(probe, self.profile, self.scene.press, self.settings,
                            self._graph_topics(), self.get_logger())
        finally:
            probe.close()

    def _setup_diagnostics(self) -> None:
        """/diagnostics: the arm (robot mode by name, state rate and age, last press) and the
        camera link this node's presses need (images arriving on ``diag_camera_topic``). Until
        the first robot state and the first image, each is in its start-up state (WARN, ERROR
        only after ``diag_startup_s``)."""
        from rclpy.qos import qos_profile_sensor_data
        from sensor_msgs.msg import Image

        from ..diagnostics import Diagnostics, RateMeter, link_check, startup_phase
        s = self.settings
        self.state_meter, self.camera_meter = RateMeter(), RateMeter()
        self.last_press: dict = {}
        self.diag = Diagnostics(self, s.diag_period_s)
        self.arm_startup = startup_phase("robot state", s.diag_startup_s)
        self.diag.add("arm", f"{self.profile.name} ({self.profile.frame_id})", self._arm_health)
        if s.diag_camera_topic:
            # raw: only the arrival counts, the image is never deserialised here; arrivals
            # and ages on the node's clock (a simulated graph's simulated time: a starved
            # machine slows the camera and the clock alike, a stopped camera still ages)
            self.create_subscription(Image, s.diag_camera_topic,
                                     lambda _m: self.camera_meter.tick(self.dclock.read()),
                                     qos_profile_sensor_data, raw=True)
            cam_startup = startup_phase("camera image", s.diag_startup_s)
            self.diag.add("camera link", s.diag_camera_topic,
                          lambda: link_check(self.camera_meter, "camera image",
                                             s.diag_camera_warn_s, s.diag_camera_error_s,
                                             now=self.dclock.read(), phase=cam_startup,
                                             wall=time.monotonic()))

    def _arm_health(self) -> tuple[int, str, dict]:
        from ..diagnostics import ERROR, OK, WARN, grade, robot_mode_name, summary
        s, now = self.settings, self.dclock.read()
        age = None if self.pose_t < 0 else now - max(self.pose_t, 0.0)
        rate = self.state_meter.rate(now)
        mode = (self.robot_mode if self.profile.franka_state else
                getattr(self, "topic_mode", None))
        fault = checks.fault_mode(mode)
        parts = [(ERROR if fault else OK, f"robot {fault or 'not stopped'}"),
                 (grade(age, s.diag_state_warn_s,
                        min(s.diag_state_error_s, s.state_timeout_s)),
                  "no robot state" if age is None else f"robot state {age:.2f} s old"),
                 (WARN if rate < s.diag_state_rate_warn else OK,
                  f"robot state at {rate:.0f} Hz")]
        rtf = behind = None
        if self.dclock.sim:
            # a starved simulation is slower, not faulty: the state's age and rate are in
            # simulated time; the clock's own pace says the simulation is behind (WARN)
            self._rtf.tick(now)
            rtf, behind = self._rtf.factor(), self.dclock.behind_s()
            if behind > SIM_BEHIND_S or (rtf is not None and rtf < SIM_BEHIND_RTF):
                parts.append((WARN, "simulation behind: " + (
                    f"the simulated clock has not advanced for {behind:.1f} s of wall time"
                    if behind > SIM_BEHIND_S else f"real-time factor {rtf:.2f}") +
                    " (the machine cannot compute the simulation in real time)"))
        level, msg = summary(parts)
        lp = self.last_press
        values = {"robot mode": robot_mode_name(mode) if (self.profile.franka_state or
                                                           self.profile.mode_topic)
                  else f"not reported (profile {self.profile.name}: pose + wrench state)",
                  "state rate [Hz]": rate,
                  "state age [s]": age, "force now [N]": self.force,
                  "last press platform": lp.get("platform"),
                  "last press force [N]": lp.get("force_n"),
                  "last press time [s]": lp.get("duration_s"),
                  "last press attempts": lp.get("attempts"),
                  "last press at": lp.get("at"), "busy": self.busy.locked(),
                  "ticks held on stale state": self.held_ticks,
                  "wrench samples checked": self.samples_seen,
                  **{f"last press {k} [s]": round(v, 3)
                     for k, v in self.last_phases.items()},
                  "capture service": ("ready" if self.capture.service_is_ready()
                                      else "not available")}
        if rtf is not None:
            values["real-time factor"] = rtf
        if behind is not None:
            values["simulated clock still [s wall]"] = behind
        wall = time.monotonic()     # the start-up phase is in wall time (it began so)
        if age is not None and self.arm_startup.active:
            self.arm_startup.end(wall)
        return self.arm_startup.apply((level, msg, values), wall)

    def _setup_recovery(self) -> None:
        """Clients of the profile's recovery interface and re-activation services; where a
        type is missing, recovery is off and ``recovery_off`` says why."""
        rec, s = self.profile.recovery, self.settings
        self.recovery_off, self.recovery_client, self.reactivate = "", None, []
        self.prepare: list = []         # the profile's `before` calls, like `reactivate`
        if rec.kind == "none":
            self.recovery_off = f"robot profile {self.profile.name!r} has no recovery interface"
            return
        try:
            rtype = import_interface(rec.type)
            name = s.recovery_name or rec.name
            self.recovery_type = rtype
            self.recovery_client = (ActionClient(self, rtype, name) if rec.kind == "action"
                                    else self.create_client(rtype, name))
            for calls, out, where in ((rec.before, self.prepare, "recovery.before"),
                                      (rec.then, self.reactivate, "recovery.then")):
                for call in calls:
                    ctype = import_interface(call.type)
                    fill_message(ctype.Request(), call.request, f"{where} {call.service}")
                    out.append((call, ctype, self.create_client(ctype, call.service)))
        except InputError as exc:
            self.recovery_off = f"recovery off: {exc}"
            self.recovery_client, self.reactivate, self.prepare = None, [], []
            self.get_logger().warning(self.recovery_off)

    def _graph_topics(self) -> list[tuple[str, str]]:
        """(what, topic) that only this graph publishes: ``preflight.other_graph``."""
        return arm_topics(self.settings, self.profile, self.settings.press_action)

    def _newcomer_refused(self) -> bool:
        """One graph per arm after the pre-flight: discovery may show the other graph only
        later. Until this node takes its first goal it is the newcomer: if another graph is
        seen, the node ends with exit status 2 (the reason logged) and True is returned. A
        node that took a goal drives the arm; the other graph's motion node refuses."""
        if self.took_goal:
            return False
        if self.finished.is_set():
            return True            # refused already: no goal is taken on the way out
        problem = other_graph(self, self._graph_topics())
        if not problem:
            return False
        self.get_logger().error(f"refused after the pre-flight: {problem}")
        self.exit_code = 2
        self.finished.set()
        return True

    def _watch_graph(self) -> None:
        if self.took_goal:
            self._graph_timer.cancel()
            return
        self._newcomer_refused()

    def activate(self) -> None:
        self._abort.clear()
        if self.settings.preflight:
            self._graph_timer = self.create_timer(GRAPH_CHECK_S, self._watch_graph)

    def deactivate(self) -> None:
        """A running press is aborted: it retracts (targets still published) and ends; wait
        for it up to the retract deadline before the publishers go off."""
        self._abort.set()
        s = self.scene.press
        if self.busy.acquire(timeout=s.retract_deadline_s + s.capture_deadline_s + 1.0):
            self.busy.release()
        else:
            self.get_logger().error("deactivated while a press did not end in time")

    # ------------------------------------------------------------------ robot state
    def _on_pose(self, msg: PoseStamped) -> None:
        try:
            self.position = adapter.pose_to_array(msg)[0]
            self.pose_t = self.dclock.read()
            self.state_meter.tick(self.pose_t)
        except InputError as exc:
            self.get_logger().warning(f"pose ignored: {exc}")

    def _on_wrench(self, msg: WrenchStamped) -> None:
        try:
            self.force, self.force_mag = adapter.force_components(msg.wrench.force, self.sign)
            self.wrench_t = self.dclock.read()
            self._keep_sample(self.force, self.force_mag)
        except InputError as exc:
            self.get_logger().warning(f"wrench ignored: {exc}")

    def _on_state(self, msg) -> None:
        try:
            pos, fn, mag, mode = adapter.franka_state_to_array(msg, self.sign)
        except InputError as exc:
            self.get_logger().warning(f"robot state ignored: {exc}")
            return
        self.position, self.force, self.force_mag, self.robot_mode = pos, fn, mag, mode
        self.pose_t = self.wrench_t = self.dclock.read()
        self._keep_sample(fn, mag)
        self.state_meter.tick(self.pose_t)

    def _on_mode_raw(self, data: bytes) -> None:
        """A serialized full state: its robot_mode decoded at most ``mode_rate_hz`` times a
        second (a reflex is then seen within 1 / mode_rate_hz; the state stopping is seen by
        the pose and wrench deadlines anyway)."""
        now = self.dclock.read()
        self._mode_t = now
        if now < self._mode_next:
            return
        self._mode_next = now + 1.0 / self.settings.mode_rate_hz
        self.topic_mode = int(deserialize_message(data, self._mode_type).robot_mode)

    def _keep_sample(self, normal: float, magnitude: float) -> None:
        """Keep every wrench sample until the press loop's next tick checks it (at most
        ``10 x WRENCH_DEPTH``: a loop that stalls longer sees the newest of them)."""
        with self._samples_lock:
            self._samples.append((normal, magnitude))
            if len(self._samples) > 10 * WRENCH_DEPTH:
                del self._samples[0]

    def _take_samples(self) -> np.ndarray:
        """Every wrench sample since the last call, (k, 2) of (normal, magnitude) [N]."""
        with self._samples_lock:
            got, self._samples = self._samples, []
        self.samples_seen += len(got)
        return np.asarray(got, dtype=float).reshape(-1, 2)

    def _fresh(self, now: float) -> bool:
        lim = self.settings.state_timeout_s
        return (self.position is not None and now - self.pose_t <= lim and
                now - self.wrench_t <= lim)

    def _state_age(self, now: float) -> float:
        """[s] the age of the older of the newest pose and the newest wrench."""
        return now - min(self.pose_t, self.wrench_t)

    def _publish_target(self, xyz: np.ndarray) -> None:
        """Command the equilibrium ``xyz`` [m] (3,) on the profile's target topic."""
        self.target_pub.publish(adapter.target_msg(
            self.target_type, xyz, self.quat, self.get_clock().now().nanoseconds * 1e-9,
            self.scene.frame_id))

    def _robot_fault(self, now: float) -> str:
        """Why the robot cannot be commanded now ("" when it can)."""
        fault = checks.fault_mode(self.robot_mode)
        if not fault and now - getattr(self, "_mode_t", float("-inf")) <= MODE_HOLD_S:
            fault = checks.fault_mode(self.topic_mode)
        if fault:
            return f"robot {fault} (franka state robot_mode)"
        if not self._fresh(now):
            return ("robot stopped: no robot state within state_timeout_s "
                    f"({self.settings.state_timeout_s} s): reflex or controllers down")
        return ""

    # ------------------------------------------------------------------ action
    def _on_goal(self, goal) -> GoalResponse:
        if not self.active:
            self.get_logger().warning("press goal rejected: the node is not active")
            return GoalResponse.REJECT
        try:
            self.scene.platform(goal.platform_id)
        except InputError as exc:
            self.get_logger().warning(f"press goal rejected: {exc}")
            return GoalResponse.REJECT
        if self.busy.locked():
            self.get_logger().warning("press goal rejected: a press is running")
            return GoalResponse.REJECT
        if self.settings.preflight and self._newcomer_refused():
            return GoalResponse.REJECT
        why = self._serves(goal.run_id)
        if why:
            self.get_logger().error(f"press goal rejected: {why}")
            return GoalResponse.REJECT
        self.took_goal = True
        return GoalResponse.ACCEPT

    def _serves(self, run_id: str) -> str | None:
        """One graph per arm: the first run whose goal is taken (or ``run_id`` set) is served;
        a goal of another run (a second explorer on this ROS domain) is refused, the reason
        returned."""
        mine = getattr(self, "served_run", None) or self.settings.run_id
        if not mine:
            self.served_run = run_id
            if run_id:
                self.get_logger().info(f"serving the explorer of run {run_id}")
            return None
        if run_id != mine:
            return (f"this motion node serves run {mine}; a goal of run {run_id or '(none)'} "
                    "came from a second explorer on the ROS domain "
                    f"{os.environ.get('ROS_DOMAIN_ID', '0')}: give each graph its own "
                    "domain (docs/hardware.md)")
        return None

    async def _execute_async(self, goal_handle):
        return await in_thread(self, self._execute, goal_handle)

    def _camera_ready(self, goal_handle) -> str:
        """Wait (up to ``capture_wait_s``) for the camera's capture service before the arm
        moves: a press without a camera is a full press for nothing. Feedback (phase
        ``waiting for the camera``) goes out meanwhile, so the explorer knows the press server
        is alive. '' when the service is there, else the refusal."""
        s = self.settings
        if self.capture.service_is_ready():
            return ""
        self.get_logger().info(f"waiting for the capture service {s.capture_service!r} "
                               f"(up to capture_wait_s, {s.capture_wait_s:g} s) before "
                               "pressing")
        end = self.dclock.now() + s.capture_wait_s
        fb = self._Press.Feedback(phase="waiting for the camera")
        while self.dclock.now() < end:
            goal_handle.publish_feedback(fb)
            if self.capture.wait_for_service(timeout_sec=0.2):
                return ""
            if self._abort.is_set() or goal_handle.is_cancel_requested:
                return "the wait for the camera was cut short (deactivated or canceled)"
        return (f"capture service {s.capture_service!r} not available within capture_wait_s "
                f"({s.capture_wait_s:g} s): is the camera node running? (not pressed)")

    def _execute(self, goal_handle):
        Press = self._Press
        with self.busy:
            platform = self.scene.platform(goal_handle.request.platform_id)
            index = [p.id for p in self.scene.ordered].index(platform.id)
            result = Press.Result()
            reasons = []
            refusal = self._camera_ready(goal_handle)
            if refusal:
                result.success, result.reason, result.attempts = False, refusal, 0
                self.get_logger().error(f"press on {platform.id} refused: {refusal}")
                goal_handle.abort()
                return result
            t_press = self.dclock.now()
            for attempt in range(1, self.scene.press.retries + 2):
                result.attempts = attempt
                try:
                    ok, reason, touch = self._press_once(goal_handle, platform, index, attempt)
                except RobotError as exc:
                    reasons.append(f"attempt {attempt}: {exc}")
                    self.get_logger().error(f"press on {platform.id}: {exc}")
                    if self._state_resumes():
                        self.get_logger().warning("robot state resumed without recovery (a "
                                                  "gap, not a reflex); pressing again")
                        continue
                    recovered, why = self._recover(platform)
                    if not recovered:
                        reasons.append(f"not retried: {why}")
                        break
                    self.get_logger().info("robot recovered; pressing again")
                    continue
                if ok:
                    # on success the reason lists the attempts that failed before ('' none)
                    result.success, result.reason, result.touch = True, "; ".join(reasons), \
                        touch
                    self.last_press = {"platform": platform.id,
                                       "force_n": float(touch.contact_force_n),
                                       "duration_s": self.dclock.now() - t_press,
                                       "attempts": attempt,
                                       "at": time.strftime("%H:%M:%S")}
                    goal_handle.succeed()
                    return result
                reasons.append(f"attempt {attempt}: {reason}")
                self.get_logger().warning(f"press on {platform.id} failed: {reason}")
                if goal_handle.is_cancel_requested or self._abort.is_set():
                    break
            result.success, result.reason = False, "; ".join(reasons)
            if goal_handle.is_cancel_requested:
                goal_handle.canceled()
            else:
                goal_handle.abort()
            return result

    def _press_once(self, goal_handle, platform, index: int, attempt: int):
        """One press; (ok, reason, touch). Raises RobotError when the robot stops."""
        from tactex.action import Press
        from tactex.msg import Touch
        s = self.settings
        period = 1.0 / s.rate_hz
        t0 = self.dclock.now()
        while self._robot_fault(self.dclock.now()):
            if self.dclock.now() - t0 > s.state_timeout_s:
                raise RobotError(self._robot_fault(self.dclock.now()))
            time.sleep(period)
        ctrl = PressController(self.scene, platform, self.position, self.dclock.now(),
                               stiffness=self.k, period_s=period, hold_s=s.state_hold_s,
                               surface_hint=self.found.get(platform.id))
        self._take_samples()    # a sample from before the press is not the press's
        cap, pose_xyz, fb, burst = None, None, Press.Feedback(), None
        fb_next = float("-inf")     # when the next feedback is due (node clock) [s]
        try:
            while not ctrl.done:
                now = self.dclock.now()
                fault = self._robot_fault(now)
                if fault:   # nothing more to command: the robot does not follow
                    raise RobotError(f"{fault} (during {ctrl.phase})")
                if goal_handle.is_cancel_requested:
                    ctrl.abort("canceled", now)
                elif self._abort.is_set():
                    ctrl.abort("the motion node was deactivated", now)
                # every tick, the capture's too: the force limit holds at every sample; on
                # stale state the target stays where it is until state returns (or the fault)
                self._publish_target(ctrl.step(now, self.position, self.force, self.force_mag,
                                               state_age_s=self._state_age(now),
                                               samples=self._take_samples()))
                if ctrl.held:
                    self.held_ticks += 1
                    time.sleep(period)
                    continue
                if ctrl.capture_requested:
                    if burst is None:
                        burst = Burst(self.capture, ctrl.s.capture_window_s,
                                      ctrl.s.capture_frames, ctrl.s.capture_deadline_s,
                                      self.settings.min_contact_score, now)
                    got = burst.poll(self.dclock.now())
                    if got is not None:
                        ok, reason, cap = got
                        if ok and burst.short:
                            self.get_logger().warning(
                                f"burst of {burst.short} in-contact frames, not "
                                f"press.capture_frames {ctrl.s.capture_frames}, within "
                                f"capture_deadline_s ({ctrl.s.capture_deadline_s} s): kept")
                        burst, pose_xyz = None, self.position.copy()
                        ctrl.captured(ok, reason, self.dclock.now())
                elif burst is not None:     # the press ended the capture (limit, deadline)
                    burst.cancel()
                    burst = None
                if ctrl.phase != fb.phase or now >= fb_next:
                    fb.phase, fb.force_n, fb.attempt = ctrl.phase, ctrl.force_n, attempt
                    fb.depth_m = float(max(0.0, platform.position[2] - self.position[2]))
                    goal_handle.publish_feedback(fb)
                    fb_next = now + FEEDBACK_PERIOD_S
                time.sleep(period)
        finally:
            if burst is not None:
                burst.cancel()
        out = ctrl.outcome()
        self.last_phases = {"press_s": out.press_s, **out.phase_s}
        if not out.success:
            return False, out.reason, None
        if out.surface_z is not None:
            self.found[platform.id] = out.surface_z   # the next press of it starts lower
        touch = Touch(header=cap.image.header, platform_id=platform.id, platform_index=index,
                      image=cap.image, contact_force_n=out.force_n, depth_m=out.depth_m,
                      attempt=attempt, no_contact_image=cap.no_contact,
                      tare_offset_n=out.tare.offset_n, tare_spread_n=out.tare.spread_n,
                      tare_samples=out.tare.samples, surface_z=out.surface_z,
                      surface_error_m=out.surface_z - platform.position[2],
                      warning=out.warning, extra_images=list(cap.extra_images),
                      press_s=float(out.press_s), phase_names=list(out.phase_s),
                      phase_s=[float(v) for v in out.phase_s.values()])
        if out.warning:
            self.get_logger().warning(out.warning)
        touch.pose = adapter.array_to_pose(pose_xyz, self.quat, 0.0, "").pose
        return True, "", touch

    def _state_resumes(self) -> bool:
        """After a robot error: does fresh state (not in reflex) come back by itself within
        state_timeout_s? A stopped robot (reflex, controllers down) stays silent until
        recovered; a loaded machine only delays messages."""
        end = self.dclock.now() + self.settings.state_timeout_s
        while self.dclock.now() < end:
            if not self._robot_fault(self.dclock.now()):
                return True
            time.sleep(0.02)
        return False

    def _wait(self, fut, deadline_s: float, what: str):
        """Wait for a future from this worker thread; its result, or TrialError at the
        deadline."""
        if not wait_for(fut, deadline_s):
            fut.cancel()
            raise TrialError(f"{what}: no answer within recovery_timeout_s "
                              f"({deadline_s} s)")
        return fut.result()

    def _recover(self, platform) -> tuple[bool, str]:
        """The profile's recovery after a robot error on ``platform``: the hold target (where
        the profile asks for it), the ``before`` calls in order, the error recovery action (its
        result) or service (its ``ok_field``), then the re-activation calls in order, then
        fresh state. (recovered, reason if not)."""
        if self.recovery_client is None:
            return False, self.recovery_off
        rec, lim = self.profile.recovery, self.settings.recovery_timeout_s
        name = self.settings.recovery_name or rec.name
        try:
            if rec.hold_target and self.position is not None:
                self._publish_hold(platform)
            for call, ctype, client in self.prepare:
                self._call(client, fill_message(ctype.Request(), call.request), call.ok_field,
                           call.service, lim)
            if rec.kind == "action":
                if not self.recovery_client.wait_for_server(timeout_sec=lim):
                    raise TrialError(f"error recovery action {name} not available")
                handle = self._wait(self.recovery_client.send_goal_async(
                    self.recovery_type.Goal()), lim, f"error recovery {name} (goal)")
                if not handle.accepted:
                    raise TrialError(f"error recovery {name}: goal rejected")
                res = self._wait(handle.get_result_async(), lim, f"error recovery {name}")
                if res.status != GoalStatus.STATUS_SUCCEEDED:
                    raise TrialError(f"error recovery {name} ended with status {res.status}")
            else:
                self._call(self.recovery_client, self.recovery_type.Request(), rec.ok_field,
                           name, lim)
            for call, ctype, client in self.reactivate:
                self._call(client, fill_message(ctype.Request(), call.request), call.ok_field,
                           call.service, lim)
            end = self.dclock.now() + lim
            while self._robot_fault(self.dclock.now()):
                if self.dclock.now() > end:
                    raise TrialError("no fresh robot state after recovery within "
                                      f"recovery_timeout_s ({lim} s)")
                time.sleep(0.02)
        except TrialError as exc:
            self.get_logger().error(f"recovery failed: {exc}")
            return False, f"recovery failed: {exc}"
        return True, ""

    def _publish_hold(self, platform) -> None:
        """Publish the hold target (``robots.hold_target``: the measured position, not below
        the platform's surface) for a controller that stays active through the recovery and
        resumes its last target when the control loop restarts."""
        sc = self.scene
        xyz = np.array(hold_target(self.position, platform.position[2], sc.workspace_min,
                                   sc.workspace_max))
        self._publish_target(xyz)
        self.get_logger().info(f"recovery: hold target {np.round(xyz, 4).tolist()} m published")

    def _call(self, client, request, ok_field: str, name: str, deadline_s: float) -> None:
        if not client.wait_for_service(timeout_sec=deadline_s):
            raise TrialError(f"service {name} not available")
        resp = self._wait(client.call_async(request), deadline_s, f"service {name}")
        if not getattr(resp, ok_field, False):
            detail = getattr(resp, "message", "") or getattr(resp, "error", "")
            raise TrialError(f"service {name} answered {ok_field} = false"
                              + (f" ({detail})" if detail else ""))


def main(args: list[str] | None = None) -> int:
    return run(MotionNode, args)


if __name__ == "__main__":
    raise SystemExit(main())
