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


def describe(sim: bool, scene_file: str | Path | None = None, *,
             explorer: dict[str, Any] | None = None, explorer_file: str | Path | None = None,
             gelsight: dict[str, Any] | None = None, mock_image: dict[str, Any] | None = None,
             mock_arm: dict[str, Any] | None = None,
             motion: dict[str, Any] | None = None) -> list[NodeSpec]:
    """The tactex graph. ``scene_file`` defaults to config/scene_sim.yaml (sim) or
    config/scene.yaml; the scene is validated here so a bad one fails before anything starts."""
    scene_file = str(Path(scene_file) if scene_file else
                     config_dir() / ("scene_sim.yaml" if sim else "scene.yaml"))
    scene = load_scene(scene_file)
    ex = {**explorer_defaults(explorer_file), "scene_file": scene_file, **(explorer or {})}
    nodes = [NodeSpec("motion_node", "motion",
                      _checked(MotionSettings, {"scene_file": scene_file, **(motion or {})})),
             NodeSpec("explorer_node", "explorer", _checked(ExplorerSettings, ex))]
    if sim:
        start = scene.reference.position
        arm = {"scene_file": scene_file, "start_x": start[0], "start_y": start[1],
               "start_z": min(scene.workspace_max[2], start[2] + 0.1), **(mock_arm or {})}
        img = {"scene_file": scene_file, "source": scene.source or "sim", **(mock_image or {})}
        nodes = [NodeSpec("mock_arm_node", "mock_arm", _checked(MockArmSettings, arm)),
                 NodeSpec("mock_image_node", "mock_image",
                          _checked(MockImageSettings, img))] + nodes
    else:
        nodes = [NodeSpec("gelsight_node", "gelsight",
                          _checked(GelsightSettings, dict(gelsight or {})))] + nodes
    return nodes


def params_file(nodes: list[NodeSpec], path: str | Path) -> Path:
    """Write one ROS 2 parameters YAML for all nodes (``<name>: {ros__parameters: ...}``)."""
    p = Path(path)
    p.parent.mkdir(parents=True, exist_ok=True)
    p.write_text(yaml.safe_dump({n.name: {"ros__parameters": n.parameters} for n in nodes},
                                sort_keys=False))
    return p
