"""Issue 49, item 3: the mock camera's frame loop never dies silently. A press file damaged
after the node opened its replay folder (the folder is judged whole at configure:
test/unit/sources/test_replay_files.py) fails the loop at the press that draws it; the node
then ends with exit status 1 and the file named on its log (an ``[ERROR]`` line, the one
``tactex graph run`` prints), instead of staying up without frames while every press fails."""

from __future__ import annotations

import time
from pathlib import Path

import cv2
import numpy as np
import pytest
import yaml

from tactex_ros.core.paths import config_dir
from tactex_ros.ros.graph import NodeSpec
from tactex_ros.ros.devrun.launcher import Graph
from tactex_ros.ros.settings import POSE_TOPIC, WRENCH_TOPIC

pytestmark = [pytest.mark.ros]


def _replay_scene(tmp: Path) -> tuple[Path, Path]:
    """A replay folder (two image presses per class) and config/scene_sim.yaml with a class
    on every platform."""
    rng = np.random.default_rng(0)
    scene = yaml.safe_load((config_dir() / "scene_sim.yaml").read_text())
    for k, p in enumerate(scene["platforms"]):
        p.pop("sim_fabric", None)
        p["replay_class"] = f"class{k}"
        (tmp / "lib" / f"class{k}").mkdir(parents=True)
        for i in range(2):
            cv2.imwrite(str(tmp / "lib" / f"class{k}" / f"{i}.png"),
                        rng.integers(0, 255, (240, 320, 3), dtype=np.uint8))
    out = tmp / "scene.yaml"
    out.write_text(yaml.safe_dump(scene))
    return out, tmp / "lib"


def test_a_press_file_damaged_while_running_ends_the_camera_named(tmp_path: Path, listener,
                                                                   active) -> None:
    from geometry_msgs.msg import PoseStamped, WrenchStamped
    from rclpy.qos import qos_profile_sensor_data
    scene_file, lib = _replay_scene(tmp_path)
    ref = yaml.safe_load(scene_file.read_text())["platforms"][0]
    node = NodeSpec("mock_image_node", "mock_image",
                    {"scene_file": str(scene_file), "source": f"replay:{lib}"})
    pose_pub = listener.node.create_publisher(PoseStamped, POSE_TOPIC, qos_profile_sensor_data)
    wrench_pub = listener.node.create_publisher(WrenchStamped, WRENCH_TOPIC,
                                                qos_profile_sensor_data)

    def send(z_above_m: float, force_n: float) -> None:
        pose = PoseStamped()
        pose.header.frame_id = "fr3_link0"
        x, y, z = ref["position"]
        pose.pose.position.x, pose.pose.position.y = float(x), float(y)
        pose.pose.position.z = float(z) + z_above_m
        pose.pose.orientation.w = 1.0
        w = WrenchStamped()
        w.wrench.force.z = force_n
        pose_pub.publish(pose)
        wrench_pub.publish(w)

    with Graph([node], tmp_path / "logs", listener.domain_id) as g:
        assert active("mock_image", 90.0), (tmp_path / "logs" / "mock_image.log").read_text()
        damaged = sorted((lib / "class0").iterdir())
        for f in damaged:          # the one the node read at configure stays in its cache
            f.write_bytes(b"")
        code = None
        end = time.monotonic() + 60.0
        while code is None and time.monotonic() < end:
            for z, f in ((-0.001, 5.0), (0.01, 0.0)):      # a press, then clear of the surface
                t_phase = time.monotonic() + 1.0
                while time.monotonic() < t_phase:
                    send(z, f)
                    time.sleep(0.02)
            code = g.wait("mock_image", 0.1)
    log = (tmp_path / "logs" / "mock_image.log").read_text(errors="replace")
    assert code == 1, log[-3000:]
    error = next(ln for ln in log.splitlines() if "[ERROR]" in ln)
    assert "frames loop failed" in error and any(str(f) in error for f in damaged), error
