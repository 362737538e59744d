"""motion_node: presses the GelSight on a platform through franka_ros2's interfaces.

Serves the ``tactex/action/Press`` action (goal: platform id from the scene). Sends Cartesian
targets (PoseStamped on ``target_topic``, e.g. the impedance controller's equilibrium pose),
reads the current pose and the external wrench (``pose_topic``, ``wrench_topic``; best-effort
QoS) and runs the press sequence of ``core.press.PressController``: approach, descend until the
force threshold or the maximum depth, settle, capture (GelSight capture service), retract.
Always enforced: workspace box, maximum force, maximum speed, a deadline for every phase.
A failed attempt (no contact, no image, force limit, stale robot state) is retried up to
``press.retries`` times; after a force-limit abort franka's ErrorRecovery action is called when
franka_msgs is installed. The result says why a press failed.
"""

from __future__ import annotations

import threading
import time

import numpy as np
from geometry_msgs.msg import PoseStamped, WrenchStamped
from rclpy.action import ActionServer, CancelResponse, GoalResponse
from rclpy.qos import qos_profile_sensor_data

from .. import adapter
from ..core.errors import TactexError
from ..core.press import PressController
from ..node_settings import PRESS_ACTION, MotionSettings
from ..scene import load_scene
from .common import TactexNode, in_thread, run

try:  # franka_ros2's error recovery, only on robot machines
    from franka_msgs.action import ErrorRecovery  # type: ignore
except ImportError:  # pragma: no cover - depends on the system
    ErrorRecovery = None


