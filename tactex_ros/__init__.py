"""tactex: active tactile texture recognition; the product (ROS 2 application, torch-free core).
The thesis lab is the package ``tactex_lab`` beside it.

In a node process (``python -m tactex_ros.ros.nodes.<node>``, or a node executable of
lib/tactex) a SIGINT or SIGTERM that arrives while the node is still importing its modules ends
the process at once, quietly, with status 0 (a requested stop; nothing is open yet): this is
the first module such a process imports, so the window before it is Python's own start-up.
``ros/nodes/process.run`` installs the node's own handling once the imports are done.
"""

import os as _os
import signal as _signal
import sys as _sys

__version__ = "0.1.0"

NODE_EXECUTABLES = ("gelsight_node", "motion_node", "explorer_node", "mock_arm_node",
                    "mock_image_node")


def _node_process() -> bool:
    """True when this process is a node executable (not a test or the CLI importing nodes)."""
    argv = list(getattr(_sys, "orig_argv", None) or _sys.argv)
    if "-m" in argv[:-1]:
        mod = argv[argv.index("-m") + 1]
        return mod.rsplit(".", 1)[-1] in NODE_EXECUTABLES and mod.startswith("tactex_ros.")
    arg0 = _os.path.basename(_sys.argv[0]) if _sys.argv else ""
    return arg0 in NODE_EXECUTABLES or _os.path.splitext(arg0)[0] in NODE_EXECUTABLES


def _stopped_during_import(signum: int, frame: object) -> None:
    _os._exit(0)


if _node_process():
    for _sig in (_signal.SIGINT, _signal.SIGTERM):
        if _signal.getsignal(_sig) in (_signal.default_int_handler, _signal.SIG_DFL):
            _signal.signal(_sig, _stopped_during_import)
