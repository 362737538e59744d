"""ros2 launch tactex explore.launch.py [sim:=true] [rviz:=true] [robot:=fr3_crisp|panda_crisp|
sim|FILE] [motion_params:=FILE] [scene:=FILE] [bag:=true] [config:=P] [strategy:=S] [model:=M]
[rounds:=N] [seed:=N] [record_dir:=DIR] [trial_id:=NAME] [exit_when_done:=true]
[sensor:=gelsight_mini|digit|FILE] [device:=/dev/videoN|'GelSight Mini'|SERIAL|DIR]
[source:=sim|replay:DIR] [session:=config/trials/NAME.yaml|NAME] [session_dir:=DIR]
[trials:=ID,...] [auto_confirm:=true] [resume:=RECORD] [settings:=FILE] [explorer_set:="PATH=VALUE ..."]
[learner.NAME:=VALUE] [trial.NAME:=VALUE]

Hardware graph: gelsight_node, motion_node, explorer_node; the robot profile (``robot``,
config/robots/) names the impedance controller, topics, message types and recovery interface of
the robot stack, which must already run. ``sim:=true``: mock_arm_node and mock_image_node replace
robot and camera at the same topics, and a static transform world -> base frame gives rviz its
fixed frame; every node of the simulated graph (rviz and the static transform too) has
``use_sim_time``: the mock arm publishes /clock (``tactex_ros.ros.simclock``). ``bag:=true``
records with receive times on the wall clock (stamps inside the messages are simulated). The nodes and their parameters come from ``tactex_ros.ros.graph.describe`` -- the same
description the ``tactex graph run`` runner uses -- and are all validated before anything starts:
a bad value ends the launch with the argument or field named and no process started. The node
settings among the arguments (config ... source) are ``tactex_ros.ros.graph.OPTIONS``: their types,
ranges, choices and descriptions come from the nodes' settings schema, as for
``tactex graph run``; '' (the default) leaves the node's own default.

Any setting of the trial is also taken by its dotted name, e.g. ``learner.device:=cuda`` (a CNN
preset's GPU: ``config:=seed_faithful learner.device:=cuda``) or ``trial.max_touches:=8``;
checked by the explorer's schema like the options above.

``session:=FILE`` runs a study session: the explorer runs the trial file's trials in order in
this one launch, tells the operator before each trial what to place on which platform (log,
``/tactex/operator/prompt``) and waits for ``ros2 service call /explorer/confirm
std_srvs/srv/Trigger`` (``auto_confirm:=true``: scripted); in simulation it sets the mock
camera's placement. A bad trial file ends the launch before anything starts, the row named.
``session_dir:=`` an existing folder of the same session continues it (see docs/operator.md);
``trials:=ID,...`` runs only those trials of the session (an unknown id is refused with the
session's ids); a later launch with the same ``session_dir:=`` continues with the others.

``resume:=RECORD`` continues the interrupted trial recorded in folder RECORD and needs no other
argument: the run's settings are resolved once as ``tactex graph run --resume`` resolves them
(``tactex_ros.ros.run_settings.resolve_run``): the options the run was given from the record's
``run.json`` (sim, source, sensor, device, settings, ``explorer_set``, the ROS domain), every
explorer setting from its ``config.json`` and its scene; an argument given with another value
than the record's is refused, the setting and both values named. A launch writes its options
to ``run.json`` in the trial record (or session folder) before any node starts, as ``tactex
graph run`` does. Every explorer setting can be set at launch, as ``tactex graph run`` sets it:
``settings:=FILE`` is a YAML of explorer parameters over ``config/explorer.yaml`` (``{name:
value}`` or the ROS 2 ``explorer: {ros__parameters: ...}`` form) and ``explorer_set:=`` takes
dotted ``PATH=VALUE`` items separated by spaces or ``;`` (e.g. ``explorer_set:="
trial.stop_confidence=0.95 learner.model=descriptor"``), the same syntax as ``--set``; both
are checked against the explorer's schema (an unknown path is refused with the nearest valid
one) and passed as node parameters.

Any tactex node that exits ends the launch (a dead camera or robot interface stops the trial;
with ``exit_when_done:=true`` the explorer's exit after the trial ends it). A node that exits
with a non-zero status (a refused start-up or pre-flight, a crash) also makes ``ros2 launch``
end with status 1: launch has no exit-status action (``LaunchService.run`` returns 1 only when
an exception reaches its event loop, launch 1.0.7 / 3.4.3 / 3.7.1 ``launch_service.py``), so
the node's exit handler emits an event of its own whose handler raises ``NodeFailed`` naming
the node and its status, after every other handler of the exit has seen it (launch_testing's
record of exit codes included; docs/hardware_checks.md). rviz2 is started only when it is installed (checked before any node
starts) and its exit does not end the launch; its generated config folder is removed when the
launch shuts down.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

# launch and launch_ros are imported where the launch runs (generate_launch_description and
# the OpaqueFunction), so the pure part below imports and is tested where they are absent

_TRUE, _FALSE = ("true", "1", "yes", "on"), ("false", "0", "no", "off")


class LaunchArgumentError(ValueError):
    """A launch argument with a value that does not fit; the message names the argument."""


class NodeFailed(RuntimeError):
    """A tactex node exited with a non-zero status: raised in its exit handler, so the launch
    shuts down and ``LaunchService.run`` (``ros2 launch``) returns 1."""


def node_exited(name: str, returncode: int | None) -> str:
    """Why the launch ends after tactex node ``name`` exited with ``returncode`` (0: a
    normal end); NodeFailed for a non-zero or unknown status."""
    if returncode != 0:
        raise NodeFailed(f"tactex node {name} exited with status {returncode}")
    return f"tactex node {name} exited"


def bag_command(out: str, topics: list[str], distro: str) -> list[str]:
    """``ros2 bag record`` of ``topics`` into ``out`` (MCAP): rosbag2 on Humble (0.15.x,
    ros2bag/verb/record.py: positional ``topics``) takes the topics positionally; Jazzy (0.26.x)
    and later take ``--topics`` and deprecate the positional form."""
    cmd = ["ros2", "bag", "record", "-s", "mcap", "-o", out]
    return cmd + topics if distro == "humble" else cmd + ["--topics"] + topics


def arguments() -> list[tuple[str, str, str]]:
    """(name, default, description) of every launch argument: the graph's own, then one per
    node setting of ``tactex_ros.ros.graph.OPTIONS`` (description and choices from the schema)."""
    from tactex_ros.ros.graph import OPTIONS, option_default, option_spec
    args = [("sim", "false", "mock arm + mock image instead of the hardware"),
            ("rviz", "false", "start rviz2 with config/tactex.rviz (fixed frame: the robot's "
                              "base frame)"),
            ("robot", "", "robot profile: fr3_crisp | panda_crisp | sim | FILE "
                          "('' = fr3_crisp, sim: sim)"),
            ("motion_params", "", "YAML of motion_node parameters (topics, stiffness, "
                                  "force_sign, recovery_name, ...) over the profile's"),
            ("scene", "", "scene YAML (default: the robot profile's, config/scene.yaml for the "
                          "FR3, config/scene_panda.yaml for the Panda; sim: "
                          "config/scene_sim.yaml)"),
            ("bag", "false", "also record the trial's topics with `ros2 bag record` (MCAP) "
                             "into record_dir/bag_<time> (needs rosbag2)"),
            ("settings", "", "YAML of explorer parameters over config/explorer.yaml "
                             "('' = config/explorer.yaml alone)"),
            ("explorer_set", "", "explorer settings as dotted PATH=VALUE items separated by "
                                 "spaces or ';' (e.g. trial.stop_confidence=0.95), over "
                                 "settings and the arguments above")]
    for name, (node, path) in OPTIONS.items():
        spec = option_spec(name)
        args.append((name, "", f"{node} {path}: {spec.description}"
                               + (f" (one of {', '.join(map(str, spec.choices))})"
                                  if spec.choices else "")
                               + f" ('' = the node's default, {option_default(name)!r})"))
    return args


def explorer_set_items(text: str) -> list[str]:
    """The launch argument ``explorer_set``: dotted ``PATH=VALUE`` items of the explorer's
    settings separated by spaces or ';' (the syntax of ``--set``; each is read and checked by
    ``core.schema.overrides``, which names the item and the nearest valid path)."""
    import re
    return [i for i in re.split(r"[;\s]+", text.strip()) if i]


def plan(values: dict[str, str]) -> dict[str, Any]:
    """The graph the launch arguments ``values`` ({name: text}) ask for: ``nodes``
    (``graph.NodeSpec``), ``sim``, ``rviz``, ``bag``, the rviz ``frame``, the robot's
    ``pose_topic``, ``wrench_topic`` and ``state_topic`` (the topics of its state), the
    ``record_dir``. Everything is checked here;
    LaunchArgumentError names the argument or field."""
    from tactex_ros.core.errors import InputError
    from tactex_ros.core.schema import flatten
    from tactex_ros.ros.graph import (OPTIONS, describe, fixed_frame, option_overrides,
                                      params_from_file, parse_option)
    from tactex_ros.ros.run_settings import resolve_run, ros_domain_id
    from tactex_ros.robot.robots import load_profile

    def flag(name: str) -> bool:
        v = values.get(name, "false").strip().lower()
        if v not in _TRUE + _FALSE:
            raise LaunchArgumentError(f"launch argument {name}:={values[name]!r}: expected true "
                                      "or false")
        return v in _TRUE

    sim, rviz, bag = flag("sim"), flag("rviz"), flag("bag")
    try:
        given = {name: parse_option(name, values[name]) for name in OPTIONS
                 if values.get(name, "") != ""}
        # the explorer's settings: the options above, then learner.NAME:= / trial.NAME:=
        # arguments, then explorer_set:= items (each checked by the schema), resolved once
        # as `tactex graph run` resolves them (a resume: from its record and run.json)
        dotted = trial_settings(values)
        items = [f"{k}={values[k]}" for k in sorted(flatten(dotted))] + \
            explorer_set_items(values.get("explorer_set", ""))
        motion_file = values.get("motion_params") or None
        robot = values.get("robot") or None
        if motion_file:
            robot = params_from_file(motion_file, "motion").get("robot") or robot
        run = resolve_run(dict(given, sim=sim, scene=values.get("scene") or None,
                               settings=values.get("settings") or None, set=items,
                               domain_id=ros_domain_id(), robot=robot),
                          set_origin="explorer_set:=")
        opts = run.options
        sim = bool(opts.get("sim"))       # a resume: the record's graph (sim:=false is unset)
        devices = option_overrides({k: opts.get(k) for k in ("source", "sensor", "device")})
        nodes = describe(sim, run.scene, explorer=run.explorer,
                         gelsight=None if sim else devices.get("gelsight"),
                         mock_image=devices.get("mock_image") if sim else None,
                         robot=values.get("robot") or None, motion_file=motion_file)
        motion = next(n for n in nodes if n.name == "motion")
        profile = load_profile(motion.parameters["robot"])
        explorer = next(n for n in nodes if n.name == "explorer")
        return {"nodes": nodes, "sim": sim, "rviz": rviz, "bag": bag, "run": run,
                "frame": fixed_frame(nodes),
                "pose_topic": motion.parameters.get("pose_topic") or profile.pose_topic,
                "wrench_topic": motion.parameters.get("wrench_topic") or profile.wrench_topic,
                # a franka state message (the Panda's): the robot state the bag records
                "state_topic": (motion.parameters.get("state_topic") or profile.state_topic
                                if profile.franka_state else ""),
                "record_dir": explorer.parameters.get("record_dir") or "runs/trials"}
    except InputError as exc:
        raise LaunchArgumentError(f"launch argument {exc}") from None


def run_folder(p: dict[str, Any]) -> Path:
    """Where the planned run ``p`` keeps its record (a new trial's id, a new session's
    folder named now, as ``tactex graph run`` names them) with its options (``run.json``,
    ``run_settings.save_run_file``), before any node starts: the trial record, the session
    folder, or the record a resume continues."""
    import time

    from tactex_ros.ros.run_settings import save_run_file
    from tactex_ros.trial.record import free_trial_id
    ex = next(n for n in p["nodes"] if n.name == "explorer").parameters
    root = Path(ex.get("record_dir") or "runs/trials")
    if ex.get("session_file"):
        if not ex.get("session_dir"):
            ex["session_dir"] = str(root / f"{Path(ex['session_file']).stem}_"
                                           f"{time.strftime('%Y%m%d_%H%M%S')}")
        folder = Path(ex["session_dir"])
    elif ex.get("resume"):
        folder = Path(ex["resume"])
    else:
        ex["trial_id"] = ex.get("trial_id") or free_trial_id(root)
        folder = root / ex["trial_id"]
    save_run_file(folder, p["run"])
    return folder


def trial_settings(values: dict[str, str]) -> dict[str, Any]:
    """The explorer's trial settings given by their dotted names (``learner.device:=cuda``,
    ``trial.max_touches:=8``), typed and checked by the schema (nested; {} when none)."""
    from tactex_ros.core.schema import nest, parse_text
    from tactex_ros.ros.settings import ExplorerSettings
    dotted = {k: v for k, v in values.items() if k.startswith(("learner.", "trial."))}
    return nest({k: parse_text(ExplorerSettings, k, v, f"{k}:={v!r}")
                 for k, v in dotted.items()})


def _nodes(context, *args, **kwargs):
    from launch.actions import EmitEvent, LogInfo, RegisterEventHandler, Shutdown
    from launch.event_handlers import OnShutdown
    from launch.substitutions import LaunchConfiguration
    from launch_ros.actions import Node

    from tactex_ros.core.errors import InputError
    from tactex_ros.core.paths import config_dir
    given = {name: LaunchConfiguration(name).perform(context) for name, _, _ in arguments()}
    # the trial's settings by dotted name, undeclared (they depend on learner.model)
    given.update({k: v for k, v in context.launch_configurations.items()
                  if k.startswith(("learner.", "trial."))})
    p = plan(given)
    try:
        run_folder(p)
    except InputError as exc:
        raise LaunchArgumentError(f"launch argument {exc}") from None
    nodes, sim, rviz, frame = p["nodes"], p["sim"], p["rviz"], p["frame"]
    if p["bag"] and not _installed("rosbag2_storage_mcap"):
        raise LaunchArgumentError("launch argument bag:=true: rosbag2 with MCAP storage is not "
                                  "installed (apt install ros-$ROS_DISTRO-rosbag2 "
                                  "ros-$ROS_DISTRO-rosbag2-storage-mcap), nothing started")
    if rviz and not _installed("rviz2"):
        # a missing rviz2 must fail here, before any node starts, not after (orphans)
        raise LaunchArgumentError("launch argument rviz:=true: rviz2 is not installed "
                                  "(apt install ros-$ROS_DISTRO-rviz2), nothing started")
    failed, fail = _node_failure()
    actions = [fail] + [Node(package=n.package, executable=n.executable, name=n.name,
                             parameters=[n.parameters], remappings=n.remappings,
                             output="screen", sigterm_timeout="10", sigkill_timeout="5",
                             on_exit=_on_exit(n.name, Shutdown,
                                              lambda name, code: EmitEvent(
                                                  event=failed(name, code))))
                        for n in nodes]
    if sim and _installed("tf2_ros"):   # rviz's fixed frame exists in TF (viewer only)
        actions.append(Node(package="tf2_ros", executable="static_transform_publisher",
                            name="tactex_sim_world", parameters=[{"use_sim_time": True}],
                            arguments=["--frame-id", "world", "--child-frame-id", frame]))
    elif sim:
        actions.append(LogInfo(msg="tf2_ros is not installed: no static transform world -> "
                                   f"{frame} for rviz"))
    if p["bag"]:   # `ros2 bag record` of the trial's topics next to the records; its exit
        #               does not end the launch (the fsync'ed record and topics.mcap stay the
        #               ground truth)
        import time
        from pathlib import Path

        from launch.actions import ExecuteProcess

        from tactex_ros.ros.settings import MARKER_TOPIC, STATE_TOPIC, TOUCH_IMAGE_TOPIC
        out = Path(p["record_dir"]) / time.strftime("bag_%Y%m%d_%H%M%S")
        topics = [t for t in (STATE_TOPIC, MARKER_TOPIC, TOUCH_IMAGE_TOPIC, p["pose_topic"],
                              p["wrench_topic"], p["state_topic"]) if t]
        import os
        actions.append(ExecuteProcess(cmd=bag_command(str(out), topics,
                                                      os.environ.get("ROS_DISTRO", "")),
                                      output="screen", sigterm_timeout="10"))
    if rviz:
        import shutil
        cfg = _rviz_config(config_dir() / "tactex.rviz", frame, p["pose_topic"])
        actions.append(Node(package="rviz2", executable="rviz2", name="rviz2",
                            arguments=["-d", str(cfg)],
                            parameters=[{"use_sim_time": True}] if sim else []))
        actions.append(RegisterEventHandler(OnShutdown(
            on_shutdown=lambda *_: shutil.rmtree(cfg.parent, ignore_errors=True))))
    return actions


def _on_exit(name: str, shutdown_cls, failure):
    """The exit handler of tactex node ``name``: end the launch (``shutdown_cls(reason=...)``);
    after a non-zero status it returns ``failure(name, returncode)`` (an action emitting the
    event that ``_node_failure`` raises NodeFailed for) and raises nothing itself: an exception
    in a handler stops launch from giving the same exit to the handlers after it
    (``LaunchService.__process_event``), launch_testing's record of the exit among them."""
    def handler(event, context):
        if event.returncode != 0:
            return [failure(name, event.returncode)]
        return [shutdown_cls(reason=node_exited(name, event.returncode))]
    return handler


def _node_failure():
    """(event class, handler action): a tactex node's non-zero exit as an event of its own,
    handled after every handler of the process's exit, by raising NodeFailed
    (``node_exited``): launch then stops the other nodes and ``LaunchService.run`` (``ros2
    launch``) returns 1."""
    from launch.actions import OpaqueFunction, RegisterEventHandler
    from launch.event import Event
    from launch.event_handler import EventHandler

    class NodeExitFailed(Event):
        name = "tactex.node_exit_failed"

        def __init__(self, node: str, returncode: int | None) -> None:
            super().__init__()
            self.node, self.returncode = node, returncode

    def fail(context):
        node_exited(context.locals.event.node, context.locals.event.returncode)

    return NodeExitFailed, RegisterEventHandler(EventHandler(
        matcher=lambda e: isinstance(e, NodeExitFailed), entities=[OpaqueFunction(function=fail)]))


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


def generate_launch_description():
    from launch import LaunchDescription
    from launch.actions import DeclareLaunchArgument, OpaqueFunction
    return LaunchDescription([DeclareLaunchArgument(n, default_value=d, description=h)
                              for n, d, h in arguments()] + [OpaqueFunction(function=_nodes)])
