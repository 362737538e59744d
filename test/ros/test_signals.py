"""Clean Ctrl-C: a node process that gets SIGINT twice (the terminal's and `ros2 launch`'s, or
an impatient user) ends with exit status 0, not -2 (killed by the second signal mid clean-up)."""

from __future__ import annotations

import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from tactex_ros.ros.graph import describe, params_file
from tactex_ros.ros.launcher import node_command, ros_env

pytestmark = pytest.mark.ros


@pytest.mark.parametrize("gap_s", [0.0, 0.02, 0.2])
def test_two_sigints_exit_cleanly(tmp_path: Path, domain_id: int, gap_s: float) -> None:
    nodes = [n for n in describe(True) if n.name == "mock_arm"]
    params = params_file(nodes, tmp_path / "params.yaml")
    proc = subprocess.Popen(node_command(nodes[0], params), env=ros_env(domain_id),
                            stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                            start_new_session=True)
    try:
        time.sleep(4.0)                      # configured, active, publishing
        assert proc.poll() is None, proc.stdout.read().decode()
        proc.send_signal(signal.SIGINT)
        time.sleep(gap_s)
        proc.send_signal(signal.SIGINT)
        code = proc.wait(timeout=20)
    finally:
        if proc.poll() is None:
            proc.kill()
    assert code == 0, proc.stdout.read().decode()[-2000:]
