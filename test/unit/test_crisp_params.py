"""scripts/crisp_params.py: the traced list of CRISP's CartesianController declarations is
written from a checkout's generate_parameter_library file (names, defaults, bounds, lines), and
a checkout without that file is bad input (exit 2)."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import yaml

ROOT = Path(__file__).resolve().parents[2]
SCRIPT = ROOT / "scripts" / "crisp_params.py"

DECLARATION = """\
cartesian_controller:
  joints:
    type: string_array
  task:
    d_pos_x:
      type: double
      default_value: -1.0
      validation:
        bounds<>: [-1.0, 5000.0]
    error_clip:
      z:
        type: double
        default_value: 0.1
  nullspace:
    weights:
      __map_joints:
        value:
          type: double
          default_value: 1.0
"""


def _run(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, str(SCRIPT), *args], capture_output=True, text=True,
                          timeout=60)


def test_extract_writes_names_defaults_bounds_and_lines(tmp_path: Path) -> None:
    (tmp_path / "src").mkdir()
    (tmp_path / "src" / "cartesian_controller.yaml").write_text(DECLARATION)
    out = tmp_path / "list.yaml"
    r = _run("extract", str(tmp_path), "--rev", "abc1234", "--release", "9.9.9", "--out", str(out))
    assert r.returncode == 0, r.stderr
    doc = yaml.safe_load(out.read_text())
    assert (doc["rev"], doc["release"]) == ("abc1234", "9.9.9")
    got = {p["name"]: p for p in doc["parameters"]}
    assert list(got) == ["joints", "task.d_pos_x", "task.error_clip.z",
                         "nullspace.weights.__map_joints.value"]
    assert "default" not in got["joints"]                      # required: no default
    assert got["task.d_pos_x"]["default"] == -1.0
    assert got["task.d_pos_x"]["bounds"] == [-1.0, 5000.0]
    assert [p["line"] for p in got.values()] == [2, 5, 11, 17]


def test_extract_refuses_a_checkout_without_the_declaration(tmp_path: Path) -> None:
    r = _run("extract", str(tmp_path), "--rev", "x", "--release", "y",
             "--out", str(tmp_path / "o.yaml"))
    assert r.returncode == 2
    assert "cartesian_controller.yaml" in r.stderr
    assert not (tmp_path / "o.yaml").exists()


def test_the_committed_list_is_a_release_with_the_seven_sentinels() -> None:
    doc = yaml.safe_load((ROOT / "config" / "upstream" / "crisp_cartesian_controller.yaml")
                         .read_text())
    assert doc["release"] == "2.3.1" and len(doc["rev"]) == 40
    sentinels = [p["name"] for p in doc["parameters"] if p.get("default") == -1.0]
    assert len(sentinels) == 7 and "nullspace.damping" in sentinels
