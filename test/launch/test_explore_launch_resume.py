"""launch_testing: ``ros2 launch tactex explore.launch.py sim:=true resume:=RECORD`` with a
stop threshold set at launch, three launches (``launch_testing.parametrize``):

- ``explorer_set``: ``explorer_set:="trial.stop_confidence=0.6"``, the record's threshold: the
  trial continues from the cut record and ends by that threshold, every process exits 0;
- ``argument``: the same threshold as the dotted argument ``trial.stop_confidence:=0.6``.

Another value than the record's is refused by the launch before any node starts
(``ros.run_settings.resolve_run``; test/unit/core/test_config.py).

The interrupted record is made before each launch, without ROS (``trial.run.TrialRun`` with
the simulator as press, cut off after 4 touches), with the settings the launch gives the
explorer (``ExplorerSettings.record_inputs``), so the resume is accepted. Run with
``launch_test test/launch/test_explore_launch_resume.py`` (see conftest.py).
"""

from __future__ import annotations

import contextlib
import json
import tempfile
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

RECORD = Path(tempfile.mkdtemp(prefix="tactex_launch_resume_"))
LAUNCH_FILE = Path(__file__).resolve().parents[2] / "launch" / "explore.launch.py"
STOP = 0.6
ARGS = {"sim": "true", "rounds": "20", "seed": "0", "exit_when_done": "true",
        "explorer_set": f"trial.stop_confidence={STOP}"}
CASES = {"explorer_set": {},
         "argument": {"explorer_set": "", "trial.stop_confidence": str(STOP)}}
CUT = 4


def _folder(case: str) -> Path:
    return RECORD / case / "cut"


def _interrupted_record(case: str) -> Path:
    """A record of the launch's trial (``ARGS``: threshold ``STOP``) in ``RECORD/case``, cut
    off after ``CUT`` touches (the process died)."""
    import importlib.util

    from tactex_ros.core.engine import TrialSpec
    from tactex_ros.core.touch import Touch, as_touch
    from tactex_ros.robot.scene import load_scene
    from tactex_ros.ros.settings import ExplorerSettings
    from tactex_ros.sources import open_source
    from tactex_ros.trial.run import TrialRun
    spec_ = importlib.util.spec_from_file_location("tactex_explore_launch", LAUNCH_FILE)
    mod = importlib.util.module_from_spec(spec_)
    spec_.loader.exec_module(mod)
    args = dict(ARGS, record_dir=str(RECORD / case))
    ex = next(n for n in mod.plan(args)["nodes"] if n.name == "explorer").parameters
    s = ExplorerSettings.check(ex, "explorer")
    ids = tuple(p.id for p in load_scene(s.scene_file).ordered)
    src = open_source("sim")
    comps = src.draw_scene(len(ids) - 1, 0)
    fn = src.trial([comps[0]] + comps, 0)
    n = [0]

    class Died(Exception):
        pass

    def press(platform: int, meta: dict) -> Touch:
        if n[0] >= CUT:
            raise Died()
        n[0] += 1
        return as_touch(fn(platform))
    run = TrialRun(TrialSpec(len(ids) - 1, s.learner, s.trial, seed=s.seed, platform_ids=ids),
                   RECORD / case, "cut", press=press, inputs=s.record_inputs(s.seed),
                   scene_file=s.scene_file)
    with contextlib.suppress(Died):
        run.run()
    return run.dir


@pytest.mark.launch_test
@launch_testing.parametrize("case", list(CASES))
def generate_test_description(case):
    folder = _interrupted_record(case)
    args = dict(ARGS, record_dir=str(RECORD / case), resume=str(folder), **CASES[case])
    include = IncludeLaunchDescription(PythonLaunchDescriptionSource(str(LAUNCH_FILE)),
                                       launch_arguments=args.items())
    return launch.LaunchDescription([include, launch_testing.actions.ReadyToTest()])


class TestResume(unittest.TestCase):
    def test_launch_ends(self, proc_info):
        proc_info.assertWaitForShutdown(process="explorer_node", timeout=300)


@launch_testing.post_shutdown_test()
class TestAfterShutdown(unittest.TestCase):
    def test_exit_codes(self, proc_info, case):
        launch_testing.asserts.assertExitCodes(proc_info, process="explorer_node")
        for other in ("mock_arm_node", "mock_image_node", "motion_node"):
            launch_testing.asserts.assertExitCodes(proc_info, process=other)

    def test_record(self, case):
        d = _folder(case)
        config = json.loads((d / "config.json").read_text())
        self.assertEqual(config["trial"]["stop_confidence"], STOP)
        touches = [json.loads(line) for line in (d / "touches.jsonl").read_text().splitlines()]
        result = json.loads((d / "result.json").read_text())
        self.assertEqual([r["after_touch"] for r in result["resumed"]], [CUT])
        self.assertGreater(len(touches), CUT)        # the recorded ones, then live presses
        self.assertEqual(result["touches"], sum(t["accepted"] for t in touches))
        # the verdict agrees with the threshold STOP: a confident stop is a sure one with a
        # final belief of at least STOP, any other end is not sure
        self.assertEqual(result["sure"], result["confidence"] >= STOP
                         and result["stop_reason"] == "confident")
        self.assertIn(result["stop_reason"], ("confident", "rounds"))
