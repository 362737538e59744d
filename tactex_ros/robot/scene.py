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

from dataclasses import dataclass
from pathlib import Path
from typing import Annotated, Any, Literal

import numpy as np
from pydantic import ConfigDict, Field, field_validator, model_validator

from ..core.contact import EXTRA_FRAMES
from ..core.schema import FieldError, Schema, param
from ..core.errors import InputError
from ..core.paths import read_yaml


FiniteFloat = Annotated[float, Field(allow_inf_nan=False)]
# a YAML list is taken for a tuple; its numbers are still checked strictly and must be finite
Vec3 = Annotated[tuple[FiniteFloat, FiniteFloat, FiniteFloat], Field(strict=False)]
Vec4 = Annotated[tuple[FiniteFloat, FiniteFloat, FiniteFloat, FiniteFloat], Field(strict=False)]


class PressSettings(Schema):
    """How a press is made; every phase has a deadline [s]."""

    model_config = ConfigDict(frozen=True)

    approach_height: float = param(0.05, "height above the surface where the descent starts [m]",
                                   0.005, 0.3)
    travel_speed: float = param(0.15, "speed of moves between platforms (also the speed cap) "
                                      "[m/s]", 0.001, 1.0)
    descend_speed: float = param(0.01, "speed of the descent where the surface may be (the "
                                       "speed at contact) [m/s]", 0.0005, 0.1)
    descend_fast_speed: float = param(
        0.0, "speed of the descent above the band where the surface may be (the expected "
             "surface plus its tolerance): it slows to descend_speed into the band; 0 = "
             "descend_speed all the way [m/s]", 0.0, 0.3)
    surface_tolerance: float = param(
        0.002, "the scene's surface heights are right to within this (a hand-guided "
               "measurement; tactex robot measure-scene: about 1 mm): the contact may come "
               "this far above the scene's surface [m]", 0.0, 0.05)
    found_tolerance: float = param(
        0.001, "the same for a surface an earlier press of the platform found: the approach "
               "point and the slow band are then lower by surface_tolerance - found_tolerance "
               "[m]", 0.0, 0.05)
    max_speed: float = param(0.25, "never exceeded by any commanded motion [m/s]", 0.001, 1.0)
    force_threshold: float = param(5.0, "normal force that ends the descent [N]", 0.1, 50.0)
    max_force: float = param(15.0, "exceeded -> abort and retract [N]", 0.2, 100.0)
    max_depth: float = param(0.008, "depth below the surface where the descent stops at the "
                                    "latest [m]", 0.0005, 0.05)
    settle_s: float = param(0.3, "held at the press before capturing [s]", 0.0, 10.0)
    capture_window_s: float = param(0.5, "frames the capture looks back over [s]", 0.0, 10.0)
    capture_frames: int = param(
        1 + EXTRA_FRAMES, "in-contact frames the capture returns, the strongest included: a "
                          "burst of consecutive sensor frames around it (about 0.16 s at the "
                          "GelSight Mini's 25 fps for 4 frames). Default 1 + the replay "
                          "source's extra frames per press (4), so every learner.descriptor_frames "
                          "gets on the robot the frames it gets offline from recorded presses "
                          "(descriptor_frames above 4 uses 4 there too); 1 = the strongest "
                          "alone", 1, 16)
    retries: int = param(2, "extra attempts after a failed press", 0, 10)
    approach_deadline_s: float = param(15.0, "deadline of the approach [s]", 0.1, 600.0)
    descend_deadline_s: float = param(6.0, "deadline of the descent [s]", 0.1, 600.0)
    capture_deadline_s: float = param(3.0, "deadline of the capture [s]", 0.1, 60.0)
    retract_deadline_s: float = param(10.0, "deadline of the retract [s]", 0.1, 600.0)
    position_tolerance: float = param(0.002, "'arrived' within this distance [m]", 0.0001, 0.05)
    tare_window_s: float = param(0.3, "before each descent, at the approach point and at rest, "
                                      "the wrench offset is the median normal force over this "
                                      "window [s]", 0.02, 5.0)
    tare_max_spread_n: float = param(0.5, "the tare settles when the normal force's spread "
                                          "(90th minus 10th percentile) over the window is at "
                                          "most this [N]", 0.01, 20.0)
    tare_max_motion_m: float = param(0.001, "at rest: the measured position moves at most this "
                                            "over the tare window [m]", 0.00005, 0.02)
    tare_max_offset_n: float = param(5.0, "an offset larger than this refuses the press (a "
                                          "payload or model error that large must be fixed "
                                          "first: the force limit acts on the tared force) [N]",
                                     0.1, 50.0)
    tare_deadline_s: float = param(3.0, "a tare that has not settled within this refuses the "
                                        "press [s]", 0.1, 60.0)
    surface_search: float = param(0.01, "the descent looks for the surface this far below "
                                         "the scene's surface (a surface lower than measured "
                                         "is still found) [m]", 0.0, 0.05)
    contact_force_n: float = param(1.0, "the smoothed tared normal force that says the sensor "
                                        "touched the surface (where it is found) [N]",
                                   0.05, 20.0)
    surface_warn_m: float = param(0.002, "a surface found farther than this from the scene's "
                                         "is reported (a warning in the touch) [m]",
                                  0.0001, 0.05)
    force_tolerance_n: float = param(0.5, "the hold captures once the smoothed force is this "
                                          "close to force_threshold, at rest, for settle_s "
                                          "[N]", 0.01, 10.0)
    hold_deadline_s: float = param(5.0, "a hold that has not reached the force within this "
                                        "(after settle_s) refuses the press [s]", 0.1, 60.0)
    rest_speed: float = param(0.002, "the arm is at rest below this measured speed [m/s]",
                              0.0001, 0.05)
    rest_s: float = param(0.3, "... for this long: an arm at rest within rest_tolerance of "
                               "its goal has arrived [s]", 0.0, 10.0)
    rest_tolerance: float = param(0.015, "farthest from its goal an arm at rest arrives (a "
                                         "static force, cable or friction holds it off) [m]",
                                  0.0001, 0.05)

    @model_validator(mode="after")
    def _limits(self) -> PressSettings:
        if self.contact_force_n >= self.force_threshold:
            raise FieldError("contact_force_n", f"{self.contact_force_n} N must be below "
                                                f"force_threshold ({self.force_threshold} N)")
        if self.rest_tolerance < self.position_tolerance:
            raise FieldError("rest_tolerance", f"{self.rest_tolerance} m must be at least "
                                               f"position_tolerance ({self.position_tolerance} m)")
        if self.force_threshold >= self.max_force:
            raise FieldError("force_threshold", f"{self.force_threshold} N must be below "
                                                f"max_force ({self.max_force} N)")
        if self.found_tolerance > self.surface_tolerance:
            raise FieldError("found_tolerance", f"{self.found_tolerance} m must be at most "
                                                f"surface_tolerance ({self.surface_tolerance} m)")
        if self.surface_tolerance >= self.approach_height:
            raise FieldError("approach_height", f"{self.approach_height} m must be above "
                                                f"surface_tolerance ({self.surface_tolerance} "
                                                "m): the surface may be that much higher than "
                                                "the scene says, so the approach point would "
                                                "be in it (measure the scene and lower "
                                                "surface_tolerance)")
        if self.surface_tolerance - self.found_tolerance >= self.approach_height:
            raise FieldError("surface_tolerance", f"{self.surface_tolerance} m minus "
                                                  f"found_tolerance ({self.found_tolerance} m) "
                                                  "must be below approach_height "
                                                  f"({self.approach_height} m): the approach "
                                                  "point above a found surface would be in it")
        for name in ("travel_speed", "descend_speed", "descend_fast_speed"):
            if getattr(self, name) > self.max_speed:
                raise FieldError(name, f"{getattr(self, name)} m/s exceeds max_speed "
                                       f"({self.max_speed} m/s)")
        return self


