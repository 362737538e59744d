"""A node process stopped (SIGINT or SIGTERM, as the launcher and `ros2 launch` stop it) while it
still imports its modules ends quietly with status 0: no KeyboardInterrupt traceback, no -2/-15."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time

import pytest

pytest.importorskip("rclpy")

DEADLINE_S = 120.0     # [s] a node's imports on a loaded machine (load 10 on 2 cores)


def _default_sigint() -> None:
    """In the child before exec: SIGINT at its default, as a terminal or a launch gives it (a
    shell's background job inherits SIGINT ignored, and Python then keeps it ignored)."""
    signal.signal(signal.SIGINT, signal.SIG_DFL)


def _importing(pid: int, marker: str) -> bool:
    """The child has mapped ``marker`` (a shared library loaded by an import)."""
    try:
        with open(f"/proc/{pid}/maps") as f:
            return marker in f.read()
    except OSError:
        return False


@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM])
@pytest.mark.parametrize("marker", ["_rclpy_pybind11", "_multiarray_umath"])
def test_a_node_stopped_while_importing_exits_quietly(sig, marker) -> None:
    p = subprocess.Popen([sys.executable, "-P", "-m", "tactex_ros.ros.nodes.explorer_node"],
                         stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                         start_new_session=True, preexec_fn=_default_sigint)
    end = time.monotonic() + DEADLINE_S
    while not _importing(p.pid, marker) and p.poll() is None and time.monotonic() < end:
        time.sleep(0.001)
    assert p.poll() is None, p.stderr.read()
    os.kill(p.pid, sig)
    try:
        out, err = p.communicate(timeout=DEADLINE_S)
    finally:
        if p.poll() is None:
            p.kill()
    assert p.returncode == 0, err
    assert "Traceback" not in err and "KeyboardInterrupt" not in err


def test_the_cli_importing_the_package_keeps_default_signals() -> None:
    code = ("import signal, tactex_ros.ros.nodes; "
            "print(signal.getsignal(signal.SIGINT) is signal.default_int_handler, "
            "signal.getsignal(signal.SIGTERM) == signal.SIG_DFL)")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         timeout=DEADLINE_S, preexec_fn=_default_sigint)
    assert out.stdout.split() == ["True", "True"], out.stderr
