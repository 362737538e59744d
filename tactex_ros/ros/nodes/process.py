"""The process main of a tactex node: ``run(node_factory)`` installs the SIGINT/SIGTERM handling,
spins the node until it is finished or stopped, and returns the exit status (0 done or stopped,
1 a failure, 2 a configure refusal)."""

from __future__ import annotations

import os
import signal
import sys
import threading
import time
from typing import Any
from collections.abc import Callable

import rclpy
from rclpy.exceptions import ParameterException
from rclpy.executors import ExternalShutdownException, SingleThreadedExecutor
from rclpy.signals import (SignalHandlerOptions, get_current_signal_handlers_options,
                           uninstall_signal_handlers)
from rclpy.task import Future

from ...core.errors import InputError
from .lifecycle import TactexNode


class StopRequest:
    """SIGINT's handler: it only records that a stop was asked for.

    A Python signal handler runs in the main thread between any two bytecodes, also inside
    itself when a second SIGINT follows at once (the terminal's and ``ros2 launch``'s). So it
    takes no lock and raises nothing: a ``threading.Event.set`` here deadlocked, the nested call
    waiting for the Event's lock that the interrupted outer call held, and an exception raised
    at an arbitrary bytecode can leave rclpy's executor or a ``with`` block half done. The stop
    itself comes from rclpy's own SIGINT handler (installed by ``rclpy.init`` after this one,
    and chaining to it): it shuts the context down from its own thread, which ends the spin.
    """

    def __init__(self) -> None:
        self.requested = False

    def __call__(self, signum: int, frame: Any) -> None:
        self.requested = True


def run(node_factory: Callable[[], TactexNode], args: list[str] | None = None) -> int:
    """Create, auto-start and spin a node until shutdown or ``node.finished``; exit status.

    One ``SingleThreadedExecutor`` per process; callbacks never block it (slow work runs in
    threads: ``in_thread``, the explorer's trial thread, the GelSight reader). rclpy 9.1's
    ``MultiThreadedExecutor`` re-queues tasks that wait in its thread pool (rclpy issue 1452,
    fixed upstream in 10.0.4): with the mock arm's 100 Hz state it queued thousands of tasks,
    took a full core and left the motion node's robot state stale for over a second.

    SIGINT (any number of them, at any moment after this call starts) is a requested stop:
    exit status 0, the node's hooks release files, devices and threads; SIGTERM likewise. A
    stop while the node's modules still import ends the process quietly with 0
    (``tactex_ros/__init__.py``). A stop asked for
    during start-up ends it at the next step (after ``rclpy.init``, node construction,
    configuration, activation); a step that failed because the stop shut the context down
    counts as stopped, not as an error.
    """
    stop = StopRequest()
    # before rclpy.init: rclpy's handlers chain to these (SIGTERM's must not be the quiet exit
    # of a stop during the imports, tactex_ros/__init__.py: it would cut the node's release)
    signal.signal(signal.SIGINT, stop)
    signal.signal(signal.SIGTERM, stop)
    try:
        code = _spin(node_factory, args, stop)
    finally:
        # From here on SIGINT is ignored, also during interpreter shutdown (which would put
        # back the default handler for a Python one: a late Ctrl-C would end it with -2).
        signal.signal(signal.SIGINT, signal.SIG_IGN)
    return _leave_busy_threads(code)


def _leave_busy_threads(code: int) -> int:
    """``code``, or leave the process at once with it while a worker thread is still running
    (the explorer's trial thread stopped in the middle of a CNN training round). The node is
    shut down and its record closed by now; the interpreter's normal exit would tear torch's
    thread pool down under that thread (C++ ``terminate``: SIGABRT, exit status -6)."""
    if any(t.is_alive() and t.daemon for t in threading.enumerate()
           if t is not threading.current_thread()):
        sys.stdout.flush()
        sys.stderr.flush()
        os._exit(code)
    return code


def _spin(node_factory: Callable[[], TactexNode], args: list[str] | None,
          stop: StopRequest) -> int:
    if stop.requested:
        return 0
    rclpy.init(args=args if args is not None else sys.argv,
               signal_handler_options=SignalHandlerOptions.ALL)

    def stopped() -> bool:
        return stop.requested or not rclpy.ok()

    def starting(step: Callable[[], Any]) -> bool:
        """Run a start-up step; False once a stop was requested (its failure included)."""
        try:
            step()
        except Exception:
            if not stopped():
                raise
        return not stopped()

    node = None
    try:
        if stopped():
            return 0
        try:
            node = node_factory()
        except (ParameterException, InputError) as exc:
            # a parameter given with the wrong type or outside its range (declaration refuses it)
            if stopped():
                return 0
            print(f"tactex: parameter refused: {exc}", file=sys.stderr)
            return 2
        except Exception:
            if stopped():
                return 0     # e.g. the stop shut the context down under the constructor
            raise
        if stopped():
            return 0
        if node.get_parameter("autostart").value:
            if not starting(node.trigger_configure):
                return 0
            if node.exit_code:
                return node.exit_code
            if not starting(node.trigger_activate):
                return 0
        return _spin_node(node, stopped)
    finally:
        try:
            if node is not None:
                if stop.requested:   # let rclpy's handler finish: one release path on SIGINT
                    _until(lambda: not rclpy.ok(), SIGINT_SHUTDOWN_S)
                try:
                    node.shutdown()
                finally:
                    node.destroy_node()
        finally:
            _leave_rclpy()


SIGINT_SHUTDOWN_S = 2.0   # [s] rclpy's handler thread shuts the context down within this
WATCH_PERIOD_S = 0.05     # [s] how often the spin's watcher checks for the end


def _spin_node(node: TactexNode, stopped: Callable[[], bool]) -> int:
    """Spin ``node`` until its work is over (``node.finished``) or a stop; exit status.

    A watcher thread ends the spin: every ``WATCH_PERIOD_S`` it checks ``node.finished`` and
    ``stopped()``. rclpy's SIGINT handler wakes the executor before it shuts the context down;
    an executor woken between the two waits again, and a node with no timer would sleep on.
    """
    ex = SingleThreadedExecutor()
    ex.add_node(node)
    done = Future()
    ended = threading.Event()

    def watch() -> None:
        while not ended.is_set():
            if node.finished.wait(WATCH_PERIOD_S) or stopped():
                done.set_result(True)
                return

    watcher = threading.Thread(target=watch, name="spin-watch", daemon=True)
    watcher.start()
    try:
        ex.spin_until_future_complete(done)
    except ExternalShutdownException:
        pass
    except Exception:
        if not stopped():
            raise
        # the stop shut the context down under a callback (e.g. while a message was taken)
    finally:
        ended.set()
        watcher.join(timeout=1.0)
    return 0 if stopped() else node.exit_code


def _until(condition: Callable[[], bool], timeout_s: float, period_s: float = 0.005) -> bool:
    """Poll ``condition`` every ``period_s`` [s] until it holds or ``timeout_s`` [s] passes."""
    end = time.monotonic() + timeout_s
    while not condition():
        if time.monotonic() >= end:
            return False
        time.sleep(period_s)
    return True


def _leave_rclpy() -> None:
    """Shut the default context down unless a signal did, and take rclpy's signal handlers out
    of the chain (Kilted's ``try_shutdown`` does so too, Humble's and Jazzy's do not)."""
    rclpy.try_shutdown()
    if get_current_signal_handlers_options() != SignalHandlerOptions.NO:
        uninstall_signal_handlers()
