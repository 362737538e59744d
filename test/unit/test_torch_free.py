"""Nodes that do not learn must not import torch or the learner: each module below is imported
in a fresh interpreter and ``sys.modules`` is checked. The launch file imports ``launch`` (not
installable here), so its tactex imports are read from its source and checked the same way."""

from __future__ import annotations

import ast
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
FORBIDDEN = ("torch", "tactex_ros.core.learner", "tactex_ros.core.models",
             "tactex_ros.core.engine", "tactex_ros.core.uncertainty",
             "tactex_ros.core.strategies")
MODULES = ["tactex_ros.ros.nodes.motion_node", "tactex_ros.ros.nodes.mock_arm_node",
           "tactex_ros.ros.nodes.gelsight_node", "tactex_ros.ros.nodes.mock_image_node",
           "tactex_ros.ros.graph", "tactex_ros.robot.robots", "tactex_ros.ros.settings",
           "tactex_ros.ros.adapter", "tactex_ros.robot.press", "tactex_ros.robot.scene",
           "tactex_ros.robot.frames", "tactex_ros.robot.sensors"]


def _launch_imports() -> list[str]:
    tree = ast.parse((ROOT / "launch" / "explore.launch.py").read_text())
    mods = {n.module for n in ast.walk(tree) if isinstance(n, ast.ImportFrom) and n.module}
    mods |= {a.name for n in ast.walk(tree) if isinstance(n, ast.Import) for a in n.names}
    return sorted(m for m in mods if m.startswith("tactex_ros"))


def _loaded(module: str) -> list[str]:
    code = ("import importlib, sys; importlib.import_module(%r); "
            "print('\\n'.join(sorted(sys.modules)))" % module)
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         timeout=120, cwd=ROOT)
    assert out.returncode == 0, out.stderr
    return out.stdout.split()


@pytest.mark.parametrize("module", MODULES + _launch_imports())
def test_module_does_not_import_torch_or_the_learner(module: str) -> None:
    bad = [m for m in _loaded(module)
           if any(m == f or m.startswith(f + ".") for f in FORBIDDEN)]
    assert not bad, f"{module} imports {bad}"


def test_mock_image_sources_do_not_import_torch() -> None:
    """What the mock image node loads at configure time: the simulator source and a press."""
    code = ("import sys, numpy as np; from tactex_ros.sources import open_source; "
            "src = open_source('sim'); src.press('satin', np.random.default_rng(0)); "
            "import tactex_ros.sources.replay; "
            "print('\\n'.join(sorted(sys.modules)))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         timeout=120, cwd=ROOT)
    assert out.returncode == 0, out.stderr
    bad = [m for m in out.stdout.split() if any(m == f or m.startswith(f + ".")
                                                for f in FORBIDDEN)]
    assert not bad, bad


def test_launch_file_imports_were_found() -> None:
    assert "tactex_ros.ros.graph" in _launch_imports()


def test_names_match_the_learning_code() -> None:
    from tactex_ros.core import models, names, preprocess, strategies
    assert names.MODEL_NAMES == models.MODEL_NAMES
    assert set(names.STRATEGY_NAMES) == set(strategies.STRATEGIES)
    assert (names.FRAME_H, names.FRAME_W) == (preprocess.FRAME_H, preprocess.FRAME_W)
