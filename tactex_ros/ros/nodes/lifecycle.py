"""The lifecycle base of every tactex node: parameters declared from a settings schema, the
transitions, and the helpers a node's threads wait with (``wait_for``, ``in_thread``). The process
around a node (signals, spin, exit status) is ``process.py``.

Every tactex node is a ``rclpy.lifecycle.LifecycleNode``. Its ROS parameters are declared from
its settings schema (``ros.settings``: type, default, range -> ``ParameterDescriptor``, choices
and description; nested settings as dotted names, their defaults from the top-level values, so
``config`` picks the preset the explorer's ``learner.*`` / ``trial.*`` start from).

Transitions: ``on_configure`` reads and validates the parameters and makes the node's
subscriptions, clients, servers and lifecycle publishers (``configure``); ``on_activate``
enables the publishers, then starts timers and threads (``activate``); ``on_deactivate``
stops them (``deactivate``) and destroys what activation made (timers); ``on_cleanup`` releases
files and devices (``cleanup``) and destroys every entity configuration made; ``on_shutdown``
does whatever of the two is due from the state it leaves. An inactive node publishes nothing
(lifecycle publishers). With the parameter ``autostart`` (default true) the node configures and
activates itself, so it runs without a lifecycle manager; a configure failure (bad parameter,
missing or invalid scene) ends the process with exit status 2 and the reason in the log.
"""

from __future__ import annotations

import threading
import time
from typing import Any
from collections.abc import Callable

import rclpy
from pydantic import ValidationError
from rcl_interfaces.msg import FloatingPointRange, IntegerRange, ParameterDescriptor
from rclpy.lifecycle import LifecycleNode, TransitionCallbackReturn
from rclpy.lifecycle.publisher import LifecyclePublisher
from rclpy.publisher import Publisher
from rclpy.task import Future
from rclpy.timer import Timer

from ...core.schema import FieldSpec, fields, flatten, merge, nearest, nest
from ...core.errors import DeviceError, InputError


def descriptor(spec: FieldSpec) -> ParameterDescriptor:
    """The ROS parameter descriptor of a schema field: description, range, choices, read-only."""
    desc = ParameterDescriptor(name=spec.name, description=spec.description,
                               read_only=spec.read_only)
    if spec.choices:
        desc.additional_constraints = "one of: " + ", ".join(map(str, spec.choices))
    if spec.lo is not None and spec.hi is not None:
        if spec.kind is int:
            desc.integer_range = [IntegerRange(from_value=int(spec.lo), to_value=int(spec.hi),
                                               step=0)]
        elif spec.kind is float:
            desc.floating_point_range = [FloatingPointRange(from_value=float(spec.lo),
                                                            to_value=float(spec.hi), step=0.0)]
    return desc


def declare_settings(node: LifecycleNode, cls: type) -> None:
    """Declare one ROS parameter per field of a settings schema. Nested fields (``trial.rounds``)
    are declared after the top-level ones, with defaults the schema derives from the top-level
    values given (e.g. the preset named by ``config``). A union's tag (``learner.model``) is
    declared before the union's other fields: only the fields of the learner it names are
    declared (a descriptor has no ``learner.lr``; one given is refused by
    ``check_overrides``, by name)."""
    specs = fields(cls)
    top = [s for s in specs if "." not in s.name]
    for s in top:
        node.declare_parameter(s.name, s.kind(s.default), descriptor(s))
    if len(top) == len(specs):
        return
    given = nest({s.name: node.get_parameter(s.name).value for s in top})
    base = _effective(cls, given)
    for s in (s for s in specs if s.tag):
        node.declare_parameter(s.name, s.kind(base.get(s.name, s.default)), descriptor(s))
        given = merge(given, nest({s.name: node.get_parameter(s.name).value}))
    base = _effective(cls, given)
    for s in fields(cls, values=nest(base) if base else given):
        if "." in s.name and not s.tag:
            node.declare_parameter(s.name, s.kind(base.get(s.name, s.default)), descriptor(s))


def _effective(cls: type, given: dict[str, Any]) -> dict[str, Any]:
    """The flat settings ``cls`` makes of ``given`` (nested), {} when invalid (on_configure
    names the bad value)."""
    try:
        return flatten(cls.model_validate(given).model_dump())
    except (ValidationError, InputError):
        return {}


