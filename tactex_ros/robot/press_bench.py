"""The press benchmark (``tactex bench press``): the product's press controller (``robot.press``) in the mock world
(``robot.mock_world``), ROS-free, on a scene as shipped.

Each world is drawn from the stated ranges (``Faults.draw``; the apparent mass uniform in
``mass_kg``) and presses one platform twice, as a trial does: the first press knows only the
scene's surface (``surface_tolerance``), the second the surface the first found
(``found_tolerance``). Every press starts where the previous one ended (the retract point of
the platform before it in the scene, as between two touches of a trial), the controller's law
is the scene's robot profile's (CRISP's error clip, filters and clamp), a 25 fps camera streams
its contact verdict and the capture waits for its burst of in-contact frames.

Figures (``run``): ``worlds``, ``presses``, ``captured_share`` (presses whose true contact
force at capture is within ``force_tolerance_n`` of ``force_threshold``), ``named_refusals``
(count per reason, the text before the first ``:``), ``silent_wrong`` (a success at the wrong
true force), ``over_limit_samples`` (control cycles, 1 kHz, with the true contact force above
``max_force``), ``peak_force_n``, ``press_s_median`` / ``press_s_p95`` (approach start to
lift-off [s]) and the median of each phase [s]; each also for first and second presses apart.
"""

from __future__ import annotations

import collections
import time
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np

from ..core.errors import InputError
from .mock_world import Faults, WorldPress, press_in_worlds
from .robots import load_profile
from .scene import Scene, load_scene

#: the robot profile whose controller presses a scene, by the scene's base frame
PROFILE_BY_FRAME = {"fr3_link0": "fr3_crisp", "panda_link0": "panda_crisp"}
#: [kg] the apparent end-effector mass range (docs/simulated_world.md)
MASS_KG = (1.0, 5.0)
#: heavy-arm worlds: a 6 kg apparent mass with a 2-4 N static downward force (issue 46's case)
HEAVY_MASS_KG = 6.0
HEAVY_DOWN_N = (2.0, 4.0)
CAMERA_FPS = 25.0


def draw_worlds(n: int, seed: int, heavy: bool = False,
                surface_tolerance: float = 0.005) -> tuple[list[Faults], np.ndarray]:
    """``n`` worlds from ``Faults.draw`` and their masses [kg]; the surface off by at most the
    scene's ``surface_tolerance`` [m] (``Faults.draw``'s +-5 mm scaled to it: what the scene
    states); ``heavy``: the mass ``HEAVY_MASS_KG`` and the static force downward,
    ``HEAVY_DOWN_N``."""
    rng = np.random.default_rng(seed)
    worlds = [Faults.draw(rng) for _ in range(n)]
    worlds = [w.replace(surface_offset=w.surface_offset * surface_tolerance / 0.005)
              for w in worlds]
    mass = rng.uniform(*MASS_KG, n)
    if heavy:
        down = rng.uniform(*HEAVY_DOWN_N, n)
        worlds = [w.replace(static_force=(w.static_force[0], w.static_force[1], -float(d)))
                  for w, d in zip(worlds, down, strict=True)]
        mass = np.full(n, HEAVY_MASS_KG)
    return worlds, mass


def _start_points(scene: Scene, ids: list[str], found: list[float] | None) -> np.ndarray:
    """Where each press starts: the retract point (approach point) of the platform before it
    in the scene's order."""
    order = [p.id for p in scene.ordered]
    s = scene.press
    out = []
    for pid in ids:
        prev = scene.platform(order[(order.index(pid) - 1) % len(order)])
        z = prev.position[2] + s.approach_height
        if found is not None:
            z -= s.surface_tolerance - s.found_tolerance
        out.append([prev.position[0], prev.position[1], z])
    return np.asarray(out, dtype=float)


