"""A node process whose worker thread is still busy at the end (the explorer's trial thread
inside a CNN training round after Ctrl-C) leaves at once with its exit status, without the
interpreter's exit (which tore torch's native threads down under that thread: SIGABRT, -6).
The interpreter's exit is told by an ``atexit`` handler: it runs only on the normal path."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

SCRIPT = """
import atexit, pathlib, threading, time
from tactex_ros.ros.nodes.process import _leave_busy_threads
atexit.register(lambda: pathlib.Path({mark!r}).write_text("interpreter exit"))
if {busy}:
    threading.Thread(target=time.sleep, args=(60,), daemon=True, name="trial").start()
raise SystemExit(_leave_busy_threads({code}))
"""


def _run(tmp: Path, busy: bool, code: int) -> tuple[int, bool]:
    mark = tmp / f"exit_{busy}"
    r = subprocess.run([sys.executable, "-c", SCRIPT.format(mark=str(mark), busy=busy,
                                                              code=code)],
                       capture_output=True, timeout=60)
    return r.returncode, mark.exists()


def test_busy_worker_thread_leaves_without_the_interpreter_exit(tmp_path: Path) -> None:
    assert _run(tmp_path, True, 3) == (3, False)     # the status kept, no interpreter exit
    assert _run(tmp_path, False, 4) == (4, True)     # nothing busy: the normal exit