class MotionNode(TactexNode):
    settings_cls = MotionSettings

    def __init__(self) -> None:
        super().__init__("motion")

    def configure(self) -> None:
        from tactex.action import Press
        from tactex.srv import Capture
        s = self.settings
        self.scene = load_scene(s.scene_file)
        self.quat = np.array(self.scene.tool_orientation)
        self.position: np.ndarray | None = None
        self.pose_t = -1.0
        self.force = 0.0
        self.wrench_t = -1.0
        self.busy = threading.Lock()
        self.create_subscription(PoseStamped, s.pose_topic, self._on_pose,
                                 qos_profile_sensor_data)
        self.create_subscription(WrenchStamped, s.wrench_topic, self._on_wrench,
                                 qos_profile_sensor_data)
        self.target_pub = self.create_publisher(PoseStamped, s.target_topic, 10)
        self.capture = self.create_client(Capture, s.capture_service)
        self.recovery = (_recovery_client(self, s.recovery_action)
                         if ErrorRecovery is not None else None)
        self._Press = Press

    def activate(self) -> None:
        self.server = ActionServer(
            self, self._Press, PRESS_ACTION, execute_callback=self._execute_async,
            goal_callback=self._on_goal, cancel_callback=lambda _: CancelResponse.ACCEPT)

    # ------------------------------------------------------------------ robot state
    def _on_pose(self, msg: PoseStamped) -> None:
        try:
            self.position = adapter.pose_to_array(msg)[0]
            self.pose_t = time.monotonic()
        except TactexError as exc:
            self.get_logger().warning(f"pose ignored: {exc}")

    def _on_wrench(self, msg: WrenchStamped) -> None:
        try:
            self.force = adapter.normal_force(msg.wrench.force, self.settings.force_sign)
            self.wrench_t = time.monotonic()
        except TactexError as exc:
            self.get_logger().warning(f"wrench ignored: {exc}")

    def _fresh(self, now: float) -> bool:
        lim = self.settings.state_timeout_s
        return (self.position is not None and now - self.pose_t <= lim and
                now - self.wrench_t <= lim)

    # ------------------------------------------------------------------ action
    def _on_goal(self, goal) -> GoalResponse:
        try:
            self.scene.platform(goal.platform_id)
        except TactexError as exc:
            self.get_logger().warning(f"press goal rejected: {exc}")
            return GoalResponse.REJECT
        if self.busy.locked():
            self.get_logger().warning("press goal rejected: a press is running")
            return GoalResponse.REJECT
        return GoalResponse.ACCEPT

    async def _execute_async(self, goal_handle):
        return await in_thread(self, self._execute, goal_handle)

    def _execute(self, goal_handle):
        Press = self._Press
        with self.busy:
            platform = self.scene.platform(goal_handle.request.platform_id)
            index = [p.id for p in self.scene.ordered].index(platform.id)
            result = Press.Result()
            reasons = []
            for attempt in range(1, self.scene.press.retries + 2):
                ok, reason, touch = self._press_once(goal_handle, platform, index, attempt)
                result.attempts = attempt
                if ok:
                    result.success, result.reason, result.touch = True, "", touch
                    goal_handle.succeed()
                    return result
                reasons.append(f"attempt {attempt}: {reason}")
                self.get_logger().warning(f"press on {platform.id} failed: {reason}")
                if reason.startswith("force limit"):
                    self._recover()
                if goal_handle.is_cancel_requested:
                    break
            result.success, result.reason = False, "; ".join(reasons)
            if goal_handle.is_cancel_requested:
                goal_handle.canceled()
            else:
                goal_handle.abort()
            return result

    def _press_once(self, goal_handle, platform, index: int, attempt: int):
        from tactex.action import Press
        from tactex.msg import Touch
        s = self.settings
        period = 1.0 / s.rate_hz
        t0 = time.monotonic()
        while not self._fresh(time.monotonic()):
            if time.monotonic() - t0 > s.state_timeout_s:
                return False, "no robot state (pose/wrench) within state_timeout_s", None
            time.sleep(period)
        ctrl = PressController(self.scene, platform, self.position, time.monotonic())
        cap, pose_xyz, fb = None, None, Press.Feedback()
        while not ctrl.done:
            now = time.monotonic()
            if not self._fresh(now):
                ctrl._abort("robot state stale (no pose/wrench within state_timeout_s)", now)
            if goal_handle.is_cancel_requested:
                ctrl._abort("canceled", now)
            target = ctrl.step(now, self.position, self.force)
            self.target_pub.publish(adapter.array_to_pose(
                target, self.quat, self.get_clock().now().nanoseconds * 1e-9,
                self.scene.frame_id))
            if ctrl.capture_requested:
                ok, reason, cap = self._capture(ctrl.s.capture_window_s,
                                                  ctrl.s.capture_deadline_s)
                pose_xyz = self.position.copy()
                ctrl.captured(ok, reason, time.monotonic())
            fb.phase, fb.force_n, fb.attempt = ctrl.phase, float(self.force), attempt
            fb.depth_m = float(max(0.0, platform.position[2] - self.position[2]))
            goal_handle.publish_feedback(fb)
            time.sleep(period)
        out = ctrl.outcome()
        if not out.success:
            return False, out.reason, None
        touch = Touch(header=cap.image.header, platform_id=platform.id, platform_index=index,
                      image=cap.image, contact_force_n=out.force_n, depth_m=out.depth_m,
                      attempt=attempt, no_contact_image=cap.no_contact)
        touch.pose = adapter.array_to_pose(pose_xyz, self.quat, 0.0, "").pose
        return True, "", touch

    def _capture(self, window_s: float, deadline_s: float):
        from tactex.srv import Capture
        if not self.capture.wait_for_service(timeout_sec=deadline_s):
            return False, "capture service not available", None
        fut = self.capture.call_async(Capture.Request(window_s=window_s))
        end = time.monotonic() + deadline_s
        while not fut.done():
            if time.monotonic() > end:
                fut.cancel()
                return False, f"no image within capture_deadline_s ({deadline_s} s)", None
            time.sleep(0.005)
        resp = fut.result()
        if not resp.success:
            return False, resp.reason, None
        if resp.contact_score < self.settings.min_contact_score:
            return False, (f"no contact in the captured frames: score {resp.contact_score:.2f} < "
                           f"min_contact_score {self.settings.min_contact_score}"), None
        return True, "", resp

    def _recover(self) -> None:
        """franka error recovery when franka_msgs is installed (reflex after a force abort)."""
        if self.recovery is None:
            return
        if not self.recovery.wait_for_server(timeout_sec=2.0):
            self.get_logger().error("error recovery action not available")
            return
        fut = self.recovery.send_goal_async(ErrorRecovery.Goal())
        end = time.monotonic() + 10.0
        while not fut.done() and time.monotonic() < end:
            time.sleep(0.01)


def _recovery_client(node, name: str):
    from rclpy.action import ActionClient
    return ActionClient(node, ErrorRecovery, name)


def main(args: list[str] | None = None) -> int:
    return run(MotionNode, args)


if __name__ == "__main__":
    raise SystemExit(main())
