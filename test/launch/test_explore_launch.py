"""launch_testing test of ``explore.launch.py sim:=true exit_when_done:=true`` (needs
launch_testing: a ROS 2 system; run it with ``launch_test test/launch/test_explore_launch.py``
or ``colcon test``; ``make test`` disables launch_testing's pytest plugin, see conftest.py).

The launch file starts the simulated graph; the test waits for the explorer to finish a short
trial, checks the published state, that the explorer's exit ends the launch (the launch's first
shutdown is the one the explorer's exit handler asked for; the other nodes are stopped by it),
that every process exits with status 0 (a -2 from a second SIGINT, or a traceback exit, fails),
and the trial record. The test waits for nothing after the explorer's exit while the launch
runs: launch_testing fails a run whose launch ends before its tests do, and the launch ends as
soon as the last node has exited.
"""

from __future__ import annotations

import json
import tempfile
import time
import unittest
from pathlib import Path

import pytest

pytest.importorskip(
    "launch_testing", reason="launch_testing is not installed (not on PyPI; ROS 2 system only)")
import launch  # noqa: E402
import launch_testing.actions  # noqa: E402
import launch_testing.asserts  # noqa: E402
from launch.actions import IncludeLaunchDescription  # noqa: E402
from launch.launch_description_sources import PythonLaunchDescriptionSource  # noqa: E402

RECORD = Path(tempfile.mkdtemp(prefix="tactex_launch_test_"))
LAUNCH_FILE = Path(__file__).resolve().parents[2] / "launch" / "explore.launch.py"
SHUTDOWNS: list[str] = []       # the reason of each shutdown event of the launch, in order


@pytest.mark.launch_test
def generate_test_description():
    from launch.actions import RegisterEventHandler
    from launch.event_handlers import OnShutdown
    include = IncludeLaunchDescription(
        PythonLaunchDescriptionSource(str(LAUNCH_FILE)),
        launch_arguments={"sim": "true", "rounds": "2", "seed": "0",
                          "record_dir": str(RECORD), "trial_id": "launch_test",
                          "exit_when_done": "true"}.items())
    return launch.LaunchDescription([
        RegisterEventHandler(OnShutdown(on_shutdown=lambda e, _: SHUTDOWNS.append(e.reason))),
        include, launch_testing.actions.ReadyToTest()])


def _launch_module():
    import importlib.util
    spec = importlib.util.spec_from_file_location("tactex_explore_launch_test", LAUNCH_FILE)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


class TestTrial(unittest.TestCase):
    def test_state_published_and_launch_ends(self, proc_info):
        import rclpy
        from tactex.msg import ExplorationState
        rclpy.init()
        node = rclpy.create_node("launch_test_listener")
        got = []
        node.create_subscription(ExplorationState, "/tactex/state", got.append, 10)
        end = time.monotonic() + 240.0
        try:
            while time.monotonic() < end and not (got and got[-1].done):
                rclpy.spin_once(node, timeout_sec=0.1)
        finally:
            node.destroy_node()
            rclpy.shutdown()
        self.assertTrue(got and got[-1].done, "no final exploration state within 240 s")
        self.assertAlmostEqual(sum(got[-1].belief), 1.0, places=3)
        # exit_when_done: the explorer exits (its exit ends the launch: TestAfterShutdown)
        proc_info.assertWaitForShutdown(process="explorer_node", timeout=60)


@launch_testing.post_shutdown_test()
class TestAfterShutdown(unittest.TestCase):
    def test_exit_codes(self, proc_info):
        # every process, status 0 only: -2 / -15 (killed by a signal) fail
        launch_testing.asserts.assertExitCodes(proc_info)

    def test_the_explorers_exit_ended_the_launch(self):
        self.assertTrue(SHUTDOWNS)
        self.assertEqual(SHUTDOWNS[0], _launch_module().node_exited("explorer", 0))

    def test_record_complete(self):
        result = json.loads((RECORD / "launch_test" / "result.json").read_text())
        touches = [json.loads(line) for line in
                   (RECORD / "launch_test" / "touches.jsonl").read_text().splitlines()]
        self.assertEqual(sum(t["accepted"] for t in touches), result["touches"])
        self.assertEqual(result["prediction"], "c1")
