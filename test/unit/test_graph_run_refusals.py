"""Issue 21's `tactex graph run` cases that are refused before any node starts (fast lane, no
graph): exit status 2, the path or option named on the console, no log folder made (no node
was started), nothing in the record changed."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from tactex_ros.cli.main import main
from tactex_ros.core.config import preset, trial_preset
from tactex_ros.core.paths import config_dir
from tactex_ros.trial.record import TrialRecord


def _record(root: Path, name: str = "t", touches: int = 2) -> Path:
    rec = TrialRecord(root, name)
    rec.save_inputs(config_dir() / "scene_sim.yaml",
                    {"explorer": {"config": "default", "seed": 0},
                           "learner": preset("default").model_dump(),
                           "trial": trial_preset("default").model_dump()})
    for i in range(touches):
        rec.add_touch(np.full((240, 320, 3), 40 * i, np.uint8),
                      {"platform_index": i, "platform_id": "reference" if i == 0 else f"c{i}",
                       "accepted": True})
    return rec.dir


def _missing_png(root: Path) -> tuple[list[str], str]:
    d = _record(root)
    png = sorted(d.glob("touch_*.png"))[0]
    png.unlink()
    return ["--resume", str(d)], png.name


def _empty_touches(root: Path) -> tuple[list[str], str]:
    d = _record(root)
    for r in range(2):
        with open(d / "decisions.jsonl", "a") as f:
            f.write(json.dumps({"round": r + 1}) + "\n")
    (d / "touches.jsonl").write_text("")
    return ["--resume", str(d)], "decisions.jsonl"


def _finished(root: Path) -> tuple[list[str], str]:
    d = _record(root)
    TrialRecord(root, "t", resume=True).finish({"prediction": "c1"})
    return ["--resume", str(d)], str(d)


def _no_scene(root: Path) -> tuple[list[str], str]:
    d = _record(root)
    (d / "scene.yaml").unlink()
    return ["--resume", str(d)], "scene"


def _not_a_record(root: Path) -> tuple[list[str], str]:
    (root / "empty").mkdir()
    return ["--resume", str(root / "empty")], "config.json"


def _record_dir_under_a_file(root: Path) -> tuple[list[str], str]:
    (root / "a_file").write_text("x")
    return ["--record-dir", str(root / "a_file" / "rec"), "--trial-id", "t"], "record_dir"


def _trial_id_with_a_path(root: Path) -> tuple[list[str], str]:
    return ["--record-dir", str(root / "rec"), "--trial-id", "../../x"], "trial_id"


def _reused_trial_id(root: Path) -> tuple[list[str], str]:
    _record(root / "rec")
    return ["--record-dir", str(root / "rec"), "--trial-id", "t"], "already exists"


def _unknown_sensor(root: Path) -> tuple[list[str], str]:
    return ["--sensor", "nope"], "'nope'"                 # validated in simulation too


@pytest.mark.parametrize("case", [_unknown_sensor, _missing_png, _empty_touches, _finished, _not_a_record,
                                  _no_scene,
                                  _record_dir_under_a_file, _trial_id_with_a_path,
                                  _reused_trial_id])
def test_graph_run_refuses_before_any_node(tmp_path: Path, capsys, case) -> None:
    args, named = case(tmp_path)
    before = {p: p.read_bytes() for p in tmp_path.rglob("*") if p.is_file()}
    logs = tmp_path / "logs"
    assert main(["graph", "run", "--sim", "--log-dir", str(logs)] + args) == 2
    err = capsys.readouterr().err
    assert named in err and "Traceback" not in err
    assert not logs.exists()                                   # no node was started
    assert {p: p.read_bytes() for p in tmp_path.rglob("*") if p.is_file()} == before


def test_resume_hint_is_the_record_alone(tmp_path: Path) -> None:
    """After a run-time failure the hint continues the record with nothing but ``--resume``
    (the record keeps the run's options); after a node's refusal (exit 2) or a finished
    record, no hint."""
    from argparse import Namespace
    from types import SimpleNamespace

    from tactex_ros.cli.graph_commands import resume_hint
    d = _record(tmp_path)
    args = Namespace(sim=False, source=None, sensor="gelsight_mini", device="/dev/video 2")
    run = SimpleNamespace(record=d, node_exit={"gelsight": 1, "explorer": 0})
    assert resume_hint(run, args) == f"tactex graph run --resume {d}"
    assert resume_hint(SimpleNamespace(record=d, node_exit={"gelsight": 2}), args) is None
    (d / "result.json").write_text(json.dumps({"prediction": "c1", "touches": 2}))
    assert resume_hint(run, args) is None


def _run_args(argv: list[str]):
    from tactex_ros.cli.main import build_parser
    return build_parser("graph").parse_args(["graph", "run"] + argv)


def test_resume_takes_every_option_from_the_record(tmp_path: Path, capsys) -> None:
    """A run's options (settings, seed, sim, mock camera source, --yes) go into the record's
    run.json; ``--resume DIR`` alone gets them back; an option given again with another value
    is refused before anything starts (exit 2, both values named); the same value is fine."""
    from tactex_ros.cli.graph_commands import _nodes
    from tactex_ros.ros.run_settings import save_run_file
    from tactex_ros.core.errors import InputError
    first = _run_args(["--sim", "--rounds", "3", "--seed", "4", "--source", "sim", "--yes",
                       "--set", "trial.stop_confidence=0.95"])
    d = _record(tmp_path)
    cfg = json.loads((d / "config.json").read_text())
    cfg["explorer"]["seed"], cfg["trial"]["rounds"] = 4, 3
    cfg["trial"]["stop_confidence"] = 0.95
    (d / "config.json").write_text(json.dumps(cfg))
    _nodes(first)
    save_run_file(d, first.run)

    again = _run_args(["--resume", str(d)])
    nodes = {n.name: n.parameters for n in _nodes(again)}
    assert (again.sim, again.rounds, again.seed, again.source, again.yes) == \
        (True, 3, 4, "sim", True)
    assert again.set == ["trial.stop_confidence=0.95"]
    assert nodes["explorer"]["trial"]["rounds"] == 3 and nodes["explorer"]["seed"] == 4
    assert nodes["explorer"]["resume"] == str(d.resolve())
    assert nodes["mock_image"]["source"] == "sim"            # the sim graph, from the record
    _nodes(_run_args(["--resume", str(d), "--rounds", "3", "--sim"]))     # same values: fine

    for argv, given, recorded in ((["--rounds", "7"], "7", "3"), (["--seed", "9"], "9", "4"),
                                  (["--source", "replay"], "'replay'", "'sim'")):
        with pytest.raises(InputError) as exc:
            _nodes(_run_args(["--resume", str(d)] + argv))
        assert f"{given} given" in str(exc.value) and f"= {recorded}" in str(exc.value)
    logs = tmp_path / "logs"
    assert main(["graph", "run", "--resume", str(d), "--rounds", "7", "--log-dir",
                 str(logs)]) == 2
    err = capsys.readouterr().err
    assert "7" in err and "3" in err and not logs.exists()   # before any node or prompt


def test_session_dir_alone_continues_the_session_with_its_options(tmp_path: Path) -> None:
    """`--session-dir DIR` of a session folder holding run.json: the trial file, rounds, seed,
    sim graph and --yes come back from it; another --rounds is refused, both values named."""
    from tactex_ros.cli.graph_commands import _nodes
    from tactex_ros.ros.run_settings import save_run_file
    from tactex_ros.core.errors import InputError
    short = Path(__file__).parents[1] / "data" / "session_short.yaml"
    d = tmp_path / "sess"
    first = _run_args(["--sim", "--session", str(short), "--session-dir", str(d),
                       "--rounds", "3", "--seed", "0", "--yes"])
    _nodes(first)
    save_run_file(d, first.run)
    again = _run_args(["--session-dir", str(d)])
    ex = next(n.parameters for n in _nodes(again) if n.name == "explorer")
    assert (again.session, again.rounds, again.seed, again.sim, again.yes) == \
        (str(short.resolve()), 3, 0, True, True)
    assert ex["session_file"] == str(short.resolve()) and ex["trial"]["rounds"] == 3
    with pytest.raises(InputError) as exc:
        _nodes(_run_args(["--session-dir", str(d), "--rounds", "5"]))
    assert "5 given" in str(exc.value) and "= 3" in str(exc.value)
