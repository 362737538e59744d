"""Shared node plumbing: parameters declared from a settings schema, lifecycle start-up.

Every tactex node is a ``rclpy.lifecycle.LifecycleNode``: ``on_configure`` reads and validates
its parameters and allocates (scene, buffers, publishers, servers), ``on_activate`` goes live
(timers, trial). With the parameter ``autostart`` (default true) the node configures and
activates itself, so it runs without a lifecycle manager; a configure failure (bad parameter,
missing or invalid scene) ends the process with exit status 2 and the reason in the log.
"""

from __future__ import annotations

import dataclasses
import signal
import sys
import threading
from typing import Any, Callable

import rclpy
from rcl_interfaces.msg import FloatingPointRange, IntegerRange, ParameterDescriptor
from rclpy.executors import ExternalShutdownException, SingleThreadedExecutor
from rclpy.lifecycle import LifecycleNode, TransitionCallbackReturn
from rclpy.task import Future

from ..core.config import validate
from ..core.errors import TactexError


def declare_settings(node: LifecycleNode, cls: type) -> None:
    """Declare one ROS parameter per field of a settings dataclass (type, range, text)."""
    for f in dataclasses.fields(cls):
        md = f.metadata
        desc = ParameterDescriptor(name=f.name, description=md.get("description", ""))
        if md.get("choices"):
            desc.additional_constraints = "one of: " + ", ".join(map(str, md["choices"]))
        lo, hi = md.get("lo"), md.get("hi")
        if lo is not None and hi is not None:
            if isinstance(f.default, bool):
                pass
            elif isinstance(f.default, int):
                desc.integer_range = [IntegerRange(from_value=int(lo), to_value=int(hi), step=0)]
            elif isinstance(f.default, float):
                desc.floating_point_range = [FloatingPointRange(from_value=float(lo),
                                                                to_value=float(hi), step=0.0)]
        if not node.has_parameter(f.name):
            node.declare_parameter(f.name, f.default, desc)


def read_settings(node: LifecycleNode, cls: type) -> Any:
    """Current parameter values as a validated settings dataclass (TactexError names a field)."""
    kw = {f.name: node.get_parameter(f.name).value for f in dataclasses.fields(cls)}
    return validate(cls(**kw))


class TactexNode(LifecycleNode):
    """Lifecycle node base: ``settings_cls`` parameters, ``configure``/``activate`` hooks."""

    settings_cls: type

    def __init__(self, name: str, **kw: Any) -> None:
        super().__init__(name, **kw)
        declare_settings(self, self.settings_cls)
        self.declare_parameter("autostart", True, ParameterDescriptor(
            description="configure and activate at start-up (no lifecycle manager needed)"))
        self.settings = None
        self.finished = threading.Event()   # set when the node's work is over (exit_when_done)
        self.exit_code = 0

    # subclasses implement these two
    def configure(self) -> None:
        raise NotImplementedError

    def activate(self) -> None:
        raise NotImplementedError

    def deactivate(self) -> None:
        pass

    def on_configure(self, state) -> TransitionCallbackReturn:
        try:
            self.settings = read_settings(self, self.settings_cls)
            self.configure()
        except (TactexError, OSError) as exc:
            self.get_logger().error(f"configuration refused: {exc}")
            self.exit_code = 2
            return TransitionCallbackReturn.FAILURE
        return TransitionCallbackReturn.SUCCESS

    def on_activate(self, state) -> TransitionCallbackReturn:
        self.activate()
        return super().on_activate(state)

    def on_deactivate(self, state) -> TransitionCallbackReturn:
        self.deactivate()
        return super().on_deactivate(state)


async def in_thread(node: "rclpy.node.Node", fn: Callable[..., Any], *args: Any) -> Any:
    """Await ``fn(*args)`` run in a new thread; the executor goes on serving other callbacks.

    For long blocking work inside a callback (a press runs for seconds): the node's single
    executor thread stays free for the robot state, the capture service and cancel requests.
    """
    ex = node.executor
    fut: Future = Future(executor=ex)

    def work() -> None:
        try:
            fut.set_result(fn(*args))
        except BaseException as exc:  # handed to the awaiting callback
            fut.set_exception(exc)
        finally:
            if ex is not None:
                ex.wake()

    threading.Thread(target=work, name=f"{node.get_name()}-work", daemon=True).start()
    return await fut


def run(node_factory: Callable[[], TactexNode], args: list[str] | None = None) -> int:
    """Create, auto-start and spin a node until shutdown or ``node.finished``; exit status.

    One ``SingleThreadedExecutor`` per process; callbacks never block it (slow work runs in
    threads: ``in_thread``, the explorer's trial thread, the GelSight reader). rclpy 9.1's
    ``MultiThreadedExecutor`` re-queues tasks that wait in its thread pool (rclpy issue 1452,
    fixed upstream in 10.0.4): with the mock arm's 100 Hz state it queued thousands of tasks,
    took a full core and left the motion node's robot state stale for over a second.
    """
    stopping = threading.Event()

    def on_sigint(signum, frame):  # rclpy's handler chains to this one
        if stopping.is_set():
            return   # Ctrl-C reaches every process of the group and `ros2 launch` sends its
            #          own SIGINT too: a second one during clean-up must not kill (exit -2)
        stopping.set()
        raise KeyboardInterrupt

    signal.signal(signal.SIGINT, on_sigint)
    try:
        return _spin(node_factory, args, stopping)
    except KeyboardInterrupt:   # a requested stop that surfaced outside the spin
        return 0


def _spin(node_factory: Callable[[], TactexNode], args: list[str] | None,
          stopping: threading.Event) -> int:
    rclpy.init(args=args if args is not None else sys.argv)
    node = node_factory()
    code = 0
    try:
        if node.get_parameter("autostart").value:
            node.trigger_configure()
            if node.exit_code:
                return node.exit_code
            node.trigger_activate()
        ex = SingleThreadedExecutor()
        ex.add_node(node)
        done = Future()
        threading.Thread(target=lambda: (node.finished.wait(), done.set_result(True)),
                         daemon=True).start()
        try:
            ex.spin_until_future_complete(done)
        except RuntimeError:
            if rclpy.ok() and not stopping.is_set():
                raise
            # SIGINT while a message was being taken (the KeyboardInterrupt surfaces as a
            # RuntimeError from the C++ layer, seen under `ros2 launch`): a normal stop
        code = node.exit_code
    except (KeyboardInterrupt, ExternalShutdownException):
        code = 0
    finally:
        stopping.set()   # from here on SIGINT is ignored, also during interpreter shutdown
        signal.signal(signal.SIGINT, signal.SIG_IGN)
        try:
            node.destroy_node()
        finally:
            if rclpy.ok():
                rclpy.shutdown()
    return code
