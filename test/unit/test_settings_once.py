"""Issue 50: a run's settings are validated once, where they enter (``ros/run_settings.py``,
``resolve_run``), and are frozen typed objects after: on the launch path (the launch file's
arguments and plan, new and resumed), in ``tactex graph describe``, in ``tactex trial`` (its
record and report included) and on the explorer node's path (its parameters resolved, then its trial and engine built) the stop threshold (the trial
settings, ``TrialConfig``) and the learner model (the learner's settings) are each validated
exactly once. Every validation of a settings model runs its ``__init__`` (a nested one too),
so the test counts those."""

from __future__ import annotations

import importlib.util
import json
from contextlib import contextmanager
from pathlib import Path
from unittest import mock

from tactex_ros.core.config import LearnerBase, TrialConfig
from tactex_ros.core.schema import Schema, flatten, nest
from tactex_ros.core.paths import config_dir
from tactex_ros.ros.settings import ExplorerSettings

LAUNCH = Path(__file__).resolve().parents[2] / "launch" / "explore.launch.py"


def _launch():
    spec = importlib.util.spec_from_file_location("tactex_explore_launch_once", LAUNCH)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


@contextmanager
def validations():
    """{"stop threshold": n, "learner": n}: validations of the trial settings (which hold
    the stop threshold) and of the learner settings while the block runs."""
    n = {"stop threshold": 0, "learner": 0}
    init = Schema.__init__

    def counted(key):
        def __init__(self, **data):
            n[key] += 1
            init(self, **data)
        return __init__
    with mock.patch.object(TrialConfig, "__init__", counted("stop threshold")), \
            mock.patch.object(LearnerBase, "__init__", counted("learner")):
        yield n


ONCE = {"stop threshold": 1, "learner": 1}


def _record(tmp_path: Path) -> Path:
    """A trial record's config.json as the explorer writes it."""
    s = ExplorerSettings.check({"seed": 7, "scene_file": str(config_dir() / "scene_sim.yaml"),
                                "trial": {"rounds": 3, "stop_confidence": 0.8}})
    d = tmp_path / "runs" / "trial_a"
    d.mkdir(parents=True)
    (d / "config.json").write_text(json.dumps(s.record_inputs(7)))
    return d


def test_the_counter_counts_a_nested_validation():
    with validations() as n:
        ExplorerSettings.check({"trial": {"stop_confidence": 0.8}})
        ExplorerSettings.check({})
    assert n == {"stop threshold": 2, "learner": 2}


def test_the_launch_path_validates_each_once(tmp_path: Path) -> None:
    launch = _launch()
    with validations() as n:
        values = {name: default for name, default, _ in launch.arguments()}
        values.update(sim="true", rounds="3", record_dir=str(tmp_path),
                      explorer_set="trial.stop_confidence=0.95")
        p = launch.plan(values)
    assert n == ONCE
    assert next(x for x in p["nodes"] if x.name == "explorer").parameters["trial"][
        "stop_confidence"] == 0.95


def test_a_resumed_launch_validates_each_once(tmp_path: Path) -> None:
    launch = _launch()
    d = _record(tmp_path)
    with validations() as n:
        p = launch.plan({"sim": "true", "resume": str(d)})
    assert n == ONCE
    ex = next(x for x in p["nodes"] if x.name == "explorer").parameters
    assert ex["seed"] == 7 and ex["trial"]["stop_confidence"] == 0.8      # the record's


def test_graph_describe_validates_each_once(capsys) -> None:
    from tactex_ros.cli.main import main
    with validations() as n:
        assert main(["graph", "describe", "--sim", "--set", "trial.stop_confidence=0.7"]) == 0
    assert n == ONCE
    capsys.readouterr()


def test_the_explorer_nodes_path_validates_each_once(tmp_path: Path) -> None:
    """As the node configures: its parameters (all given, as a launch gives them) resolved
    (``ExplorerNode.load_settings``), then its trial opened (``TrialRun``: the engine and its
    learner built from the frozen settings)."""
    from tactex_ros.core.engine import TrialSpec
    from tactex_ros.ros.run_settings import resolve_run
    from tactex_ros.trial.run import TrialRun
    values = flatten(ExplorerSettings.check(
        {"scene_file": str(config_dir() / "scene_sim.yaml"), "record_dir": str(tmp_path),
         "trial": {"stop_confidence": 0.85}}).model_dump())
    with validations() as n:
        s = resolve_run(explorer=nest(values), defaults=values).explorer
        spec = TrialSpec(4, s.learner, s.trial, seed=s.seed,
                         platform_ids=("reference", "c1", "c2", "c3", "c4"))
        run = TrialRun(spec, tmp_path, "t", press=lambda p, meta: None,
                       inputs=s.record_inputs(s.seed))
    assert n == ONCE
    assert run.engine.trial_cfg.stop_confidence == 0.85


def test_tactex_trial_validates_each_once(tmp_path: Path) -> None:
    """``tactex trial``: its options checked once, its record and report written after."""
    from tactex_ros.cli.main import main
    with validations() as n:
        assert main(["trial", "--source", "sim:easy", "--rounds", "2", "--quiet",
                     "--record-dir", str(tmp_path)]) == 0
    assert n == ONCE
