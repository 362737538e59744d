"""Issue 31, item 5: one graph per arm. A second tactex graph started on the ROS domain of a
running one is refused by its motion node's pre-flight (exit 2, the shared topic and the nodes
named) before it drives anything; the running motion node serves its own explorer's run and
rejects a press goal of another run."""

from __future__ import annotations

from pathlib import Path

import pytest

from tactex_ros.paths import config_dir
from tactex_ros.ros.graph import NodeSpec
from tactex_ros.ros.launcher import Graph

from .conftest import press_goal

pytestmark = [pytest.mark.ros, pytest.mark.slow]
SCENE = str(config_dir() / "scene_sim.yaml")
START_S = 180.0      # [s] a graph's start on a loaded machine (load 10 on 2 cores)


def _motion(**p) -> NodeSpec:
    return NodeSpec("motion_node", "motion", {"scene_file": SCENE, "robot": "sim",
                                              "preflight_deadline_s": 30.0, **p})


def test_a_second_graph_on_the_domain_is_refused(tmp_path: Path, domain_id, listener) -> None:
    arm = NodeSpec("mock_arm_node", "mock_arm", {"scene_file": SCENE})
    with Graph([arm, _motion()], tmp_path / "a", domain_id) as first:
        res = press_goal(listener, "c1", timeout=START_S, run_id="run-a")
        assert res is not None and res.success, res          # the first graph presses
        with Graph([_motion()], tmp_path / "b", domain_id) as second:
            assert second.wait("motion", START_S) == 2         # refused by its pre-flight
        log = (tmp_path / "b" / "motion.log").read_text(errors="replace")
        assert "/tactex/press/_action/status" in log or "target" in log
        assert first.wait("motion", 0.1) is None and first.wait("mock_arm", 0.1) is None
        # a second explorer's goal (another run) is refused; the first run is still served
        assert press_goal(listener, "c2", timeout=START_S, run_id="run-b") is None
        res = press_goal(listener, "c2", timeout=START_S, run_id="run-a")
        assert res is not None and res.success
