"""The node executables (``NODE_EXECUTABLES``). A SIGINT or SIGTERM that arrives while a node
process still imports its modules ends it quietly with status 0: ``tactex_ros/__init__.py``
installs that before anything else is imported (Python's default would print a
KeyboardInterrupt traceback and end with -2, seen under ``ros2 launch`` when the launch stopped
while the explorer imported its learner; a SIGTERM would end it with -15). ``process.run``
installs the node's own handling as soon as the imports are done."""

from __future__ import annotations

from ... import NODE_EXECUTABLES as EXECUTABLES  # noqa: F401 - the node executables
