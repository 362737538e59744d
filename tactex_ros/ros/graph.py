"""The node graph, described once: used by ``launch/explore.launch.py`` and by the runner.

``describe(...)`` returns the nodes (executable, name, parameters, remappings). Hardware graph:
gelsight_node, motion_node, explorer_node. Simulated graph (``sim=True``): mock_arm_node and
mock_image_node replace the robot/franka_ros2 and the camera at the same topics; motion_node
and explorer_node run unchanged. Pure Python (no rclpy, no launch).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import yaml
from ..core.schema import FieldSpec, field_spec, merge, nest, parse_text, typed
from ..core.errors import InputError
from .settings import (ExplorerSettings, GelsightSettings, MockArmSettings, MockImageSettings,
                       MotionSettings)
from ..core.paths import config_dir, read_yaml
from ..robot.scene import load_scene

PACKAGE = "tactex"


@dataclass
class NodeSpec:
    executable: str
    name: str
    parameters: dict[str, Any]
    remappings: list[tuple[str, str]] = field(default_factory=list)
    package: str = PACKAGE


SIM_MIN_STATE_RATE_HZ = 5.0    # [Hz] the sim graph's motion pre-flight (mock arm state)

# every node's settings schema, by node name
SETTINGS: dict[str, type] = {"gelsight": GelsightSettings, "motion": MotionSettings,
                             "explorer": ExplorerSettings, "mock_arm": MockArmSettings,
                             "mock_image": MockImageSettings}
# the node settings `tactex graph describe|run` and the launch file take as options, by option
# name: (node, dotted setting); type, range, choices, default and help come from the schema
OPTIONS: dict[str, tuple[str, str]] = {
    "config": ("explorer", "config"), "strategy": ("explorer", "trial.strategy"),
    "model": ("explorer", "learner.model"), "rounds": ("explorer", "trial.rounds"),
    "seed": ("explorer", "seed"), "record_dir": ("explorer", "record_dir"),
    "trial_id": ("explorer", "trial_id"), "exit_when_done": ("explorer", "exit_when_done"),
    "session": ("explorer", "session_file"), "session_dir": ("explorer", "session_dir"),
    "trials": ("explorer", "trials"),
    "auto_confirm": ("explorer", "auto_confirm"), "resume": ("explorer", "resume"),
    "sensor": ("gelsight", "sensor"), "device": ("gelsight", "device"),
    "source": ("mock_image", "source")}


def option_spec(name: str) -> FieldSpec:
    """The schema field behind option ``name`` of ``OPTIONS``."""
    node, path = OPTIONS[name]
    return field_spec(SETTINGS[node], path)


def option_default(name: str) -> Any:
    """The value option ``name`` of ``OPTIONS`` has when not given: the node's settings with
    nothing set (the explorer's ``learner.*`` / ``trial.*`` come from the default preset, not
    from the field's own default)."""
    from ..core.config import PRESETS, TRIAL_PRESETS
    node, path = OPTIONS[name]
    head, _, last = path.partition(".")
    preset = {"learner": PRESETS, "trial": TRIAL_PRESETS}.get(head) if node == "explorer" \
        else None
    default = option_spec(name).default
    return preset["default"].get(last, default) if preset else default


def parse_option(name: str, text: str) -> Any:
    """Option ``name`` given as text (a launch argument), typed and checked by its schema;
    InputError names the option."""
    node, path = OPTIONS[name]
    return parse_text(SETTINGS[node], path, text, f"{name}:={text!r}")


def option_overrides(values: dict[str, Any]) -> dict[str, dict[str, Any]]:
    """Options given (not None) -> ``{node: nested settings}`` for ``describe``."""
    out: dict[str, dict[str, Any]] = {}
    for name, value in values.items():
        if value is not None:
            node, path = OPTIONS[name]
            out[node] = merge(out.get(node), nest({path: value}))
    return out


def _checked(node: str, params: dict[str, Any]) -> dict[str, Any]:
    """A node's given parameters checked against its schema and typed (unknown names refused)."""
    return typed(SETTINGS[node], params, f"{node} parameters")


def explorer_defaults(path: str | Path | None = None) -> dict[str, Any]:
    """Explorer settings from ``config/explorer.yaml`` (or ``path``)."""
    p = Path(path) if path else config_dir() / "explorer.yaml"
    if not p.is_file():
        raise InputError(f"explorer settings file {str(p)!r} not found")
    return _checked("explorer", params_from_file(p, "explorer"))


def params_from_file(path: str | Path, node: str) -> dict[str, Any]:
    """A node's parameters from a YAML file: either ``{name: value}`` or the ROS 2 form
    ``{<node>: {ros__parameters: {...}}}``."""
    p = Path(path)
    if not p.is_file():
        raise InputError(f"{node} parameters file {str(p)!r} not found")
    data = read_yaml(p, f"{node} parameters file") or {}
    if isinstance(data, dict) and isinstance(data.get(node), dict):
        data = data[node].get("ros__parameters", {})
    if not isinstance(data, dict):
        raise InputError(f"{node} parameters file {str(p)!r}: expected a mapping")
    return data


NODE_PARAMS = ("motion", "mock_arm", "mock_image", "gelsight")


def node_params_file(path: str | Path) -> dict[str, dict[str, Any]]:
    """``{node: parameters}`` from a ROS 2 parameters YAML (``<node>: {ros__parameters:
    {...}}``) for the nodes of ``NODE_PARAMS`` (the explorer's settings: ``settings``);
    InputError names an unknown node (each node's values are checked by ``describe``)."""
    p = Path(path)
    if not p.is_file():
        raise InputError(f"node parameters file {str(p)!r} not found")
    data = read_yaml(p, "node parameters file")
    if not isinstance(data, dict):
        raise InputError(f"node parameters file {str(p)!r}: expected a mapping of node names "
                         f"({', '.join(NODE_PARAMS)}) to {{ros__parameters: ...}}")
    bad = sorted(set(data) - set(NODE_PARAMS))
    if bad:
        raise InputError(f"node parameters file {str(p)!r}: unknown node(s) {', '.join(bad)} "
                         f"(one of {', '.join(NODE_PARAMS)}; the explorer's: --settings)")
    return {node: params_from_file(p, node) for node in data}


def scene_path(sim: bool, scene: str | Path | None, robot: str | None = None) -> str:
    """The scene file of a graph: ``scene`` (a path, or a shipped scene by name:
    scene_replay, scene_sim), else config/scene_sim.yaml (``sim``) or the robot profile's
    ``scene`` (``robot``: a profile name or path; default fr3_crisp)."""
    from ..robot.robots import load_profile
    if scene and not Path(scene).is_file() and "/" not in str(scene):
        for cand in (config_dir() / str(scene), config_dir() / f"{scene}.yaml"):
            if cand.is_file():
                return str(cand)
    if scene:
        return str(Path(scene))
    if sim:
        return str(config_dir() / "scene_sim.yaml")
    return str(config_dir() / load_profile(robot or "fr3_crisp").scene)


def describe(sim: bool, scene_file: str | Path | None = None, *,
             explorer: dict[str, Any] | ExplorerSettings | None = None,
             explorer_file: str | Path | None = None,
             gelsight: dict[str, Any] | None = None, mock_image: dict[str, Any] | None = None,
             mock_arm: dict[str, Any] | None = None,
             motion: dict[str, Any] | None = None, motion_file: str | Path | None = None,
             robot: str | None = None, sim_clock: bool = True) -> list[NodeSpec]:
    """The tactex graph. ``robot`` (profile name or path) defaults to ``sim`` (sim) or
    ``fr3_crisp``; ``scene_file`` to config/scene_sim.yaml (sim) or the profile's ``scene``
    (config/scene.yaml for the FR3, config/scene_panda.yaml for the Panda);
    ``motion_file``: a YAML of motion node parameters, under ``motion``. ``explorer``: the
    explorer's settings resolved by ``run_settings.resolve_run`` (the launch file and ``tactex
    graph``: taken as they are), or settings given over ``explorer_file`` (default
    config/explorer.yaml), checked here. The scene, the robot profile and every parameter are
    validated here, so bad values fail before anything starts, with the field named.
    ``sim_clock`` (sim only): every node gets ``use_sim_time`` and the mock arm publishes
    /clock (ros/simclock.py); False keeps wall time, as the robot graph does (a test of the
    robot graph's own timing against the mock)."""
    from ..robot.press import check_press
    from ..robot.robots import load_profile
    given_motion = merge(params_from_file(motion_file, "motion") if motion_file else None,
                         motion)
    scene_file = scene_path(sim, scene_file, given_motion.get("robot") or robot)
    scene = load_scene(scene_file)
    # the mock arm is no robot: its state rate (100 Hz nominal) fell to 12 Hz during start-up
    # on a loaded machine, so the sim graph's pre-flight asks only for SIM_MIN_STATE_RATE_HZ
    mo = merge({"scene_file": scene_file, "robot": robot or ("sim" if sim else "fr3_crisp")},
               {"min_state_rate_hz": SIM_MIN_STATE_RATE_HZ} if sim else None, given_motion)
    mo = _checked("motion", mo)
    prof = load_profile(mo["robot"])
    if prof.frame_id != scene.frame_id:
        raise InputError(f"scene {Path(scene_file).name}: frame_id {scene.frame_id!r} is not "
                          f"the base frame {prof.frame_id!r} of robot profile {prof.name!r}")
    check_press(scene, mo.get("stiffness") or prof.stiffness, f"scene {Path(scene_file).name}",
                prof.law.error_clip)
    if isinstance(explorer, ExplorerSettings):    # resolved at the edge (ros/run_settings.py)
        ex = explorer.model_dump()
    else:
        ex = _checked("explorer", merge(explorer_defaults(explorer_file),
                                        {"scene_file": scene_file}, explorer))
    if ex.get("session_file"):
        check_session(ex, scene, sim, (mock_image or {}).get("source") or scene.source or "sim")
    elif ex.get("library_materials"):
        check_library(ex, scene, sim, (mock_image or {}).get("source") or scene.source or "sim")
    elif ex.get("trials"):
        raise InputError(f"trials {ex['trials']!r}: picks trials of a session; give the "
                          "session (session / --session, or --session-dir of a session)")
    nodes = [NodeSpec("motion_node", "motion", mo), NodeSpec("explorer_node", "explorer", ex)]
    if sim:
        start = scene.reference.position
        arm = merge({"scene_file": scene_file, "robot": mo["robot"], "start_x": start[0],
                     "start_y": start[1],
                     "start_z": min(scene.workspace_max[2], start[2] + 0.1)}, mock_arm)
        arm = _checked("mock_arm", arm)
        # the mock camera follows the mock arm's state topics, so the two cannot disagree
        arm_prof = load_profile(arm["robot"])
        img = merge({"scene_file": scene_file, "source": scene.source or "sim",
                     "pose_topic": arm.get("pose_topic") or arm_prof.pose_topic,
                     "wrench_topic": arm.get("wrench_topic") or arm_prof.wrench_topic},
                    mock_image)
        nodes = [NodeSpec("mock_arm_node", "mock_arm", arm),
                 NodeSpec("mock_image_node", "mock_image", _checked("mock_image", img))] + nodes
        if gelsight:       # no GelSight node in simulation, but a bad option is still refused
            from ..robot.sensors import sensor_config
            sensor_config(GelsightSettings(**_checked("gelsight", gelsight)), camera=False)
    else:
        from ..robot.sensors import sensor_config
        gs = _checked("gelsight", gelsight or {})
        sensor_config(GelsightSettings(**gs), camera=False)   # the sensor profile, validated
        nodes = [NodeSpec("gelsight_node", "gelsight", gs)] + nodes
    if sim and sim_clock:   # the simulated graph keeps the mock arm's time (ros/simclock.py)
        for n in nodes:
            n.parameters["use_sim_time"] = True
    return nodes


def check_session(explorer: dict[str, Any], scene, sim: bool, source: str) -> None:
    """A study session's trial file checked against the scene before anything starts (the
    row named); in simulation the explorer drives the mock camera's placement."""
    from ..trial.session import load_session, select_trials
    session = load_session(explorer["session_file"], [p.id for p in scene.ordered],
                           seed=int(explorer.get("seed", 0)))
    select_trials(session, explorer.get("trials", ""))
    if sim:
        if not source.startswith("sim"):
            raise InputError(f"session {explorer['session_file']!r}: a simulated session "
                              f"places catalogue fabrics; source {source!r} cannot show them "
                              "(use source sim)")
        explorer.setdefault("placement_service", "/mock_image/set_parameters")
        if not explorer["placement_service"]:
            explorer["placement_service"] = "/mock_image/set_parameters"


def check_library(explorer: dict[str, Any], scene, sim: bool, source: str) -> None:
    """A press library's materials and platform checked before anything starts
    (``trial.press_library``): plain names, and in simulation catalogue fabrics the mock
    camera shows on the platform (the explorer drives its placement); the platform one of
    the scene's (InputError naming them)."""
    from ..trial.press_library import check_presses, parse_materials
    from ..trial.session import catalogue_names
    ids = [p.id for p in scene.ordered]
    if sim and not source.startswith("sim"):
        raise InputError(f"a simulated press library presses catalogue fabrics; source "
                         f"{source!r} cannot show them (use source sim)")
    parse_materials(explorer["library_materials"], catalogue_names() if sim else None)
    check_presses(int(explorer.get("library_presses", 0)))
    pid = explorer.get("library_platform") or ids[0]
    if pid not in ids:
        raise InputError(f"--platform {pid!r}: not a platform of the scene (its platforms: "
                         f"{', '.join(ids)})")
    if sim and not explorer.get("placement_service"):
        explorer["placement_service"] = "/mock_image/set_parameters"


def fixed_frame(nodes: list[NodeSpec]) -> str:
    """The robot's base frame (the rviz fixed frame) of a described graph."""
    from ..robot.robots import load_profile
    motion = next(n for n in nodes if n.name == "motion")
    return load_profile(motion.parameters["robot"]).frame_id


def params_file(nodes: list[NodeSpec], path: str | Path) -> Path:
    """Write one ROS 2 parameters YAML for all nodes (``<name>: {ros__parameters: ...}``)."""
    p = Path(path)
    p.parent.mkdir(parents=True, exist_ok=True)
    p.write_text(yaml.safe_dump({n.name: {"ros__parameters": n.parameters} for n in nodes},
                                sort_keys=False))
    return p
