"""Measuring the scene's surfaces with light presses (``tactex robot measure-scene``), the pure
part: the light press's settings and the corrected scene file.

A light press is the scene's press with ``force_threshold`` lowered to ``force_n`` [N]
(``contact_force_n`` at most half of it) and ``surface_search`` widened to ``search_m`` [m]: it
finds each platform's surface (``PressController.surface_found``), holds the light force and
retracts without a frame. The scene file is then rewritten with each measured platform's
surface z; everything else stays as it was (comments are not kept).
"""

from __future__ import annotations

import copy
from typing import Any

from .press import PressSettings


def light_press(press: PressSettings, force_n: float, search_m: float) -> PressSettings:
    """The scene's press made light: threshold ``force_n`` [N], search ``search_m`` [m] past
    the scene's surface, and a descent deadline long enough for that search."""
    reach = press.approach_height + search_m + press.max_depth
    return press.replace(force_threshold=force_n, contact_force_n=min(press.contact_force_n,
                                                                      0.5 * force_n),
                         surface_search=search_m,
                         descend_deadline_s=max(press.descend_deadline_s,
                                                2.0 * reach / press.descend_speed + 2.0))


def corrected_scene(data: dict[str, Any], heights: dict[str, float]) -> dict[str, Any]:
    """A copy of the scene file's mapping ``data`` with the surface z [m] of each platform id
    in ``heights`` replaced (rounded to 0.1 mm)."""
    out = copy.deepcopy(data)
    for p in out.get("platforms", []):
        if p.get("id") in heights:
            x, y, _ = p["position"]
            p["position"] = [x, y, round(float(heights[p["id"]]), 4)]
    return out