def _figures(scene: Scene, got: list[WorldPress]) -> dict[str, Any]:
    s = scene.press
    tol = s.force_tolerance_n
    ok = [g.outcome.success and abs(g.true_force_n - s.force_threshold) <= tol for g in got]
    wrong = [g.outcome.success and not k for g, k in zip(got, ok, strict=True)]
    reasons = collections.Counter(g.outcome.reason.split(":")[0] for g in got
                                  if not g.outcome.success)
    times = np.array([g.outcome.press_s for g in got if g.outcome.success])
    phases: dict[str, list[float]] = collections.defaultdict(list)
    for g in got:
        if g.outcome.success:
            for k, v in g.outcome.phase_s.items():
                phases[k].append(v)
    med = (lambda a: float(np.median(a)) if len(a) else float("nan"))
    return {
        "presses": len(got),
        "captured_share": float(np.mean(ok)) if got else float("nan"),
        "named_refusals": dict(sorted(reasons.items())),
        "unnamed_refusals": sum(1 for g in got if not g.outcome.success
                                and not g.outcome.reason),
        "silent_wrong": int(sum(wrong)),
        "over_limit_samples": int(sum(g.over_limit_samples for g in got)),
        "peak_force_n": float(max(g.peak_force_n for g in got)) if got else float("nan"),
        "reported_max_force_n": float(max(g.outcome.max_force_n for g in got)) if got
        else float("nan"),
        "press_s_median": med(times),
        "press_s_p95": float(np.percentile(times, 95)) if len(times) else float("nan"),
        "phase_s_median": {k: med(v) for k, v in phases.items()},
    }


def run(scene_file: str | Path, worlds: int = 1000, seed: int = 0, heavy: bool = False,
        approach_height: float | None = None, surface_tolerance: float | None = None,
        robot: str | None = None) -> dict[str, Any]:
    """The benchmark's figures (module docstring) for ``worlds`` worlds of seed ``seed``;
    ``approach_height``, ``surface_tolerance`` [m]: the scene's, changed (a lab that measured
    its scene and shortened the approach)."""
    if worlds < 1:
        raise InputError(f"--worlds: {worlds}; give at least 1")
    scene = load_scene(scene_file)
    change = {k: v for k, v in (("approach_height", approach_height),
                                ("surface_tolerance", surface_tolerance)) if v is not None}
    if change:
        if "surface_tolerance" in change:
            change["found_tolerance"] = min(scene.press.found_tolerance,
                                            change["surface_tolerance"])
        try:
            scene = replace(scene, press=scene.press.replace(**change))
        except ValueError as exc:
            raise InputError(f"--scene {scene_file} with {change}: {exc}") from None
    name = robot or PROFILE_BY_FRAME.get(scene.frame_id)
    if name is None:
        raise InputError(f"--scene {scene_file}: no robot profile presses frame "
                         f"{scene.frame_id!r} by default; give --robot (one of "
                         f"{', '.join(sorted(set(PROFILE_BY_FRAME.values())))} or a file)")
    prof = load_profile(name)
    law = prof.law
    faults, mass = draw_worlds(worlds, seed, heavy, scene.press.surface_tolerance)
    order = [p.id for p in scene.ordered]
    ids = [order[i % len(order)] for i in range(worlds)]
    t0 = time.perf_counter()
    first = press_in_worlds(scene, law, faults, ids, start=_start_points(scene, ids, None),
                            mass=mass, stiffness=prof.stiffness,
                            camera_fps=CAMERA_FPS)
    hints = [g.outcome.surface_z if g.outcome.success else None for g in first]
    second = press_in_worlds(scene, law, faults, ids, start=_start_points(scene, ids, hints),
                             mass=mass, stiffness=prof.stiffness,
                             camera_fps=CAMERA_FPS, surface_hints=hints)
    wall = time.perf_counter() - t0
    out = {"scene": str(scene_file), "robot": prof.name, "worlds": worlds, "seed": seed,
           "heavy": heavy, "approach_height": scene.press.approach_height,
           "surface_tolerance": scene.press.surface_tolerance,
           **_figures(scene, first + second),
           "first_press": _figures(scene, first), "second_press": _figures(scene, second),
           "wall_s": wall}
    return out


def report(out: dict[str, Any]) -> str:
    """The figures as lines for the terminal."""
    lines = [f"{out['scene']} ({out['robot']}), {out['worlds']} worlds (seed {out['seed']}"
             f"{', heavy arm' if out['heavy'] else ''}), approach_height "
             f"{out['approach_height']} m: {out['presses']} presses"]
    for label, f in (("all", out), ("first", out["first_press"]),
                     ("second", out["second_press"])):
        phases = ", ".join(f"{k} {v:.2f}" for k, v in f["phase_s_median"].items())
        lines.append(
            f"  {label:>6}: captured {f['captured_share']:.3f}, refusals "
            f"{f['named_refusals'] or 'none'}, silent_wrong {f['silent_wrong']}, "
            f"over_limit_samples {f['over_limit_samples']}, peak {f['peak_force_n']:.2f} N, "
            f"press {f['press_s_median']:.2f} s median / {f['press_s_p95']:.2f} s p95 "
            f"(phases: {phases})")
    return "\n".join(lines)
