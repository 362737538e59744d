"""Issue 50: one door into a trial. Every entrance (``tactex trial``, the launch file,
``tactex graph describe|run``, the explorer node) resolves a run's settings, new or resumed,
through one function, ``trial.settings.resolve_settings``; ``tactex trial`` keeps its options
in the record's run.json as the graph does, and a resume refuses a contradicting value,
naming both."""

from __future__ import annotations

import ast
import json
from pathlib import Path

import pytest

import tactex_ros
import tactex_ros.trial.settings as trial_settings
from tactex_ros.cli.main import _trial_request, build_parser, main
from tactex_ros.core.errors import InputError
from tactex_ros.trial.settings import ENTRANCE_KEY, RUN_FILE

PKG = Path(tactex_ros.__file__).resolve().parent
LAUNCH = PKG.parent / "launch" / "explore.launch.py"


def _callers(name: str) -> set[str]:
    """The product's files (and the launch file) that call a function ``name``."""
    out = set()
    for p in sorted(PKG.rglob("*.py")) + [LAUNCH]:
        for node in ast.walk(ast.parse(p.read_text(), str(p))):
            if isinstance(node, ast.Call):
                f = node.func
                if (f.id if isinstance(f, ast.Name) else getattr(f, "attr", None)) == name:
                    out.add(p.relative_to(PKG.parent).as_posix())
    return out


def test_every_entrance_calls_the_one_resolver():
    assert _callers("settings_from_record") == {"tactex_ros/trial/settings.py"}
    assert _callers("resolve_settings") == {"tactex_ros/ros/run_settings.py",
                                            "tactex_ros/cli/main.py"}
    assert _callers("resolve_run") == {"launch/explore.launch.py",
                                       "tactex_ros/cli/graph_commands.py",
                                       "tactex_ros/ros/nodes/explorer_node.py"}


def test_tactex_trial_and_the_graph_go_through_it(tmp_path: Path, monkeypatch, capsys) -> None:
    seen = []
    real = trial_settings.resolve_settings

    def spy(options, entrance):
        seen.append(entrance.name)
        return real(options, entrance)

    monkeypatch.setattr(trial_settings, "resolve_settings", spy)
    assert main(["trial", "--source", "sim:easy", "--rounds", "2", "--quiet",
                 "--record-dir", str(tmp_path)]) == 0
    assert main(["graph", "describe", "--sim"]) == 0
    assert seen == ["trial", "graph"]


def _short_trial(root: Path) -> Path:
    assert main(["trial", "--source", "sim:easy", "--rounds", "2", "--seed", "3", "--quiet",
                 "--set", "trial.stop_confidence=0", "--record-dir", str(root),
                 "--trial-id", "t"]) == 0
    return root / "t"


def _resume(d: Path, *more: str) -> tuple[dict, str | None]:
    return _trial_request(build_parser("trial").parse_args(["trial", "--resume", str(d),
                                                             *more]))


def test_tactex_trial_remembers_its_options_as_the_graph_does(tmp_path: Path) -> None:
    d = _short_trial(tmp_path)
    kept = json.loads((d / RUN_FILE).read_text())
    assert kept[ENTRANCE_KEY] == "trial"
    assert (kept["source"], kept["seed"], kept["rounds"], kept["comparisons"]) == \
        ("sim:easy", 3, 2, 4)
    flat, record = _resume(d)                       # nothing given but the record
    assert record == str(d.resolve())
    assert (flat["source"], flat["seed"], flat["trial.rounds"]) == ("sim:easy", 3, 2)
    assert flat["trial.stop_confidence"] == 0
    assert _resume(d, "--seed", "3", "--rounds", "2")[1] == record     # same values: fine


@pytest.mark.parametrize("run_file", [True, False])
def test_a_resume_refuses_a_contradicting_value_naming_both(tmp_path: Path,
                                                            run_file: bool) -> None:
    """With run.json (the option named) and without (a record made before: its config.json,
    the setting named)."""
    d = _short_trial(tmp_path)
    if not run_file:
        (d / RUN_FILE).unlink()
    for argv, given, recorded in ((["--seed", "4"], "4", "3"), (["--rounds", "5"], "5", "2"),
                                  (["--source", "sim:hard"], "'sim:hard'", "'sim:easy'"),
                                  (["--set", "trial.stop_confidence=0.5"], "0.5", "0")):
        with pytest.raises(InputError) as exc:
            _resume(d, *argv)
        assert f"{given} given" in str(exc.value) and f"= {recorded}" in str(exc.value)
    with pytest.raises(InputError) as exc:
        _resume(d, "--record-dir", str(tmp_path / "other"))
    assert str(tmp_path / "other") in str(exc.value) and str(tmp_path) in str(exc.value)


def test_a_record_continues_with_the_command_that_started_it(tmp_path: Path) -> None:
    from tactex_ros.cli.graph_commands import _nodes
    d = _short_trial(tmp_path)
    with pytest.raises(InputError) as exc:
        _nodes(build_parser("graph").parse_args(["graph", "run", "--resume", str(d)]))
    assert "tactex trial" in str(exc.value)
    (d / RUN_FILE).write_text(json.dumps({"sim": True, "source": "sim", "seed": 3}))
    with pytest.raises(InputError) as exc:             # a graph's run.json (no entrance)
        _resume(d)
    assert "tactex graph" in str(exc.value)
    with pytest.raises(InputError):
        _resume(tmp_path / "nothing_here")