# parameters rclpy declares itself (a node option, QoS overrides when an entity asks for them)
ROS_OWN_PARAMETERS = ("use_sim_time",)
ROS_OWN_PREFIXES = ("qos_overrides.",)


def check_overrides(node: LifecycleNode) -> None:
    """Refuse parameters given to the node (``-p``, ``--params-file``) that it does not
    declare. rclpy keeps such values as *overrides* and applies one only when a parameter of
    that name is declared, so with ``allow_undeclared_parameters=False`` (the default) an
    unknown name or a typo is silently ignored rather than refused: it is refused here, at
    configure, by name (InputError)."""
    given = given_parameters(node)
    unknown = sorted(n for n in given if not node.has_parameter(n)
                     and n not in ROS_OWN_PARAMETERS and not n.startswith(ROS_OWN_PREFIXES))
    if unknown:
        declared = sorted(node._parameters)
        raise InputError(f"{node.get_name()} parameters: unknown parameter(s) " + ", ".join(
            f"{n} (nearest valid: {nearest(n, declared)})" for n in unknown)
            + f" (ros2 param list /{node.get_name()} shows the declared ones)")


def given_parameters(node: LifecycleNode) -> set[str]:
    """The names of the parameters given to ``node`` (``-p``, ``--params-file``, a launch's
    parameters), not its declared defaults."""
    return set(getattr(node, "_parameter_overrides", {}) or {})


def parameter_values(node: LifecycleNode, cls: type) -> dict[str, Any]:
    """The current values of the declared parameters of schema ``cls``, flat (dotted names),
    as given (not validated)."""
    return {s.name: node.get_parameter(s.name).value for s in fields(cls)
            if node.has_parameter(s.name)}


def read_settings(node: LifecycleNode, cls: type) -> Any:
    """Current parameter values as a validated settings model (InputError names a field)."""
    return cls.check(nest(parameter_values(node, cls)), f"{node.get_name()} parameters")


def entities(node: LifecycleNode) -> set:
    """Every ROS entity of ``node``: publishers, subscriptions, clients, services, timers,
    guard conditions, waitables (action servers and clients)."""
    return (set(node.publishers) | set(node.subscriptions) | set(node.clients) |
            set(node.services) | set(node.timers) | set(node.guards) | set(node.waitables))


