"""The node graph, described once: used by ``launch/explore.launch.py`` and by the runner.

``describe(...)`` returns the nodes (executable, name, parameters, remappings). Hardware graph:
gelsight_node, motion_node, explorer_node. Simulated graph (``sim=True``): mock_arm_node and
mock_image_node replace the robot/franka_ros2 and the camera at the same topics; motion_node
and explorer_node run unchanged. Pure Python (no rclpy, no launch).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import yaml

from .core.config import validate
from .core.errors import TactexError
from .node_settings import (ExplorerSettings, GelsightSettings, MockArmSettings,
                            MockImageSettings, MotionSettings)
from .paths import config_dir
from .scene import load_scene

PACKAGE = "tactex"


@dataclass
class NodeSpec:
    executable: str
    name: str
    parameters: dict[str, Any]
    remappings: list[tuple[str, str]] = field(default_factory=list)
    package: str = PACKAGE


def _checked(cls: type, params: dict[str, Any]) -> dict[str, Any]:
    """Validate parameters against a node's schema; unknown names are refused."""
    names = {f.name for f in dataclasses.fields(cls)}
    unknown = set(params) - names
    if unknown:
        raise TactexError(f"{cls.__name__}: unknown parameter(s) {sorted(unknown)}")
    validate(cls(**params))
    return dict(params)


def explorer_defaults(path: str | Path | None = None) -> dict[str, Any]:
    """Explorer settings from ``config/explorer.yaml`` (or ``path``)."""
    p = Path(path) if path else config_dir() / "explorer.yaml"
    if not p.is_file():
        raise TactexError(f"explorer settings file {str(p)!r} not found")
    data = yaml.safe_load(p.read_text()) or {}
    if not isinstance(data, dict):
        raise TactexError(f"explorer settings file {str(p)!r}: expected a mapping")
    return _checked(ExplorerSettings, data)


def params_from_file(path: str | Path, node: str) -> dict[str, Any]:
    """A node's parameters from a YAML file: either ``{name: value}`` or the ROS 2 form
    ``{<node>: {ros__parameters: {...}}}``."""
    p = Path(path)
    if not p.is_file():
        raise TactexError(f"{node} parameters file {str(p)!r} not found")
    try:
        data = yaml.safe_load(p.read_text()) or {}
    except yaml.YAMLError as exc:
        raise TactexError(f"{node} parameters file {str(p)!r}: not valid YAML ({exc})") from None
    if isinstance(data, dict) and isinstance(data.get(node), dict):
        data = data[node].get("ros__parameters", {})
    if not isinstance(data, dict):
        raise TactexError(f"{node} parameters file {str(p)!r}: expected a mapping")
    return data


def describe(sim: bool, scene_file: str | Path | None = None, *,
             explorer: dict[str, Any] | None = None, explorer_file: str | Path | None = None,
             gelsight: dict[str, Any] | None = None, mock_image: dict[str, Any] | None = None,
             mock_arm: dict[str, Any] | None = None,
             motion: dict[str, Any] | None = None, motion_file: str | Path | None = None,
             robot: str | None = None) -> list[NodeSpec]:
    """The tactex graph. ``scene_file`` defaults to config/scene_sim.yaml (sim) or
    config/scene.yaml; ``robot`` (profile name or path) to ``sim`` (sim) or ``fr3_jazzy``;
    ``motion_file``: a YAML of motion node parameters, under ``motion``. The scene, the robot
    profile and every parameter are validated here, so bad values fail before anything starts,
    with the field named."""
    from .core.press import check_press
    from .robot import load_profile
    scene_file = str(Path(scene_file) if scene_file else
                     config_dir() / ("scene_sim.yaml" if sim else "scene.yaml"))
    scene = load_scene(scene_file)
    ex = {**explorer_defaults(explorer_file), "scene_file": scene_file, **(explorer or {})}
    mo = {"scene_file": scene_file, "robot": robot or ("sim" if sim else "fr3_jazzy"),
          **(params_from_file(motion_file, "motion") if motion_file else {}), **(motion or {})}
    mo = _checked(MotionSettings, mo)
    prof = load_profile(mo["robot"])
    if prof.frame_id != scene.frame_id:
        raise TactexError(f"scene {Path(scene_file).name}: frame_id {scene.frame_id!r} is not "
                          f"the base frame {prof.frame_id!r} of robot profile {prof.name!r}")
    check_press(scene, mo.get("stiffness") or prof.stiffness, f"scene {Path(scene_file).name}")
    nodes = [NodeSpec("motion_node", "motion", mo),
             NodeSpec("explorer_node", "explorer", _checked(ExplorerSettings, ex))]
    if sim:
        start = scene.reference.position
        arm = {"scene_file": scene_file, "robot": mo["robot"], "start_x": start[0],
               "start_y": start[1], "start_z": min(scene.workspace_max[2], start[2] + 0.1),
               **(mock_arm or {})}
        img = {"scene_file": scene_file, "source": scene.source or "sim", **(mock_image or {})}
        nodes = [NodeSpec("mock_arm_node", "mock_arm", _checked(MockArmSettings, arm)),
                 NodeSpec("mock_image_node", "mock_image",
                          _checked(MockImageSettings, img))] + nodes
    else:
        from .sensor import sensor_config
        gs = _checked(GelsightSettings, dict(gelsight or {}))
        sensor_config(GelsightSettings(**gs), camera=False)   # the sensor profile, validated
        nodes = [NodeSpec("gelsight_node", "gelsight", gs)] + nodes
    return nodes


def fixed_frame(nodes: list[NodeSpec]) -> str:
    """The robot's base frame (the rviz fixed frame) of a described graph."""
    from .robot import load_profile
    motion = next(n for n in nodes if n.name == "motion")
    return load_profile(motion.parameters["robot"]).frame_id


def params_file(nodes: list[NodeSpec], path: str | Path) -> Path:
    """Write one ROS 2 parameters YAML for all nodes (``<name>: {ros__parameters: ...}``)."""
    p = Path(path)
    p.parent.mkdir(parents=True, exist_ok=True)
    p.write_text(yaml.safe_dump({n.name: {"ros__parameters": n.parameters} for n in nodes},
                                sort_keys=False))
    return p