class Platform(Schema):
    """One platform: ``position`` is the centre of its fabric surface in the base frame [m]."""

    model_config = ConfigDict(frozen=True)

    id: str = param(..., "name of letters, digits and _")
    position: Vec3 = param(..., "surface centre in the base frame [m]")
    role: Literal["reference", "comparison"] = param("comparison", "reference or comparison")
    sim_fabric: str = param("", "catalogue fabric on this platform (simulated graph)")
    replay_class: str = param("", "recorded class on this platform (replayed graph)")
    radius: float = param(0.04, "half the fabric's side: the contact region [m]", 0.005, 0.2)

    @field_validator("id")
    @classmethod
    def _name(cls, v: str) -> str:
        if not v or not v.replace("_", "").isalnum():
            raise ValueError(f"must be a non-empty name of letters, digits, _ (got {v!r})")
        return v


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
        raise InputError(f"unknown platform {pid!r}; the scene has "
                         f"{[p.id for p in self.platforms]}")



class Workspace(Schema):
    """The box every commanded position stays in [m]."""

    min: Vec3 = param(..., "lower corner [x, y, z] in the base frame [m]")
    max: Vec3 = param(..., "upper corner [x, y, z] in the base frame [m]")

    @model_validator(mode="after")
    def _ordered(self) -> Workspace:
        if not all(lo < hi for lo, hi in zip(self.min, self.max, strict=True)):
            raise FieldError("min", f"{list(self.min)} must be below max {list(self.max)} on "
                                    "every axis")
        return self


