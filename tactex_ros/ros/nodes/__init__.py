"""The node executables. Importing this package from a node executable (the console scripts in
lib/tactex, or ``python -m tactex_ros.ros.nodes.<node>``) makes a SIGINT that arrives while
the node is still importing its modules end the process quietly with status 0: nothing is open
yet, and Python's default would print a KeyboardInterrupt traceback and end with -2 (seen under
``ros2 launch`` when the launch stopped while the explorer imported its learner). ``common.run``
installs the node's own SIGINT handling as soon as the imports are done."""

from __future__ import annotations

import os
import signal
import sys
from pathlib import Path

EXECUTABLES = ("gelsight_node", "motion_node", "explorer_node", "mock_arm_node",
               "mock_image_node")


def _node_process() -> bool:
    """True when this process is a node executable (not a test or the CLI importing nodes)."""
    arg0 = sys.argv[0] if sys.argv else ""
    return arg0 == "-m" or Path(arg0).name in EXECUTABLES or \
        Path(arg0).stem in EXECUTABLES


def _stopped_during_import(signum: int, frame: object) -> None:
    os._exit(0)


if _node_process() and signal.getsignal(signal.SIGINT) is signal.default_int_handler:
    signal.signal(signal.SIGINT, _stopped_during_import)
