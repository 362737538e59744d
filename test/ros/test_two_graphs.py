"""Issue 31, item 5: one graph per arm. A second tactex graph started on the ROS domain of a
running one is refused by its motion node's pre-flight (exit 2, the shared topic and the nodes
named) before it drives anything; the running motion node serves its own explorer's run and
rejects a press goal of another run."""

from __future__ import annotations

from pathlib import Path

import pytest

from tactex_ros.robot.robots import load_profile
from tactex_ros.ros.graph import describe
from tactex_ros.ros.devrun.launcher import Graph

pytestmark = [pytest.mark.ros, pytest.mark.slow]
START_S = 180.0      # [s] a graph's start on a loaded machine (load 10 on 2 cores)


def test_a_second_graph_on_the_domain_is_refused(tmp_path: Path, domain_id, press_as) -> None:
    graph = [n for n in describe(True, motion={"preflight_deadline_s": 30.0})
             if n.name in ("mock_arm", "mock_image", "motion")]
    with Graph(graph, tmp_path / "a", domain_id) as first:
        # taken and run (its capture may come before the mock camera is up: not asked here)
        assert press_as("c1", "run-a", START_S) is not None
        second_graph = [n for n in describe(True, motion={"preflight_deadline_s": 30.0})
                        if n.name == "motion"]               # its state: the first's arm
        with Graph(second_graph, tmp_path / "b", domain_id) as second:
            assert second.wait("motion", START_S) == 2         # refused by its pre-flight
        log = (tmp_path / "b" / "motion.log").read_text(errors="replace")
        assert load_profile("sim").target_topic in log      # the shared topic named
        assert all(first.wait(n.name, 0.1) is None for n in graph)   # the first runs on
        # a second explorer's goal (another run) is refused; the first run is still served
        assert press_as("c2", "run-b", START_S) is None
        res = press_as("c2", "run-a", START_S)
        assert res is not None and res.success, res


def test_another_graph_seen_after_the_preflight_ends_a_node_without_a_goal(
        tmp_path: Path, listener, active) -> None:
    """Discovery has no deadline: another publisher of the arm's target that appears after the
    pre-flight (here the test's node, with the controller's QoS depth) ends a motion node that
    has taken no goal yet, with exit status 2 and the topic named."""
    from geometry_msgs.msg import PoseStamped
    prof = load_profile("sim")
    graph = [n for n in describe(True, motion={"preflight_deadline_s": 30.0})
             if n.name in ("mock_arm", "motion")]
    with Graph(graph, tmp_path / "logs", listener.domain_id) as g:
        assert active("motion", START_S)
        listener.node.create_publisher(PoseStamped, prof.target_topic, 10)
        assert g.wait("motion", START_S) == 2
        assert g.wait("mock_arm", 0.1) is None              # the arm's node runs on
    log = (tmp_path / "logs" / "motion.log").read_text(errors="replace")
    assert prof.target_topic in log                         # the shared topic named