class SceneFile(Schema):
    """The scene file as written (``config/scene.yaml``); ``parse_scene`` makes the Scene."""

    frame_id: str = param(..., "base frame of every position", min_length=1)
    workspace: Workspace
    tool_orientation: Vec4 = param((1.0, 0.0, 0.0, 0.0), "quaternion x y z w of the sensor "
                                                         "(pointing down)")
    press: PressSettings = Field(default_factory=PressSettings)
    platforms: list[Platform] = param(..., "a reference and at least 2 comparisons")
    source: str = param("", "touch source of the simulated graph: sim[:q] or replay:DIR")

    @field_validator("tool_orientation")
    @classmethod
    def _unit(cls, q: tuple) -> tuple:
        if abs(float(np.linalg.norm(q)) - 1.0) > 1e-3:
            raise ValueError(f"must be a unit quaternion (x y z w), got {list(q)}")
        return q

    @model_validator(mode="after")
    def _platforms(self) -> SceneFile:
        plats, ws, press = self.platforms, self.workspace, self.press
        refs = [p for p in plats if p.role == "reference"]
        if len(refs) != 1 or len(plats) - 1 < 2:
            raise FieldError("platforms", f"need exactly one role: reference and at least 2 "
                                          f"comparisons, got {len(refs)} reference(s) among "
                                          f"{len(plats)} platforms")
        seen: set[str] = set()
        for i, p in enumerate(plats):
            if p.id in seen:
                raise FieldError(f"platforms.{i}.id", f"duplicate platform id {p.id!r}")
            seen.add(p.id)
            for q in plats[:i]:      # each fabric its own place: a press finds one platform
                apart = float(np.hypot(p.position[0] - q.position[0],
                                       p.position[1] - q.position[1]))
                if apart < p.radius + q.radius:
                    raise FieldError(f"platforms.{i}.position",
                                     f"{list(p.position)} overlaps platform {q.id!r} at "
                                     f"{list(q.position)}: their centres are {apart:.3f} m "
                                     f"apart in x-y, less than their radii "
                                     f"({q.radius} + {p.radius} m)")
            for high in (0.0, press.approach_height):
                probe = np.asarray(p.position) + [0.0, 0.0, high]
                if not (np.all(probe >= ws.min) and np.all(probe <= ws.max)):
                    raise FieldError(f"platforms.{i}.position",
                                     f"{list(p.position)} (approach height {high} m above) "
                                     f"lies outside the workspace {list(ws.min)}..{list(ws.max)}")
            if p.position[2] - press.max_depth - press.surface_search < ws.min[2]:
                raise FieldError(f"platforms.{i}.position",
                                 f"the deepest press (max_depth {press.max_depth} m + "
                                 f"surface_search {press.surface_search} m below z="
                                 f"{p.position[2]}) lies below workspace.min z={ws.min[2]}")
        return self


def parse_scene(data: Any, origin: str = "scene") -> Scene:
    """Validate a scene mapping; InputError names every bad field (``platforms.2.position``)."""
    if not isinstance(data, dict):
        raise InputError(f"{origin}: expected a mapping at the top level")
    f = SceneFile.check(data, origin)
    return Scene(frame_id=f.frame_id, workspace_min=f.workspace.min,
                 workspace_max=f.workspace.max, tool_orientation=f.tool_orientation,
                 press=f.press, platforms=tuple(f.platforms), source=f.source)


def load_scene(path: str | Path) -> Scene:
    """Read and validate a scene YAML file."""
    if not str(path).strip():
        raise InputError("scene_file is empty: give the scene YAML (parameter scene_file, "
                          "e.g. config/scene_sim.yaml)")
    p = Path(path)
    if not p.is_file():
        raise InputError(f"scene file {str(p)!r} not found")
    return parse_scene(read_yaml(p, "scene file"), origin=f"scene {p.name}")
