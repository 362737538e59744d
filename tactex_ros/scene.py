"""The scene file: platforms (ids, poses), workspace box, press forces, speeds and deadlines.

Pure (no rclpy): loaded and validated once at node start-up; every error names the field.
Units: metres, seconds, newtons; positions in the robot base frame (``frame_id``). A platform's
``position`` is the centre of its fabric surface; presses approach straight down (-z).

Example (``config/scene.yaml``)::

    frame_id: fr3_link0
    workspace: {min: [0.25, -0.45, 0.0], max: [0.75, 0.45, 0.5]}
    tool_orientation: [1.0, 0.0, 0.0, 0.0]     # quaternion x y z w: sensor pointing down
    press: {approach_height: 0.05, travel_speed: 0.15, descend_speed: 0.01, ...}
    platforms:
      - {id: reference, role: reference, position: [0.50, 0.00, 0.05]}
      - {id: c1, position: [0.40, -0.20, 0.05], sim_fabric: satin}

``sim_fabric`` (catalogue name) or ``replay_class`` tell the mock image node what lies on a
platform; the robot application itself never reads them.
"""

from __future__ import annotations

from dataclasses import dataclass, fields
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from .core.errors import TactexError


@dataclass(frozen=True)
class PressSettings:
    """How a press is made; every phase has a deadline [s]."""

    approach_height: float = 0.05      # m above the surface where the descent starts
    travel_speed: float = 0.15         # m/s, moves between platforms (also the speed cap)
    descend_speed: float = 0.01        # m/s while descending onto the fabric
    max_speed: float = 0.25            # m/s, never exceeded by any commanded motion
    force_threshold: float = 5.0       # N, normal force that ends the descent
    max_force: float = 15.0            # N, exceeded -> abort and retract
    max_depth: float = 0.008           # m below the surface, descent stops here at the latest
    settle_s: float = 0.3              # s held at the press before capturing
    capture_window_s: float = 0.5      # s of frames the capture looks back over
    retries: int = 2                   # extra attempts after a failed press
    approach_deadline_s: float = 15.0
    descend_deadline_s: float = 6.0
    capture_deadline_s: float = 3.0
    retract_deadline_s: float = 10.0
    position_tolerance: float = 0.002  # m, "arrived" within this distance

    _RANGES = {
        "approach_height": (0.005, 0.3), "travel_speed": (0.001, 1.0),
        "descend_speed": (0.0005, 0.1), "max_speed": (0.001, 1.0),
        "force_threshold": (0.1, 50.0), "max_force": (0.2, 100.0), "max_depth": (0.0005, 0.05),
        "settle_s": (0.0, 10.0), "capture_window_s": (0.0, 10.0), "retries": (0, 10),
        "approach_deadline_s": (0.1, 600.0), "descend_deadline_s": (0.1, 600.0),
        "capture_deadline_s": (0.1, 60.0), "retract_deadline_s": (0.1, 600.0),
        "position_tolerance": (0.0001, 0.05),
    }


@dataclass(frozen=True)
class Platform:
    id: str
    position: tuple[float, float, float]   # m, surface centre in the base frame
    role: str = "comparison"               # reference | comparison
    sim_fabric: str = ""
    replay_class: str = ""
    radius: float = 0.04                   # m, half the fabric's side (contact region)


@dataclass(frozen=True)
class Scene:
    frame_id: str
    workspace_min: tuple[float, float, float]
    workspace_max: tuple[float, float, float]
    tool_orientation: tuple[float, float, float, float]
    press: PressSettings
    platforms: tuple[Platform, ...]
    source: str = ""

    @property
    def reference(self) -> Platform:
        return next(p for p in self.platforms if p.role == "reference")

    @property
    def comparisons(self) -> list[Platform]:
        return [p for p in self.platforms if p.role == "comparison"]

    @property
    def ordered(self) -> list[Platform]:
        """[reference, comparison 1..N]: platform index i of the trial engine."""
        return [self.reference] + self.comparisons

    def platform(self, pid: str) -> Platform:
        for p in self.platforms:
            if p.id == pid:
                return p
        raise TactexError(f"unknown platform {pid!r}; the scene has "
                          f"{[p.id for p in self.platforms]}")



def _vec(value: Any, n: int, where: str) -> tuple[float, ...]:
    try:
        arr = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        raise TactexError(f"{where}: expected {n} numbers, got {value!r}") from None
    if arr.shape != (n,) or not np.all(np.isfinite(arr)):
        raise TactexError(f"{where}: expected {n} finite numbers, got {value!r}")
    return tuple(float(v) for v in arr)


def _press(d: Any, where: str) -> PressSettings:
    if d is None:
        return PressSettings()
    if not isinstance(d, dict):
        raise TactexError(f"{where}: expected a mapping, got {type(d).__name__}")
    known = {f.name: f for f in fields(PressSettings)}
    kw = {}
    for k, v in d.items():
        if k not in known or k.startswith("_"):
            raise TactexError(f"{where}.{k}: unknown setting; known: "
                              f"{', '.join(n for n in known if not n.startswith('_'))}")
        want = int if k == "retries" else float
        if isinstance(v, bool) or not isinstance(v, (int, float)) or (want is int and
                                                                      not isinstance(v, int)):
            raise TactexError(f"{where}.{k}: expected {want.__name__}, got {v!r}")
        lo, hi = PressSettings._RANGES[k]
        if not lo <= v <= hi:
            raise TactexError(f"{where}.{k} = {v} outside [{lo}, {hi}]")
        kw[k] = want(v)
    s = PressSettings(**kw)
    if s.force_threshold >= s.max_force:
        raise TactexError(f"{where}.force_threshold ({s.force_threshold} N) must be below "
                          f"max_force ({s.max_force} N)")
    if s.travel_speed > s.max_speed or s.descend_speed > s.max_speed:
        raise TactexError(f"{where}: travel_speed and descend_speed must not exceed max_speed "
                          f"({s.max_speed} m/s)")
    return s