class TactexNode(LifecycleNode):
    """Lifecycle node base: ``settings_cls`` parameters and the hooks ``configure``,
    ``activate``, ``deactivate``, ``cleanup``; the base releases every ROS entity a stage made
    when the node leaves that stage."""

    settings_cls: type

    def __init__(self, name: str, **kw: Any) -> None:
        super().__init__(name, **kw)
        declare_settings(self, self.settings_cls)
        self.declare_parameter("autostart", True, ParameterDescriptor(
            description="configure and activate at start-up (no lifecycle manager needed)"))
        self.settings: Any = None           # the validated settings (configure)
        self.finished = threading.Event()   # set when the node's work is over (exit_when_done)
        self.exit_code = 0
        self.configured = self.active = self.finalized = False
        self._made_before: dict[str, set] = {}    # entities before configure / activate
        self._loops: list[RateLoop] = []          # started by activate (``rate_loop``)

    def load_settings(self) -> Any:
        """The node's settings from its parameters, validated (at configure)."""
        return read_settings(self, self.settings_cls)

    # subclasses implement these
    def configure(self) -> None:
        """Make subscriptions, clients, servers, lifecycle publishers; open files/devices."""
        raise NotImplementedError

    def activate(self) -> None:
        """Start timers and threads (publishers are enabled already)."""

    def deactivate(self) -> None:
        """Stop threads; timers and rate loops made by ``activate`` are ended by the base."""

    def rate_loop(self, period_s: float, fn: Callable[[], None], name: str) -> RateLoop:
        """A ``RateLoop`` of this node (``fn`` every ``period_s`` [s]); from ``activate`` only:
        the base stops it on deactivation, as it destroys the activation's timers. A tick
        that raises ends the node (``loop_failed``): a device whose loop is dead must not
        stay up looking alive."""
        loop = RateLoop(period_s, fn, f"{self.get_name()}-{name}", self.context.ok,
                        on_error=lambda exc: self.loop_failed(name, exc))
        self._loops.append(loop)
        return loop

    def loop_failed(self, name: str, exc: BaseException) -> None:
        """The rate loop ``name`` ended in ``exc``: the reason on the log (an ``[ERROR]`` line,
        the one ``tactex graph run`` prints), exit status 1 (a run-time failure; a bad input
        is refused at configure), and the node's work is over."""
        self.get_logger().error(f"{name} loop failed: {type(exc).__name__}: {exc}")
        self.exit_code = 1
        self.finished.set()

    def _deactivate(self) -> None:
        """``deactivate``, then the rate loops stopped."""
        try:
            self.deactivate()
        finally:
            loops, self._loops = self._loops, []
            for loop in loops:
                loop.stop()

    def cleanup(self) -> None:
        """Close files and devices ``configure`` opened; entities are destroyed by the base."""

    def _release(self, stage: str) -> None:
        """Destroy every ROS entity made since ``stage`` began."""
        for e in entities(self) - self._made_before.pop(stage, entities(self)):
            if isinstance(e, Timer):
                self.destroy_timer(e)
            elif isinstance(e, LifecyclePublisher):
                self.destroy_lifecycle_publisher(e)
            elif isinstance(e, Publisher):
                self.destroy_publisher(e)
            elif e in set(self.subscriptions):
                self.destroy_subscription(e)
            elif e in set(self.clients):
                self.destroy_client(e)
            elif e in set(self.services):
                self.destroy_service(e)
            elif e in set(self.guards):
                self.destroy_guard_condition(e)
            else:
                e.destroy()    # action servers and clients remove themselves from the node

    def _transition(self, name: str, fn: Callable[[], None]) -> TransitionCallbackReturn:
        """Run a hook; an exception is logged (rclpy would swallow it) and fails the
        transition: bad input (InputError, OSError) -> FAILURE and exit status 2; a device
        absent at run time (DeviceError) -> FAILURE and exit status 1."""
        try:
            fn()
        except DeviceError as exc:
            self.get_logger().error(f"{name} failed: {exc}")
            self.exit_code = 1
            return TransitionCallbackReturn.FAILURE
        except (InputError, OSError) as exc:
            self.get_logger().error(f"{name} refused: {exc}")
            self.exit_code = 2
            return TransitionCallbackReturn.FAILURE
        except Exception as exc:  # noqa: BLE001 - reported, then the lifecycle's error path
            if self.context.ok():
                self.get_logger().error(f"{name} failed: {type(exc).__name__}: {exc}")
            else:   # a stop (SIGINT, SIGTERM) shut the context down under the hook: no error
                self.get_logger().info(f"{name} ended by the stop: {type(exc).__name__}")
            self.exit_code = 1
            return TransitionCallbackReturn.ERROR
        return TransitionCallbackReturn.SUCCESS

    def on_configure(self, state) -> TransitionCallbackReturn:
        self._made_before["configure"] = entities(self)

        def configure() -> None:
            check_overrides(self)
            self.settings = self.load_settings()
            self.configure()
        ret = self._transition("configuration", configure)
        if ret != TransitionCallbackReturn.SUCCESS:
            self._undo_configure()
            return ret
        self.configured = True
        return super().on_configure(state)

    def on_activate(self, state) -> TransitionCallbackReturn:
        self._made_before["activate"] = entities(self)
        ret = super().on_activate(state)       # lifecycle publishers first: then timers
        if ret == TransitionCallbackReturn.SUCCESS:
            ret = self._transition("activation", self.activate)
        if ret != TransitionCallbackReturn.SUCCESS:
            self._undo_activate()
            return ret
        self.active = True
        return ret

    def on_deactivate(self, state) -> TransitionCallbackReturn:
        self._undo_activate()
        return super().on_deactivate(state)

    def on_cleanup(self, state) -> TransitionCallbackReturn:
        self._undo_configure()
        return super().on_cleanup(state)

    def on_shutdown(self, state) -> TransitionCallbackReturn:
        self._undo_activate()
        self._undo_configure()
        self.finalized = True
        return super().on_shutdown(state)

    def on_error(self, state) -> TransitionCallbackReturn:
        self._undo_activate()
        self._undo_configure()
        return super().on_error(state)

    def _undo_activate(self) -> None:
        if self.active or "activate" in self._made_before:
            self.active = False
            self._transition("deactivation", self._deactivate)
            super().on_deactivate(None)      # publishers off (idempotent)
            self._release("activate")

    def _undo_configure(self) -> None:
        if self.configured or "configure" in self._made_before:
            self.configured = False
            self._transition("clean-up", self.cleanup)
            self._release("configure")

    def shutdown(self) -> None:
        """Leave the lifecycle (releasing everything) unless already finalized. After the
        context was shut down (SIGINT, SIGTERM: rclpy's handler, possibly while the shutdown
        transition runs), only files, devices and threads are released here, each hook at most
        once: ``destroy_node`` takes the ROS entities."""
        if self.finalized:
            return
        failure = None
        if self.context.ok():
            try:
                self.trigger_shutdown()
            except Exception as exc:  # noqa: BLE001 - re-raised below unless the context went
                failure = exc          # down meanwhile; the hooks run first either way
        if not self.finalized:
            self.finalized = True
            if self.active:
                self.active = False
                self._transition("deactivation", self._deactivate)
            if self.configured:
                self.configured = False
                self._transition("clean-up", self.cleanup)
        if failure is not None and self.context.ok():
            raise failure


