"""Bad scene or parameters: the node refuses to start (exit status 2) before moving anything."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest
import yaml

from tactex_ros.core.paths import config_dir
from tactex_ros.ros.devrun.launcher import ros_env

pytestmark = pytest.mark.ros


def _start(node: str, params: list[str], domain_id: int) -> subprocess.CompletedProcess:
    cmd = [sys.executable, "-m", f"tactex_ros.ros.nodes.{node}", "--ros-args"]
    for p in params:
        cmd += ["-p", p]
    return subprocess.run(cmd, capture_output=True, timeout=60, env=ros_env(domain_id))


@pytest.mark.parametrize("node", ["motion_node", "explorer_node", "mock_arm_node"])
def test_platform_outside_workspace_refused(tmp_path: Path, node: str, domain_id) -> None:
    scene = yaml.safe_load((config_dir() / "scene_sim.yaml").read_text())
    scene["platforms"][2]["position"] = [0.9, 0.22, 0.08]      # x beyond workspace max 0.75
    bad = tmp_path / "scene.yaml"
    bad.write_text(yaml.safe_dump(scene))
    r = _start(node, [f"scene_file:={bad}", f"record_dir:={tmp_path}"]
               if node == "explorer_node" else [f"scene_file:={bad}"], domain_id)
    assert r.returncode == 2
    assert b"platforms.2.position" in r.stdout + r.stderr


def test_missing_scene_refused(tmp_path: Path, domain_id) -> None:
    r = _start("motion_node", [f"scene_file:={tmp_path / 'nope.yaml'}"], domain_id)
    assert r.returncode == 2


def test_bad_strategy_refused(tmp_path: Path, domain_id) -> None:
    r = _start("explorer_node", [f"scene_file:={config_dir() / 'scene_sim.yaml'}",
                                 "trial.strategy:=greedy", f"record_dir:={tmp_path}"], domain_id)
    assert r.returncode == 2
    assert b"trial.strategy" in r.stdout + r.stderr


def test_goal_answer_not_below_press_silence_refused(tmp_path: Path, domain_id) -> None:
    r = _start("explorer_node", [f"scene_file:={config_dir() / 'scene_sim.yaml'}",
                                 "goal_answer_s:=12.0", "press_silence_s:=10.0",
                                 f"record_dir:={tmp_path}"], domain_id)
    assert r.returncode == 2
    assert b"goal_answer_s" in r.stdout + r.stderr


def test_mock_camera_refuses_recorded_sessions(domain_id) -> None:
    # sim:recorded simulates a replayed dataset; the mock camera is a live sensor
    r = _start("mock_image_node", [f"scene_file:={config_dir() / 'scene_sim.yaml'}",
                                   "source:=sim:medium:recorded"], domain_id)
    assert r.returncode == 2
    assert b"recorded" in r.stdout + r.stderr


@pytest.mark.parametrize("node, param", [
    ("motion_node", "descend_speed:=fast"),
    ("motion_node", "retries:=-5"),
    ("explorer_node", "trial.warp:=1"),
    ("explorer_node", "learner.lr:=0.1"),        # a CNN setting; the default learner has none
])
def test_unknown_parameter_refused(tmp_path: Path, node: str, param: str, domain_id) -> None:
    # rclpy keeps an undeclared -p value as an override and never applies it: refused here
    r = _start(node, [f"scene_file:={config_dir() / 'scene_sim.yaml'}", param]
               + ([f"record_dir:={tmp_path}"] if node == "explorer_node" else ["robot:=sim"]),
               domain_id)
    assert r.returncode == 2
    assert param.split(":=")[0].encode() in r.stdout + r.stderr
    assert not list(tmp_path.iterdir())          # the explorer recorded nothing


def test_motion_node_without_scene_file_names_the_parameter(domain_id) -> None:
    r = _start("motion_node", [], domain_id)
    assert r.returncode == 2
    assert b"scene_file" in r.stdout + r.stderr


def test_a_cnn_setting_under_the_descriptor_names_the_nearest(tmp_path: Path, domain_id) -> None:
    r = _start("explorer_node", [f"scene_file:={config_dir() / 'scene_sim.yaml'}",
                                 "learner.match_temprature:=0.1", f"record_dir:={tmp_path}"],
               domain_id)
    assert r.returncode == 2
    assert b"learner.match_temprature (nearest valid: learner.match_temperature)" in \
        r.stdout + r.stderr
