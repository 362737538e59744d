#!/usr/bin/env python3
"""cpu_hog: N bounded busy processes beside a command, for the soak lane (``make test-soak``).

    python scripts/cpu_hog.py --procs 4 --limit-s 3600 -- python -m pytest test/ros

Starts ``--procs`` processes that each spin on the CPU (no I/O, no memory growth) until
``--limit-s`` [s] have passed or the command ends, whichever is first; then every hog is killed
(SIGKILL by its process id) and waited for. Without a command the hogs run for ``--limit-s``.
Exit status: the command's own (2 for a bad option here); the hogs never outlive this process
by more than their own time limit (each one checks it), even if this process is killed hard.
"""

from __future__ import annotations

import argparse
import multiprocessing as mp
import os
import signal
import subprocess
import sys
import time
import contextlib


def _spin(limit_s: float) -> None:
    """Busy-loop until ``limit_s`` [s] of wall time have passed (a hog's whole life)."""
    end = time.monotonic() + limit_s
    x = 0
    while time.monotonic() < end:
        for _ in range(10_000):
            x = (x * 1103515245 + 12345) & 0xFFFFFFFF


def start_hogs(procs: int, limit_s: float) -> list[mp.Process]:
    """``procs`` busy processes, each ending by itself after ``limit_s`` [s]."""
    ctx = mp.get_context("spawn")      # no copy of the caller's threads or locks
    hogs = [ctx.Process(target=_spin, args=(limit_s,), name=f"cpu_hog-{i}", daemon=True)
            for i in range(procs)]
    for h in hogs:
        h.start()
    return hogs


def stop_hogs(hogs: list[mp.Process], timeout_s: float = 5.0) -> None:
    """Kill every hog by its pid and wait for it (up to ``timeout_s`` [s] each)."""
    for h in hogs:
        if h.is_alive() and h.pid is not None:
            with contextlib.suppress(ProcessLookupError):
                os.kill(h.pid, signal.SIGKILL)
    for h in hogs:
        h.join(timeout_s)


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--procs", type=int, default=4, help="busy processes (>= 1; default 4)")
    p.add_argument("--limit-s", type=float, default=3600.0,
                   help="most seconds a hog runs (> 0; default 3600)")
    p.add_argument("command", nargs=argparse.REMAINDER, help="-- the command to run beside")
    a = p.parse_args(argv)
    if a.procs < 1:
        p.error(f"--procs {a.procs}: must be >= 1")
    if not a.limit_s > 0:
        p.error(f"--limit-s {a.limit_s}: must be > 0")
    cmd = a.command[1:] if a.command[:1] == ["--"] else a.command
    hogs = start_hogs(a.procs, a.limit_s)
    print(f"cpu_hog: {a.procs} busy process(es), at most {a.limit_s:g} s "
          f"(pids {' '.join(str(h.pid) for h in hogs)})", file=sys.stderr, flush=True)
    try:
        if not cmd:
            for h in hogs:
                h.join(a.limit_s + 5.0)
            return 0
        try:
            return subprocess.call(cmd)
        except FileNotFoundError:
            print(f"cpu_hog: command not found: {cmd[0]!r}", file=sys.stderr)
            return 2
    except KeyboardInterrupt:
        return 130
    finally:
        stop_hogs(hogs)


if __name__ == "__main__":
    raise SystemExit(main())
