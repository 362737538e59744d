"""ros2 launch tactex explore.launch.py [sim:=true] [rviz:=true] [scene:=FILE] [strategy:=S]
[model:=M] [rounds:=N] [seed:=N] [device:=/dev/videoN|'GelSight Mini'] [source:=sim|replay:DIR]

Hardware graph: gelsight_node, motion_node, explorer_node (franka_ros2 must already run the
robot state broadcaster and a Cartesian impedance controller). ``sim:=true``: mock_arm_node and
mock_image_node replace robot and camera at the same topics. The nodes and their parameters come
from ``tactex_ros.graph.describe`` -- the same description the ``tactex graph run`` runner uses.
"""

from __future__ import annotations

from launch import LaunchDescription
from launch.actions import DeclareLaunchArgument, OpaqueFunction
from launch.conditions import IfCondition
from launch.substitutions import LaunchConfiguration
from launch_ros.actions import Node


def _nodes(context, *args, **kwargs):
    from tactex_ros.graph import describe
    from tactex_ros.paths import config_dir

    def arg(name: str) -> str:
        return LaunchConfiguration(name).perform(context)

    sim = arg("sim").lower() in ("true", "1", "yes")
    explorer = {"strategy": arg("strategy"), "rounds": int(arg("rounds")),
                "seed": int(arg("seed"))}
    if arg("model"):
        explorer["model"] = arg("model")
    if arg("record_dir"):
        explorer["record_dir"] = arg("record_dir")
    if arg("trial_id"):
        explorer["trial_id"] = arg("trial_id")
    if arg("exit_when_done").lower() in ("true", "1", "yes"):
        explorer["exit_when_done"] = True
    nodes = describe(sim, arg("scene") or None, explorer=explorer,
                     gelsight={"device": arg("device")} if not sim else None,
                     mock_image={"source": arg("source")} if sim and arg("source") else None)
    actions = [Node(package=n.package, executable=n.executable, name=n.name,
                    parameters=[n.parameters], remappings=n.remappings, output="screen")
               for n in nodes]
    actions.append(Node(package="rviz2", executable="rviz2", name="rviz2",
                        arguments=["-d", str(config_dir() / "tactex.rviz")],
                        condition=IfCondition(LaunchConfiguration("rviz"))))
    return actions


def generate_launch_description() -> LaunchDescription:
    args = [("sim", "false", "mock arm + mock image instead of the hardware"),
            ("rviz", "false", "start rviz2 with config/tactex.rviz"),
            ("scene", "", "scene YAML (default config/scene.yaml, sim: config/scene_sim.yaml)"),
            ("strategy", "", "'' (the preset's) | infogain | variance | entropy | random | yoto | bald"),
            ("model", "", "model variant ('' = the preset's; auto escalates)"),
            ("rounds", "20", "decisions that request a touch"),
            ("seed", "0", "learner / strategy seed"),
            ("device", "GelSight Mini", "GelSight device path, camera name or video file"),
            ("source", "", "sim only: sim[:difficulty] or replay:DIR for the mock image"),
            ("record_dir", "", "where trial records go ('' = runs/trials)"),
            ("trial_id", "", "record sub-folder ('' = time stamp)"),
            ("exit_when_done", "false", "explorer exits after the trial")]
    return LaunchDescription([DeclareLaunchArgument(n, default_value=d, description=h)
                              for n, d, h in args] + [OpaqueFunction(function=_nodes)])
