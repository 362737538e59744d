"""The simulated graph (mock arm, mock image, motion, explorer) as real processes over DDS."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from geometry_msgs.msg import PoseStamped
from rclpy.qos import qos_profile_sensor_data
from visualization_msgs.msg import MarkerArray

from tactex_ros.ros.graph import describe
from tactex_ros.ros.settings import POSE_TOPIC
from tactex_ros.trial.record import read_record
from tactex_ros.ros.devrun.launcher import run_graph
from tactex_ros.robot.scene import load_scene

pytestmark = pytest.mark.ros


def test_short_trial_on_easy_scene(tmp_path: Path, listener, force_trace) -> None:
    from tactex.msg import ExplorationState
    nodes = describe(True, explorer={"trial": {"rounds": 2, "stop_confidence": 0.0}, "seed": 0,
                                     "record_dir": str(tmp_path),
                                     "trial_id": "t1"})
    scene = load_scene(nodes[0].parameters["scene_file"])
    states = listener.collect(ExplorationState, "/tactex/state")
    marks = listener.collect(MarkerArray, "/tactex/markers")
    poses = listener.collect(PoseStamped, POSE_TOPIC, qos_profile_sensor_data)

    run = run_graph(nodes, tmp_path / "logs", timeout_s=240, domain_id=listener.domain_id)

    assert not run.timed_out and run.exit_code == 0, (tmp_path / "logs" / "explorer.log")
    res = run.result
    truth = next(p.id for p in scene.comparisons if p.sim_fabric == scene.reference.sim_fabric)
    assert res["prediction"] == truth and res["stop_reason"] == "rounds"
    # decisions: 2 that ask for a touch + the final one, all published
    assert [s.round for s in states] == [1, 2, 3] and states[-1].done
    assert states[-1].prediction == truth
    assert all(abs(sum(s.belief) - 1.0) < 1e-3 for s in states)
    assert len(marks) > 0 and len(marks[-1].markers) >= 2 * len(scene.platforms)
    # the 1 Hz marker timer keeps firing while the worker thread trains: the node stays live
    stamps = sorted(m.markers[0].header.stamp.sec + 1e-9 * m.markers[0].header.stamp.nanosec
                    for m in marks)
    assert np.diff(stamps).max() < 3.0
    # safety: force and workspace, over everything the mock arm reported
    assert len(poses) > 100 and len(force_trace.forces()) > 100
    xyz = np.array([[p.pose.position.x, p.pose.position.y, p.pose.position.z] for p in poses])
    assert np.all(xyz >= np.array(scene.workspace_min) - 1e-6)
    assert np.all(xyz <= np.array(scene.workspace_max) + 1e-6)
    force_trace.check(scene.press.max_force, label="the trial")
    # the record holds every touch, image and metadata, and the result
    rec = read_record(run.record)
    accepted = [t for t in rec["touches"] if t["accepted"]]
    # every requested touch is on disk; a touch that failed under load is recorded with its
    # reason, the trial went on and the 2 rounds still requested their touches
    assert len(accepted) == res["touches"] >= 5 + 1
    assert len(rec["touches"]) == res["touches"] + len(res["failed_touches"]) >= 5 + 2
    assert all(t["array"].shape == (240, 320, 3) for t in accepted)
    # the impedance press holds the force measured at the threshold (dynamics: a few %)
    assert all(t["force_n"] >= 0.9 * scene.press.force_threshold for t in accepted)
    # the surface found is in the record: the mock's surfaces are where the scene says
    assert all(abs(t["surface"]["error_m"]) < 0.001 and not t["surface"]["warning"]
               for t in accepted)
    assert rec["result"]["prediction"] == truth
    assert len(rec["decisions"]) == 3
    assert json.loads((run.record / "config.json").read_text())["trial"]["rounds"] == 2
    # the MCAP beside it carries standard messages any viewer shows: one sensor_msgs/Image
    # per accepted touch (pixels of its PNG, the camera's frame), its press force and the
    # belief per decision; read with mcap's ROS 2 decoder, no ROS needed
    from mcap_ros2.reader import read_ros2_messages
    from tactex_ros.ros.bag import BELIEF_VIEW, TOUCH_IMAGE_VIEW, WRENCH_VIEW
    msgs = list(read_ros2_messages(str(run.record / "topics.mcap")))
    images = [m.ros_msg for m in msgs if m.channel.topic == TOUCH_IMAGE_VIEW]
    assert {m.schema.name for m in msgs if m.channel.topic == TOUCH_IMAGE_VIEW} == \
        {"sensor_msgs/msg/Image"}
    assert len(images) == len(accepted)
    for im, t in zip(images, accepted, strict=True):
        assert (im.encoding, im.height, im.width) == ("rgb8", 240, 320)
        assert im.header.frame_id == "gelsight_optical_frame"
        assert np.array_equal(np.frombuffer(bytes(im.data), np.uint8).reshape(240, 320, 3),
                              t["array"])
    forces = [m.ros_msg.wrench.force.z for m in msgs if m.channel.topic == WRENCH_VIEW]
    assert forces == pytest.approx([t["force_n"] for t in accepted])
    belief = [m.ros_msg.data for m in msgs if m.channel.topic == BELIEF_VIEW + truth]
    assert belief == pytest.approx([s.belief[int(truth[1:]) - 1] for s in states], abs=1e-6)


def test_press_faults(tmp_path: Path, listener, press) -> None:
    """Unknown platform: goal rejected. Platforms lower than the scene says: no contact, the
    press is retried, then reported failed; the arm stays in the workspace meanwhile."""
    from tactex_ros.ros.devrun.launcher import Graph
    nodes = [n for n in describe(True, mock_arm={"surface_offset": -0.03})
             if n.name in ("mock_arm", "mock_image", "motion")]
    scene = load_scene(nodes[0].parameters["scene_file"])
    poses = listener.collect(PoseStamped, POSE_TOPIC, qos_profile_sensor_data)
    with Graph(nodes, tmp_path / "logs", listener.domain_id):
        assert press("no_such_platform") is None
        res = press("c1")
        assert res is not None and not res.success
        assert res.attempts == scene.press.retries + 1
        assert res.reason.count("attempt") == scene.press.retries + 1
    xyz = np.array([[p.pose.position.x, p.pose.position.y, p.pose.position.z] for p in poses])
    assert len(xyz) > 50
    assert np.all(xyz >= np.array(scene.workspace_min) - 1e-6)
    # never below the deepest equilibrium of a press (the floor below the scene's surface at
    # the profile's stiffness), up to 1 mm of the impedance controller's overshoot
    from tactex_ros.robot.press import equilibrium_floor
    from tactex_ros.robot.robots import load_profile
    floor = equilibrium_floor(scene.press, load_profile("sim").stiffness)
    assert xyz[:, 2].min() >= scene.platform("c1").position[2] - floor - 0.001


def test_blank_presses_retried_and_trial_goes_on(tmp_path: Path, listener,
                                                  small_scene: str) -> None:
    """The mock camera shows no texture on some presses: the motion node sees no contact in the
    captured frames and retries the press; nothing blank reaches the learner; the trial ends."""
    nodes = describe(True, small_scene,
                     explorer={"trial": {"rounds": 1, "stop_confidence": 0.0}, "seed": 0,
                               "record_dir": str(tmp_path), "trial_id": "blank"},
                     mock_image={"fault_blank": 0.2, "seed": 3})
    run = run_graph(nodes, tmp_path / "logs", timeout_s=240, domain_id=listener.domain_id)
    assert not run.timed_out and run.exit_code == 0
    rec = read_record(run.record)
    accepted = [t for t in rec["touches"] if t["accepted"]]
    assert max(t["attempts"] for t in accepted) >= 2      # a blank press was retried
    assert len(accepted) == run.result["touches"]
    assert len(rec["touches"]) == run.result["touches"] + len(run.result["failed_touches"])
    assert run.result["prediction"] in {"c1", "c2"}


def test_guard_rejected_touch_is_pressed_again(tmp_path: Path, listener,
                                               small_scene: str) -> None:
    """The motion node lets blank captures through (min_contact_score 0): the core's contact
    guard refuses them in the explorer, which presses the same platform again at once; the
    rejected image stays on disk, marked, and the round is not lost."""
    nodes = describe(True, small_scene,
                     explorer={"trial": {"rounds": 1, "stop_confidence": 0.0}, "seed": 0,
                               "record_dir": str(tmp_path), "trial_id": "guard"},
                     mock_image={"fault_blank": 0.3, "seed": 3},
                     motion={"min_contact_score": 0.0})
    run = run_graph(nodes, tmp_path / "logs", timeout_s=240, domain_id=listener.domain_id)
    assert not run.timed_out and run.exit_code == 0
    rec = read_record(run.record)
    touches = rec["touches"]
    rejected = [i for i, t in enumerate(touches) if not t["accepted"]]
    assert rejected, "no blank press reached the explorer's guard"
    for i in rejected:
        assert touches[i].get("array") is not None               # kept on disk
        assert i + 1 < len(touches)
        assert touches[i + 1]["platform_id"] == touches[i]["platform_id"]   # pressed again
    accepted = [t for t in touches if t["accepted"]]
    assert run.result["touches"] == len(accepted) == 3 + 1     # baseline 3, 1 round: none lost
