"""Clean Ctrl-C: a node process that gets SIGINT twice (the terminal's and `ros2 launch`'s, or
an impatient user) ends with exit status 0, not -2 (killed by the second signal mid clean-up)
and does not hang (a second SIGINT landing inside the first one's handler deadlocked it)."""

from __future__ import annotations

import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
from geometry_msgs.msg import PoseStamped
from rclpy.qos import qos_profile_sensor_data

from tactex_ros.ros.graph import describe, params_file
from tactex_ros.ros.devrun.launcher import node_command, ros_env
from tactex_ros.ros.settings import POSE_TOPIC

pytestmark = pytest.mark.ros


@pytest.mark.parametrize("gap_s", [0.0, 0.02, 0.2])
def test_two_sigints_exit_cleanly(tmp_path: Path, domain_id: int, listener,
                                  gap_s: float) -> None:
    nodes = [n for n in describe(True) if n.name == "mock_arm"]
    params = params_file(nodes, tmp_path / "params.yaml")
    poses = listener.collect(PoseStamped, POSE_TOPIC, qos_profile_sensor_data)
    proc = subprocess.Popen(node_command(nodes[0], params), env=ros_env(domain_id),
                            stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                            start_new_session=True)
    try:
        end = time.monotonic() + 60.0          # configured, active, publishing: not a guess
        while not poses and proc.poll() is None and time.monotonic() < end:
            time.sleep(0.05)
        assert proc.poll() is None, proc.stdout.read().decode()
        assert poses, "the mock arm published no pose within 60 s"
        proc.send_signal(signal.SIGINT)
        time.sleep(gap_s)
        proc.send_signal(signal.SIGINT)
        code = proc.wait(timeout=20)
    finally:
        if proc.poll() is None:
            proc.kill()
    assert code == 0, proc.stdout.read().decode()[-2000:]


INTERRUPTED = """
import os, signal, sys, time
from pathlib import Path
from tactex_ros.ros.nodes.process import run
from tactex_ros.ros.nodes.mock_arm_node import MockArmNode

where, marker = sys.argv[1], Path(sys.argv[2])


def interrupt(node):
    os.kill(os.getpid(), signal.SIGINT)
    end = time.monotonic() + 5.0          # rclpy's handler shuts the context down meanwhile
    while node.context.ok() and time.monotonic() < end:
        time.sleep(0.01)


class Interrupted(MockArmNode):
    def configure(self):
        if where == "configure":
            interrupt(self)
        super().configure()               # makes entities: on a shut-down context that fails

    def activate(self):
        if where == "activate":
            interrupt(self)
        super().activate()

    def cleanup(self):
        marker.write_text("released")
        super().cleanup()


sys.exit(run(Interrupted, ["interrupted"] + sys.argv[3:]))
"""


@pytest.mark.parametrize("where", ["configure", "activate"])
def test_sigint_during_start_up(tmp_path: Path, domain_id: int, where: str) -> None:
    """Ctrl-C while the node configures or activates: the step fails on the shut-down context,
    yet that is the requested stop (exit 0, not 1) and what configuration made is released."""
    nodes = [n for n in describe(True) if n.name == "mock_arm"]
    params = params_file(nodes, tmp_path / "params.yaml")
    marker = tmp_path / "cleanup"
    node_cmd = node_command(nodes[0], params)
    cmd = [sys.executable, "-c", INTERRUPTED, where, str(marker)] + \
        node_cmd[node_cmd.index("--ros-args"):]
    proc = subprocess.run(cmd, env=ros_env(domain_id), stdout=subprocess.PIPE,
                          stderr=subprocess.STDOUT, timeout=60, start_new_session=True)
    out = proc.stdout.decode()[-2000:]
    assert proc.returncode == 0, out
    assert marker.read_text() == "released", out
