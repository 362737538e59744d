"""A press through the motion node in a faulty simulated world (real processes over DDS): the
mock arm's surfaces 4 mm below the scene's, a 2.5 N upward pull, a wrench bias with noise and
friction, the controller's stiffness clamped at 900 N/m with CRISP 2.3's filters. The press
finds the surface, reaches the force by feedback and reports the moved surface in the touch."""

from __future__ import annotations

from pathlib import Path

import pytest

from tactex_ros.robot.scene import load_scene
from tactex_ros.ros.graph import describe
from tactex_ros.ros.devrun.launcher import Graph

pytestmark = pytest.mark.ros

SHIFT = -0.004


def test_press_in_a_faulty_world(tmp_path: Path, listener, press) -> None:
    nodes = [n for n in describe(True, mock_arm={
        "surface_offset": SHIFT, "static_force_z": 2.5, "wrench_offset_x": 1.4,
        "wrench_offset_z": -1.7, "wrench_noise": 0.05, "coulomb_friction": 0.5,
        "max_stiffness": 900.0, "state_filter": 0.5, "output_filter": 0.5, "world_seed": 7})
             if n.name in ("mock_arm", "mock_image", "motion")]
    scene = load_scene(nodes[0].parameters["scene_file"])
    s = scene.press
    with Graph(nodes, tmp_path / "logs", listener.domain_id):
        res = press("c2", timeout=120.0)
    assert res is not None and res.success, res and res.reason
    t = res.touch
    assert abs(t.contact_force_n - s.force_threshold) <= s.force_tolerance_n
    assert t.surface_error_m == pytest.approx(SHIFT, abs=0.0007)
    assert t.surface_z == pytest.approx(scene.platform("c2").position[2] + SHIFT, abs=0.0007)
    assert t.warning.startswith("surface moved")