def wait_for(fut: Future, timeout_s: float, check: Callable[[], None] | None = None,
             period_s: float = 0.1) -> bool:
    """Block this worker thread until ``fut`` is done or ``timeout_s`` [s] passes; True when
    done. The wait wakes on the future's completion (a done callback), not by polling; ``check``
    runs every ``period_s`` meanwhile and may raise to end the wait (e.g. the server left). Never
    call it from an executor callback (the executor completes the future)."""
    done = threading.Event()
    fut.add_done_callback(lambda _f: done.set())
    end = time.monotonic() + timeout_s
    while not (done.is_set() or fut.done()):
        left = end - time.monotonic()
        if left <= 0:
            return False
        if check is not None:
            check()
        done.wait(min(left, period_s) if check is not None else left)
    return True


async def in_thread(node: rclpy.node.Node, fn: Callable[..., Any], *args: Any) -> Any:
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


class RateLoop:
    """``fn()`` every ``period_s`` [s] in a thread of its own, until ``stop``: a simulated
    device's fixed-rate loop. An executor timer costs the executor's whole wake per tick
    (about 1 ms of CPU in rclpy's ``SingleThreadedExecutor``: 10 % of a core at 100 Hz); a
    thread costs a sleep. A tick that ends late starts the next at once, never a burst of
    catch-up ticks. ``fn`` runs outside the executor: it guards what callbacks share with it.
    The loop ends quietly once ``ok()`` is False (the context shut down by a stop while a tick
    published); any other exception in ``fn`` ends it and goes to ``on_error`` (None: it is
    raised in its thread)."""

    def __init__(self, period_s: float, fn: Callable[[], None], name: str,
                 ok: Callable[[], bool],
                 on_error: Callable[[BaseException], None] | None = None) -> None:
        if not period_s > 0:
            raise ValueError(f"RateLoop period_s must be > 0, got {period_s}")
        self.period_s, self.fn, self.ok = float(period_s), fn, ok
        self.on_error = on_error
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, name=name, daemon=True)
        self._thread.start()

    def _run(self) -> None:
        due = time.monotonic()
        while not self._stop.is_set():
            try:
                self.fn()
            except Exception as exc:
                if self._stop.is_set() or not self.ok():
                    return              # stopped under the tick: not an error
                if self.on_error is None:
                    raise
                self.on_error(exc)
                return
            due += self.period_s
            now = time.monotonic()
            if due < now:
                due = now               # late: go on from now, no catch-up burst
            self._stop.wait(due - now)

    def stop(self, timeout_s: float = 1.0) -> None:
        """End the loop after its current tick; waits up to ``timeout_s`` [s] for it."""
        self._stop.set()
        if self._thread is not threading.current_thread():
            self._thread.join(timeout_s)