def parse_scene(data: Any, origin: str = "scene") -> Scene:
    """Validate a scene mapping; TactexError names the first bad field."""
    if not isinstance(data, dict):
        raise TactexError(f"{origin}: expected a mapping at the top level")
    allowed = {"frame_id", "workspace", "tool_orientation", "press", "platforms", "source"}
    for k in data:
        if k not in allowed:
            raise TactexError(f"{origin}: unknown field {k!r}; allowed: {sorted(allowed)}")
    frame_id = data.get("frame_id")
    if not isinstance(frame_id, str) or not frame_id:
        raise TactexError(f"{origin}: frame_id must be a non-empty string")
    ws = data.get("workspace")
    if not isinstance(ws, dict) or "min" not in ws or "max" not in ws:
        raise TactexError(f"{origin}: workspace needs min and max ([x, y, z] in metres)")
    wmin, wmax = _vec(ws["min"], 3, f"{origin}: workspace.min"), _vec(ws["max"], 3,
                                                                      f"{origin}: workspace.max")
    if not np.all(np.asarray(wmin) < np.asarray(wmax)):
        raise TactexError(f"{origin}: workspace.min must be below workspace.max on every axis")
    quat = _vec(data.get("tool_orientation", [1.0, 0.0, 0.0, 0.0]), 4,
                f"{origin}: tool_orientation")
    if abs(np.linalg.norm(quat) - 1.0) > 1e-3:
        raise TactexError(f"{origin}: tool_orientation must be a unit quaternion (x y z w)")
    press = _press(data.get("press"), f"{origin}: press")
    plats = data.get("platforms")
    if not isinstance(plats, list) or len(plats) < 3:
        raise TactexError(f"{origin}: platforms must list a reference and at least 2 "
                          "comparison platforms")
    out, seen = [], set()
    for i, p in enumerate(plats):
        where = f"{origin}: platforms[{i}]"
        if not isinstance(p, dict):
            raise TactexError(f"{where}: expected a mapping")
        unknown = set(p) - {"id", "role", "position", "sim_fabric", "replay_class", "radius"}
        if unknown:
            raise TactexError(f"{where}: unknown field(s) {sorted(unknown)}")
        pid = p.get("id")
        if not isinstance(pid, str) or not pid or not pid.replace("_", "").isalnum():
            raise TactexError(f"{where}.id: must be a non-empty name of letters, digits, _")
        if pid in seen:
            raise TactexError(f"{where}.id: duplicate platform id {pid!r}")
        seen.add(pid)
        role = p.get("role", "comparison")
        if role not in ("reference", "comparison"):
            raise TactexError(f"{where}.role: 'reference' or 'comparison', got {role!r}")
        pos = _vec(p.get("position"), 3, f"{where}.position")
        radius = p.get("radius", 0.04)
        if not isinstance(radius, (int, float)) or not 0.005 <= radius <= 0.2:
            raise TactexError(f"{where}.radius: metres in [0.005, 0.2], got {radius!r}")
        for high in (0.0, press.approach_height):
            probe = np.asarray(pos) + [0.0, 0.0, high]
            if not (np.all(probe >= wmin) and np.all(probe <= wmax)):
                raise TactexError(f"{where}.position {list(pos)} (approach height "
                                  f"{high} m above) lies outside the workspace "
                                  f"{list(wmin)}..{list(wmax)}")
        if pos[2] - press.max_depth < wmin[2]:
            raise TactexError(f"{where}.position: the deepest press ({press.max_depth} m below "
                              f"z={pos[2]}) lies below workspace.min z={wmin[2]}")
        out.append(Platform(id=pid, position=pos, role=role,
                            sim_fabric=str(p.get("sim_fabric", "")),
                            replay_class=str(p.get("replay_class", "")), radius=float(radius)))
    refs = [p for p in out if p.role == "reference"]
    if len(refs) != 1:
        raise TactexError(f"{origin}: platforms need exactly one role: reference, got {len(refs)}")
    if len(out) - 1 < 2:
        raise TactexError(f"{origin}: at least 2 comparison platforms are needed")
    source = data.get("source", "")
    if not isinstance(source, str):
        raise TactexError(f"{origin}: source must be a string (sim[:q] or replay:DIR)")
    return Scene(frame_id=frame_id, workspace_min=wmin, workspace_max=wmax,
                 tool_orientation=quat, press=press, platforms=tuple(out), source=source)


def load_scene(path: str | Path) -> Scene:
    """Read and validate a scene YAML file."""
    p = Path(path)
    if not p.is_file():
        raise TactexError(f"scene file {str(p)!r} not found")
    try:
        data = yaml.safe_load(p.read_text())
    except yaml.YAMLError as exc:
        raise TactexError(f"scene file {str(p)!r}: not valid YAML ({exc})") from None
    return parse_scene(data, origin=f"scene {p.name}")
