"""ros2 launch tactex explore.launch.py [sim:=true] [rviz:=true] [robot:=fr3_jazzy|panda_multipanda|
sim|FILE] [motion_params:=FILE] [scene:=FILE] [strategy:=S] [model:=M] [rounds:=N] [seed:=N]
[sensor:=gelsight_mini|digit|FILE] [device:=/dev/videoN|'GelSight Mini'|SERIAL|DIR]
[source:=sim|replay:DIR] [bag:=true] [exit_when_done:=true]

Hardware graph: gelsight_node, motion_node, explorer_node; the robot profile (``robot``,
config/robots/) names the impedance controller, topics, message types and recovery interface of
the robot stack, which must already run. ``sim:=true``: mock_arm_node and mock_image_node replace
robot and camera at the same topics, and a static transform world -> base frame gives rviz its
fixed frame. The nodes and their parameters come from ``tactex_ros.graph.describe`` -- the same
description the ``tactex graph run`` runner uses -- and are all validated before anything starts:
a bad value ends the launch with the argument or field named and no process started.

Any tactex node that exits ends the launch (a dead camera or robot interface stops the trial;
with ``exit_when_done:=true`` the explorer's exit after the trial ends it). rviz2 is started only
when it is installed (checked before any node starts) and its exit does not end the launch.
"""

from __future__ import annotations

from launch import LaunchDescription
from launch.actions import DeclareLaunchArgument, OpaqueFunction, Shutdown
from launch.substitutions import LaunchConfiguration
from launch_ros.actions import Node

_TRUE, _FALSE = ("true", "1", "yes", "on"), ("false", "0", "no", "off")


class LaunchArgumentError(ValueError):
    """A launch argument with a value that does not fit; the message names the argument."""


def _nodes(context, *args, **kwargs):
    from tactex_ros.core.errors import TactexError
    from tactex_ros.graph import describe, fixed_frame
    from tactex_ros.paths import config_dir

    def arg(name: str) -> str:
        return LaunchConfiguration(name).perform(context)

    def flag(name: str) -> bool:
        v = arg(name).strip().lower()
        if v not in _TRUE + _FALSE:
            raise LaunchArgumentError(f"launch argument {name}:={arg(name)!r}: expected true "
                                      "or false")
        return v in _TRUE

    def integer(name: str) -> int:
        try:
            return int(arg(name))
        except ValueError:
            raise LaunchArgumentError(f"launch argument {name}:={arg(name)!r}: expected an "
                                      "integer") from None

    sim, rviz = flag("sim"), flag("rviz")
    explorer = {"strategy": arg("strategy"), "rounds": integer("rounds"),
                "seed": integer("seed")}
    for name in ("model", "record_dir", "trial_id"):
        if arg(name):
            explorer[name] = arg(name)
    if flag("exit_when_done"):
        explorer["exit_when_done"] = True
    try:
        nodes = describe(sim, arg("scene") or None, explorer=explorer,
                         gelsight={"device": arg("device"), "sensor": arg("sensor")}
                         if not sim else None,
                         mock_image={"source": arg("source")} if sim and arg("source") else None,
                         robot=arg("robot") or None, motion_file=arg("motion_params") or None)
        frame = fixed_frame(nodes)
        from tactex_ros.robot import load_profile
        motion = next(n for n in nodes if n.name == "motion")
        profile = load_profile(motion.parameters["robot"])
        pose_topic = motion.parameters.get("pose_topic") or profile.pose_topic
    except TactexError as exc:
        raise LaunchArgumentError(str(exc)) from None
    bag = flag("bag")
    if bag and not _installed("rosbag2_storage_mcap"):
        raise LaunchArgumentError("launch argument bag:=true: rosbag2 with MCAP storage is not "
                                  "installed (apt install ros-$ROS_DISTRO-rosbag2 "
                                  "ros-$ROS_DISTRO-rosbag2-storage-mcap), nothing started")
    if rviz and not _installed("rviz2"):
        # a missing rviz2 must fail here, before any node starts, not after (orphans)
        raise LaunchArgumentError("launch argument rviz:=true: rviz2 is not installed "
                                  "(apt install ros-$ROS_DISTRO-rviz2), nothing started")
    actions = [Node(package=n.package, executable=n.executable, name=n.name,
                    parameters=[n.parameters], remappings=n.remappings, output="screen",
                    sigterm_timeout="10", sigkill_timeout="5",
                    on_exit=Shutdown(reason=f"tactex node {n.name} exited"))
               for n in nodes]
    if sim and _installed("tf2_ros"):   # rviz's fixed frame exists in TF (viewer only)
        actions.append(Node(package="tf2_ros", executable="static_transform_publisher",
                            name="tactex_sim_world",
                            arguments=["--frame-id", "world", "--child-frame-id", frame]))
    elif sim:
        from launch.actions import LogInfo
        actions.append(LogInfo(msg="tf2_ros is not installed: no static transform world -> "
                                   f"{frame} for rviz"))
    if bag:   # `ros2 bag record` of the trial's topics next to the records; its exit does
        #         not end the launch (the fsync'ed record and topics.mcap stay the ground truth)
        import time
        from pathlib import Path

        from launch.actions import ExecuteProcess
        from tactex_ros.node_settings import MARKER_TOPIC, STATE_TOPIC, TOUCH_IMAGE_TOPIC
        out = Path(arg("record_dir") or "runs/trials") / time.strftime("bag_%Y%m%d_%H%M%S")
        wrench = motion.parameters.get("wrench_topic") or profile.wrench_topic
        topics = [t for t in (STATE_TOPIC, MARKER_TOPIC, TOUCH_IMAGE_TOPIC, pose_topic,
                              wrench) if t]
        actions.append(ExecuteProcess(cmd=["ros2", "bag", "record", "-s", "mcap", "-o",
                                           str(out)] + topics, output="screen",
                                      sigterm_timeout="10"))
    if rviz:
        actions.append(Node(package="rviz2", executable="rviz2", name="rviz2",
                            arguments=["-d", str(_rviz_config(config_dir() / "tactex.rviz",
                                                              frame, pose_topic))]))
    return actions


