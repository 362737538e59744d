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
from tactex_ros.paths import config_dir
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


def test_resume_hint_repeats_this_runs_device_options(tmp_path: Path) -> None:
    """After a run-time failure the hint continues the record with the device options given
    (not kept in the record); after a node's refusal (exit 2) or a finished record, no hint."""
    from argparse import Namespace
    from types import SimpleNamespace

    from tactex_ros.cli.graph_commands import resume_hint
    d = _record(tmp_path)
    args = Namespace(sim=False, source=None, sensor="gelsight_mini", device="/dev/video 2")
    run = SimpleNamespace(record=d, node_exit={"gelsight": 1, "explorer": 0})
    assert resume_hint(run, args) == (f"tactex graph run --sensor gelsight_mini "
                                      f"--device '/dev/video 2' --resume {d}")
    assert resume_hint(SimpleNamespace(record=d, node_exit={"gelsight": 2}), args) is None
    (d / "result.json").write_text(json.dumps({"prediction": "c1", "touches": 2}))
    assert resume_hint(run, args) is None
