"""``tactex graph run``'s own clock: "in this run" and "s into the session" count from the
command's start, its Python start-up and imports included (the operator walk of issue 47 at
load 11: 45.6 s printed into the session against 54.8 s since the command began)."""

from __future__ import annotations

import subprocess
import sys


def test_the_command_clock_starts_with_the_process() -> None:
    code = ("import time; time.sleep(1.0); "
            "from tactex_ros.cli.graph_commands import command_started; "
            "print(time.monotonic() - command_started())")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         timeout=120, check=True).stdout
    took = float(out.split()[-1])
    assert 1.0 <= took < 60.0, out        # the second slept before any import counts
