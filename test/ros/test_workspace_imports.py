"""The nodes and ``tactex --help`` start with only what a ROS 2 workspace install gives them:
the Python packages of package.xml's run-time rosdep keys and of requirements-ros.txt
(docs/install.md), each with what it requires. Every other third-party module of this
environment is refused in the processes by an import hook (a ``sitecustomize`` on PYTHONPATH),
as if it were not installed."""

from __future__ import annotations

import importlib.util
import json
import os
import subprocess
import sys
import time
from importlib import metadata
from pathlib import Path

import cv2
import numpy as np
import pytest
import yaml
from packaging.utils import canonicalize_name
from rclpy.qos import qos_profile_sensor_data
from sensor_msgs.msg import Image

from tactex_ros.ros.graph import NodeSpec, describe
from tactex_ros.ros.devrun.launcher import Graph
from tactex_ros.ros.settings import IMAGE_TOPIC

pytestmark = pytest.mark.ros

ROOT = Path(__file__).resolve().parents[2]
#: the PyPI distribution standing in here for the system package of each python3-* rosdep key
#: (on Ubuntu and Debian: apt's python3-numpy, ...; rosdep_keys.yaml)
SYSTEM_KEYS = {"python3-numpy": "numpy", "python3-opencv": "opencv-python-headless",
               "python3-yaml": "pyyaml", "python3-pydantic": "pydantic", "python3-scipy": "scipy",
               "python3-skimage": "scikit-image", "python3-pil": "pillow",
               "python3-numba": "numba", "python3-rich": "rich"}
#: first-party: the package's own Python packages (tactex: its generated interfaces) and the
#: modules Python's start-up looks for
OWN = {"tactex", "tactex_ros", "tactex_lab", "sitecustomize", "usercustomize"}
DISTRO = "kilted"                  # the ROS 2 wheels of this environment
START_S = 120.0                    # [s] every node up, on a loaded 2-core machine

HOOK = '''\
"""Test hook (test/ros/test_workspace_imports.py): a top-level module outside the workspace
install's packages is not found, as if it were not installed; each refusal of a module that
is installed here is logged."""
import site
import sys

SITE = tuple(site.getsitepackages())
ALLOWED = frozenset({allowed!r})
LOG = {log!r}


class _WorkspaceOnly:
    @staticmethod
    def find_spec(name, path=None, target=None):
        if "." in name or name in ALLOWED or name in sys.stdlib_module_names:
            return None                 # a submodule: its package was let through
        spec = next(filter(None, (f.find_spec(name, path, target) for f in sys.meta_path
                                  if f is not _WorkspaceOnly and hasattr(f, "find_spec"))),
                    None)
        if spec is None or not spec.origin or not spec.origin.startswith(SITE):
            return None                 # not installed here, or Python's own
        with open(LOG, "a") as f:
            f.write(name + "\\n")
        raise ModuleNotFoundError(f"No module named {{name!r}} (not in the workspace install)",
                                  name=name)


sys.meta_path.insert(0, _WorkspaceOnly)
'''


def _load(path: Path, name: str):
    spec = importlib.util.spec_from_file_location(name, path)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def workspace_distributions() -> set[str]:
    """The canonical names of the distributions a workspace install gives the package: its
    run-time rosdep keys on ``DISTRO`` (a ROS package: this environment's ``ros-<name>`` wheel;
    a pip rule: its packages; a system package: ``SYSTEM_KEYS``), requirements-ros.txt's pins,
    and everything those require."""
    from catkin_pkg.package import parse_package

    reqs = _load(ROOT / "test" / "unit" / "test_requirements.py", "_requirements")
    rules = yaml.safe_load((ROOT / "rosdep_keys.yaml").read_text())["keys"]
    pkg = parse_package(str(ROOT / "package.xml"))
    env = {"ROS_DISTRO": DISTRO, "ROS_VERSION": "2", "ROS_PYTHON_VERSION": "3"}
    names: set[str] = set()
    unknown = []
    for dep in pkg.exec_depends + pkg.build_export_depends:
        dep.evaluate_condition(env)
        if not dep.evaluated_condition:
            continue
        rule = rules[dep.name][DISTRO]["ubuntu:noble"] or ""
        if rule.startswith("pip: "):
            names.update(rule.removeprefix("pip: ").split())
        elif dep.name.startswith("python3-"):
            if dep.name not in SYSTEM_KEYS:
                unknown.append(dep.name)
            names.add(SYSTEM_KEYS.get(dep.name, dep.name))
        else:   # a ROS package; one not installed here gives no module here either
            names.update(f"ros-{p}{dep.name}".replace("_", "-") for p in ("", f"{DISTRO}-"))
    assert unknown == [], f"add the stand-in of these rosdep keys to SYSTEM_KEYS: {unknown}"
    names.update(r.name for r in reqs._pins(ROOT / "requirements-ros.txt"))
    from packaging.requirements import Requirement
    return reqs._closure([Requirement(n) for n in names])