def _installed(package: str) -> bool:
    from ament_index_python.packages import PackageNotFoundError, get_package_prefix
    try:
        get_package_prefix(package)
    except PackageNotFoundError:
        return False
    return True


def _rviz_config(template, frame: str, pose_topic: str):
    """A copy of the rviz config with the robot profile's base frame as fixed frame and its
    pose topic in the Pose display (off where the profile has no PoseStamped state)."""
    import tempfile
    from pathlib import Path

    import yaml
    cfg = yaml.safe_load(Path(template).read_text())
    cfg["Visualization Manager"]["Global Options"]["Fixed Frame"] = frame
    for d in cfg["Visualization Manager"].get("Displays", []):
        if d.get("Class") == "rviz_default_plugins/Pose":
            d["Enabled"] = bool(pose_topic)
            if pose_topic:
                d["Topic"]["Value"] = pose_topic
    out = Path(tempfile.mkdtemp(prefix="tactex_rviz_")) / "tactex.rviz"
    out.write_text(yaml.safe_dump(cfg, sort_keys=False))
    return out


def generate_launch_description() -> LaunchDescription:
    args = [("sim", "false", "mock arm + mock image instead of the hardware"),
            ("rviz", "false", "start rviz2 with config/tactex.rviz (fixed frame: the robot's "
                              "base frame)"),
            ("robot", "", "robot profile: fr3_jazzy | panda_multipanda | sim | FILE "
                          "('' = fr3_jazzy, sim: sim)"),
            ("motion_params", "", "YAML of motion_node parameters (topics, stiffness, "
                                  "force_sign, recovery_name, ...) over the profile's"),
            ("scene", "", "scene YAML (default config/scene.yaml, sim: config/scene_sim.yaml)"),
            ("strategy", "", "'' (the preset's) | infogain | variance | entropy | random | "
                             "yoto | bald"),
            ("model", "", "model variant ('' = the preset's; auto escalates)"),
            ("rounds", "20", "decisions that request a touch"),
            ("seed", "0", "learner / strategy seed"),
            ("sensor", "gelsight_mini", "sensor profile: gelsight_mini | digit | FILE "
                                        "(config/sensors/)"),
            ("device", "", "camera: device path, camera name, DIGIT serial, video file or "
                           "folder of frames ('' = the sensor profile's camera name)"),
            ("source", "", "sim only: sim[:difficulty] or replay:DIR for the mock image"),
            ("record_dir", "", "where trial records go ('' = runs/trials)"),
            ("trial_id", "", "record sub-folder ('' = time stamp)"),
            ("bag", "false", "also record the trial's topics with `ros2 bag record` (MCAP) "
                             "into record_dir/bag_<time> (needs rosbag2)"),
            ("exit_when_done", "false", "the explorer exits after the trial, which ends the "
                                        "launch")]
    return LaunchDescription([DeclareLaunchArgument(n, default_value=d, description=h)
                              for n, d, h in args] + [OpaqueFunction(function=_nodes)])
