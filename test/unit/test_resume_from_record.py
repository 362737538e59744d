"""Issue 29: a resume needs no option but the record. ``settings_from_record`` (the explorer
node's ``resume`` parameter and ``tactex graph run --resume`` both use it) takes the record's
settings; a value given as well that differs from the record's is refused, both values named."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from tactex_ros.core.errors import InputError
from tactex_ros.core.schema import flatten, nest
from tactex_ros.core.paths import config_dir
from tactex_ros.ros.settings import ExplorerSettings
from tactex_ros.trial.resume import record_scene, settings_from_record


def _record(tmp_path: Path) -> Path:
    """A trial record's config.json as the explorer writes it: seed 7, 3 rounds, random."""
    s = ExplorerSettings.check({"seed": 7, "scene_file": str(config_dir() / "scene_sim.yaml"),
                                "trial": {"rounds": 3, "strategy": "random"},
                                "press_timeout_s": 50.0})
    d = tmp_path / "runs" / "trial_a"
    d.mkdir(parents=True)
    (d / "config.json").write_text(json.dumps(s.record_inputs(7)))
    return d


def test_the_record_gives_every_setting_and_a_contradiction_is_refused(tmp_path) -> None:
    d = _record(tmp_path)
    unset = flatten(ExplorerSettings.check({}).model_dump())
    now = dict(unset, press_timeout_s=80.0)                  # where and how long: free
    out = settings_from_record(d, now, [unset])
    assert (out["seed"], out["trial.rounds"], out["trial.strategy"]) == (7, 3, "random")
    assert out["press_timeout_s"] == 80.0
    assert (out["resume"], out["record_dir"], out["trial_id"]) == (
        str(d.resolve()), str(d.parent.resolve()), "trial_a")
    ExplorerSettings.check(nest(out))                          # a valid node setting
    for key, value, was in (("seed", 8, 7), ("trial.rounds", 5, 3)):
        with pytest.raises(InputError) as err:
            settings_from_record(d, dict(unset, **{key: value}), [unset])
        assert f"{key} = {value!r}" in str(err.value) and f"{key} = {was!r}" in str(err.value)
    with pytest.raises(InputError, match="config.json"):
        settings_from_record(tmp_path, unset)
    assert record_scene(d) == str(config_dir() / "scene_sim.yaml")


def test_graph_run_resume_takes_the_record_and_refuses_a_contradiction(tmp_path) -> None:
    """``tactex graph run --resume`` builds the graph from the record with the same call."""
    from tactex_ros.cli.graph_commands import _nodes
    from tactex_ros.cli.main import build_parser
    d = _record(tmp_path)

    def explorer(*more: str) -> dict:
        args = build_parser().parse_args(["graph", "run", "--sim", "--resume", str(d), *more])
        return next(n for n in _nodes(args) if n.name == "explorer").parameters
    ex = explorer()
    assert (ex["seed"], ex["trial"]["rounds"], ex["trial"]["strategy"], ex["resume"]) == (
        7, 3, "random", str(d.resolve()))
    for more, named in ((["--set", "trial.rounds=5"], ("trial.rounds = 5", "trial.rounds = 3")),
                        (["--seed", "8"], ("seed = 8", "seed = 7"))):
        with pytest.raises(InputError) as err:
            explorer(*more)
        assert all(n in str(err.value) for n in named), err.value
