"""The product runs the shipped method without torch: the engine, every node (the explorer under
the default configuration included), the command line and the launch file's imports load neither
torch nor the lab (``tactex_lab``). Each module below is imported in a fresh interpreter and
``sys.modules`` is checked; the launch file imports ``launch`` (not installable here), so its
tactex imports are read from its source and checked the same way. The thesis method is one
option away: the same engine with ``config seed_faithful`` loads the lab's learner (and torch)."""

from __future__ import annotations

import ast
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
FORBIDDEN = ("torch", "tactex_lab")
MODULES = ["tactex_ros.core.engine", "tactex_ros.ros.nodes.explorer_node",
           "tactex_ros.cli.main", "tactex_ros.sources",
           "tactex_ros.ros.nodes.motion_node", "tactex_ros.ros.nodes.mock_arm_node",
           "tactex_ros.ros.nodes.gelsight_node", "tactex_ros.ros.nodes.mock_image_node",
           "tactex_ros.ros.graph", "tactex_ros.robot.robots", "tactex_ros.ros.settings",
           "tactex_ros.ros.adapter", "tactex_ros.robot.press", "tactex_ros.robot.mock_world",
           "tactex_ros.robot.scene",
           "tactex_ros.robot.frames", "tactex_ros.robot.sensors"]


def _launch_imports() -> list[str]:
    tree = ast.parse((ROOT / "launch" / "explore.launch.py").read_text())
    mods = {n.module for n in ast.walk(tree) if isinstance(n, ast.ImportFrom) and n.module}
    mods |= {a.name for n in ast.walk(tree) if isinstance(n, ast.Import) for a in n.names}
    return sorted(m for m in mods if m.startswith("tactex_ros"))


def _run(code: str) -> list[str]:
    """``sys.modules`` after ``code`` in a fresh interpreter (run from the repository)."""
    out = subprocess.run([sys.executable, "-c", code + "\nimport sys; "
                          "print('\\n'.join(sorted(sys.modules)))"], capture_output=True,
                         text=True, timeout=120, cwd=ROOT)
    assert out.returncode == 0, out.stderr
    return out.stdout.split()


def _forbidden(modules: list[str]) -> list[str]:
    return [m for m in modules if any(m == f or m.startswith(f + ".") for f in FORBIDDEN)]


def _loaded(module: str) -> list[str]:
    return _run(f"import importlib; importlib.import_module({module!r})")


def test_no_module_imports_torch_or_the_lab() -> None:
    """The modules are imported one after another in one interpreter; the first one after
    which a forbidden module is loaded is named."""
    code = ("import importlib, sys\n"
            f"for m in {MODULES + _launch_imports()!r}:\n"
            "    importlib.import_module(m)\n"
            "    bad = [k for k in sys.modules if any(k == f or k.startswith(f + '.') "
            f"for f in {FORBIDDEN!r})]\n"
            "    if bad:\n"
            "        print(m, 'imports', sorted(bad)[:5]); break\n"
            "else:\n"
            "    print('clean')")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         timeout=120, cwd=ROOT)
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip() == "clean"


@pytest.mark.slow
def test_the_check_names_a_module_that_imports_torch() -> None:
    bad = _forbidden(_loaded("tactex_lab.cnn.uncertainty"))
    assert "torch" in bad and "tactex_lab" in bad


@pytest.mark.slow
def test_mock_image_sources_do_not_import_torch() -> None:
    """What the mock image node loads at configure time: the simulator source and a press."""
    bad = _forbidden(_run("import numpy as np; from tactex_ros.sources import open_source; "
                          "src = open_source('sim'); src.press('satin', np.random.default_rng(0)); "
                          "import tactex_ros.sources.replay"))
    assert not bad, bad


# a trial's engine as the explorer node builds it (``ExplorerNode``: TrialSettings -> TrialEngine)
ENGINE = ("from tactex_ros.core.config import TrialSettings; "
          "from tactex_ros.core.engine import TrialEngine; "
          "s = TrialSettings.check({'config': %r}, 'test'); "
          "TrialEngine(4, s.learner, s.trial, seed=0)")


def test_the_default_trial_engine_loads_no_torch() -> None:
    bad = _forbidden(_run(ENGINE % "default"))
    assert not bad, bad


@pytest.mark.slow
def test_the_thesis_method_is_one_option_away() -> None:
    """``config seed_faithful`` finds the lab's CNN learner through its entry point."""
    loaded = _run(ENGINE % "seed_faithful")
    assert "torch" in loaded and "tactex_lab.cnn.learner" in loaded


def test_launch_file_imports_were_found() -> None:
    assert "tactex_ros.ros.graph" in _launch_imports()


@pytest.mark.parametrize("argv, absent", [
    (["--help"], ("numpy", "pydantic", "torch", "tactex_lab.experiments")),
    (["trial", "--help"], ("numpy", "torch", "tactex_lab", "tactex_ros.core.plugins")),
])
def test_help_imports_only_what_it_shows(argv, absent) -> None:
    """Start-up: ``tactex --help`` lists the commands without building their options; ``tactex
    trial --help`` builds only the trial's (from the schema, without numpy) and looks up no
    plug-in (no plug-in extends ``trial``)."""
    loaded = _run("import contextlib, io; from tactex_ros.cli.main import main\n"
                  "with contextlib.redirect_stdout(io.StringIO()), "
                  f"contextlib.suppress(SystemExit):\n    main({argv!r})")
    assert not [m for m in loaded if any(m == a or m.startswith(a + ".") for a in absent)]