def allowed_modules() -> set[str]:
    """Top-level module names of the workspace install's distributions, and the package's own."""
    dists = workspace_distributions()
    return OWN | {top for top, owners in metadata.packages_distributions().items()
                  if any(canonicalize_name(d) in dists for d in owners)}


@pytest.fixture
def workspace_env(tmp_path: Path) -> tuple[dict[str, str], Path]:
    """(environment whose Python processes import only the workspace install's modules, the
    log of refused imports)."""
    site = tmp_path / "site"
    site.mkdir()
    log = tmp_path / "refused.txt"
    (site / "sitecustomize.py").write_text(HOOK.format(allowed=sorted(allowed_modules()),
                                                       log=str(log)))
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join([str(site), *filter(None, [env.get("PYTHONPATH")])])
    return env, log


def _refused(log: Path) -> list[str]:
    return sorted(set(log.read_text().split())) if log.exists() else []


def test_the_hook_refuses_a_module_outside_the_workspace(workspace_env) -> None:
    env, log = workspace_env
    code = ("import importlib.util as u, numpy, mcap, rclpy\n"
            "for m in ('torch', 'selenium', 'pytest', 'matplotlib'):\n"
            "    try:\n"
            "        __import__(m)\n"
            "    except ModuleNotFoundError:\n"
            "        print(m)\n")
    r = subprocess.run([sys.executable, "-P", "-c", code], env=env, capture_output=True,
                       text=True, timeout=120)
    assert r.returncode == 0, r.stderr
    assert r.stdout.split() == ["torch", "selenium", "pytest", "matplotlib"]
    assert _refused(log) == ["matplotlib", "pytest", "selenium", "torch"]


def test_tactex_help_starts_from_the_workspace_packages(workspace_env) -> None:
    env, log = workspace_env
    code = ("import sys\nfrom importlib.metadata import entry_points\n"
            "ep = next(iter(entry_points(group='console_scripts', name='tactex')))\n"
            "sys.argv = ['tactex', '--help']\nsys.exit(ep.load()())\n")
    r = subprocess.run([sys.executable, "-P", "-c", code], env=env, capture_output=True,
                       text=True, timeout=120)
    assert r.returncode == 0, f"{r.stderr[-2000:]}\nrefused: {_refused(log)}"
    assert "trial" in r.stdout                   # the product's commands are listed


def _video(path: Path) -> Path:
    """A 1-s recording of a gel lit but touching nothing (a smooth left-to-right shading, MJPG,
    320 x 240) to play as the GelSight camera."""
    out = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*"MJPG"), 30, (320, 240))
    shade = np.linspace(60, 200, 320).astype(np.uint8)
    frame = np.ascontiguousarray(np.broadcast_to(shade[None, :, None], (240, 320, 3)))
    for _ in range(30):
        out.write(frame)
    out.release()
    return path


@pytest.mark.parametrize("which", ["sim", "gelsight"])
def test_every_node_starts_from_the_workspace_packages(which: str, tmp_path: Path, listener,
                                                       quick_scene, workspace_env) -> None:
    """The simulated graph (mock arm, mock camera, motion, explorer) and the GelSight node
    (playing a recording as its camera; it publishes the mock camera's topic, so apart) come up
    in the ROS graph, publish images and stop cleanly."""
    env, log = workspace_env
    if which == "sim":
        nodes = describe(True, quick_scene, explorer={"record_dir": str(tmp_path / "rec"),
                                                      "trial.rounds": 1})
    else:
        nodes = [NodeSpec("gelsight_node", "gelsight", {
            "device": str(_video(tmp_path / "press.avi")), "fps": 30.0, "warmup_frames": 0,
            "loop_file": True})]
    images = listener.collect(Image, IMAGE_TOPIC, qos_profile_sensor_data)
    graph = Graph(nodes, tmp_path / "logs", listener.domain_id)
    graph.env["PYTHONPATH"] = env["PYTHONPATH"]
    want = {n.name for n in nodes}
    up: set[str] = set()
    with graph:
        end = time.monotonic() + START_S
        while time.monotonic() < end and graph.first_exit() is None:
            up = want & set(listener.node.get_node_names())
            if up == want and images:
                break
            time.sleep(0.2)
        early = graph.first_exit()
        codes = graph.stop()
    logs = {n.name: (tmp_path / "logs" / f"{n.name}.log").read_text()[-1500:] for n in nodes}
    why = f"refused imports: {_refused(log)}\n" + json.dumps(logs, indent=1)
    assert early is None, why
    assert up == want and images, why
    assert codes == {n.name: 0 for n in nodes}, why


def test_the_two_graphs_hold_every_node_executable() -> None:
    cmake = (ROOT / "CMakeLists.txt").read_text()
    listed = cmake.split("foreach(NODE ")[1].split(")")[0].split()
    sim = {n.executable for n in describe(True)}
    assert sorted(listed) == sorted(sim | {"gelsight_node"})
