"""mock_arm_node: stands in for the Panda and franka_ros2 at their topics.

Publishes the current pose (PoseStamped) and the external wrench in the base frame
(WrenchStamped) at ``rate_hz`` on franka_robot_state_broadcaster's topic names; reads target
poses (the impedance controller's equilibrium pose). The pose follows the target with a speed
limit; the wrench's z force rises with penetration below a platform's surface (``stiffness``).
The physics lives in ``core.press.ArmModel``.
"""

from __future__ import annotations

import numpy as np
from geometry_msgs.msg import PoseStamped, Vector3, WrenchStamped
from rclpy.qos import qos_profile_sensor_data
from std_msgs.msg import Header

from .. import adapter
from ..core.errors import TactexError
from ..core.press import ArmModel
from ..node_settings import MockArmSettings
from ..scene import load_scene
from .common import TactexNode, run


class MockArmNode(TactexNode):
    settings_cls = MockArmSettings

    def __init__(self) -> None:
        super().__init__("mock_arm")

    def configure(self) -> None:
        s = self.settings
        scene = load_scene(s.scene_file)
        if s.surface_offset:
            from dataclasses import replace
            scene = replace(scene, platforms=tuple(
                replace(p, position=(p.position[0], p.position[1],
                                     p.position[2] + s.surface_offset))
                for p in scene.platforms))
        self.scene = scene
        self.arm = ArmModel(scene, np.array([s.start_x, s.start_y, s.start_z]),
                            stiffness=s.stiffness, max_speed=s.max_speed)
        self.quat = np.array(scene.tool_orientation)
        self.pose_pub = self.create_publisher(PoseStamped, s.pose_topic, qos_profile_sensor_data)
        self.wrench_pub = self.create_publisher(WrenchStamped, s.wrench_topic,
                                                qos_profile_sensor_data)
        self.create_subscription(PoseStamped, s.target_topic, self._on_target, 10)

    def activate(self) -> None:
        self._last = self.get_clock().now().nanoseconds * 1e-9
        self.create_timer(1.0 / self.settings.rate_hz, self._tick)

    def _on_target(self, msg: PoseStamped) -> None:
        try:
            xyz, _ = adapter.pose_to_array(msg)
        except TactexError as exc:
            self.get_logger().warning(f"target ignored: {exc}")
            return
        self.arm.target = xyz

    def _tick(self) -> None:
        now = self.get_clock().now().nanoseconds * 1e-9
        self.arm.step(min(0.1, now - self._last))
        self._last = now
        self.pose_pub.publish(adapter.array_to_pose(self.arm.position, self.quat, now,
                                                    self.scene.frame_id))
        w = WrenchStamped(header=Header(stamp=adapter.stamp(now), frame_id=self.scene.frame_id))
        w.wrench.force = Vector3(x=0.0, y=0.0, z=float(self.arm.normal_force()))
        self.wrench_pub.publish(w)


def main(args: list[str] | None = None) -> int:
    return run(MockArmNode, args)


if __name__ == "__main__":
    raise SystemExit(main())
