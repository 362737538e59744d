"""The pre-flight's ROS side: a probe that samples topics and calls services while a node
configures, whether or not that node already spins in an executor (autostart: not yet; under a
lifecycle manager: configure runs inside its executor's callback). The probe is a plain node in
the same context with its own executor, spun in the calling thread; every wait has a deadline.
What the samples mean is decided in ``robot/preflight.py``."""

from __future__ import annotations

import time
from typing import Any

from rclpy.context import Context
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node

from ..core.errors import TrialError
from ..robot.robots import fill_message

SPIN_S = 0.02     # [s] longest single wait of the probe's executor


def other_graph(node: Node, topics: list[tuple[str, str]]) -> str | None:
    """One graph per arm: each of ``topics`` ((what, topic)) must have at most one publisher
    on this ROS domain as ``node`` sees the graph (this graph's: the arm's target and the press
    action's status are this motion node's, the robot state the robot's). A second one is
    another tactex graph, or another program driving or playing the arm; the problem names the
    topic and the publishing nodes, None when there is none. Discovery takes an unbounded
    time, so the motion node asks during its pre-flight and again until it takes a goal."""
    for what, topic in topics:
        name = node.resolve_topic_name(topic)
        pubs = node.get_publishers_info_by_topic(name)
        if len(pubs) > 1:
            nodes = sorted({f"{p.node_namespace.rstrip('/')}/{p.node_name}" for p in pubs})
            return (f"{len(pubs)} publishers of {what} {name} on ROS_DOMAIN_ID "
                    f"{node.context.get_domain_id()} (nodes {', '.join(nodes)}): another "
                    "tactex graph or program drives this arm; stop it, or give each graph "
                    "its own ROS_DOMAIN_ID (docs/hardware.md)")
    return None


class Stopped(Exception):
    """The context was shut down (SIGINT, SIGTERM) during the pre-flight."""


class Probe:
    """Samples and service calls for a pre-flight, on a helper node ``name`` in ``context``."""

    def __init__(self, context: Context, name: str, sim_time: bool = False) -> None:
        from rclpy.parameter import Parameter

        from .simclock import NodeClock
        self.context = context
        # not renamed by the process's `-r __node:=...` (that names the lifecycle node);
        # ``sim_time``: this probe's windows and deadlines are on the simulated clock (/clock,
        # spun by this probe's own executor), as the simulated graph's nodes are
        self.node = Node(name, context=context, use_global_arguments=False,
                         parameter_overrides=[Parameter("use_sim_time", value=True)]
                         if sim_time else [])
        self.now = NodeClock(self.node).now     # [s] monotonic, or simulated time
        self.sim = sim_time
        self.executor = SingleThreadedExecutor(context=context)
        self.executor.add_node(self.node)

    def _spin(self) -> None:
        if not self.context.ok():
            raise Stopped()
        self.executor.spin_once(timeout_sec=SPIN_S)

    def _clock_started(self) -> None:
        """On the simulated clock: spin until the first /clock (``NodeClock`` raises
        ``SimClockStalled`` when none comes within its wall-time limit)."""
        while self.sim and self.now() <= 0.0:
            self._spin()

    def other_graph(self, topics: list[tuple[str, str]]) -> str | None:
        """``other_graph`` as this probe's node sees the ROS graph."""
        return other_graph(self.node, topics)

    def sample(self, msg_type: type, topic: str, qos: Any, window_s: float,
               deadline_s: float) -> tuple[list[float], Any]:
        """Arrival times [s, monotonic or simulated: ``self.now``] of ``topic``'s messages over ``window_s`` after the
        first one (which must come within ``deadline_s``), and the last message (None if
        none)."""
        return self.sample_all([(msg_type, topic, qos)], window_s, deadline_s)[0]

    def sample_all(self, topics: list[tuple[type, str, Any]], window_s: float,
                   deadline_s: float) -> list[tuple[list[float], Any]]:
        """``sample`` of every (type, topic, QoS) of ``topics`` at once: each topic's window
        starts at its own first message; all end within ``deadline_s`` + ``window_s``."""
        stamps: list[list[float]] = [[] for _ in topics]
        last: list[Any] = [None] * len(topics)

        def on(i: int):
            def got(msg: Any) -> None:
                # on the simulated clock a stamped message counts at its own stamp (the
                # simulated time it was computed at): a starved probe that reads /clock (keep
                # last 1) late must not see the stream as slow
                stamp = getattr(getattr(msg, "header", None), "stamp", None)
                t = stamp.sec + stamp.nanosec * 1e-9 if self.sim and stamp is not None else 0.0
                stamps[i].append(t if t > 0.0 else self.now())
                last[i] = msg
            return got
        subs = [self.node.create_subscription(t, name, on(i), qos)
                for i, (t, name, qos) in enumerate(topics)]
        try:
            self._clock_started()
            start = self.now()

            def open_window() -> bool:
                now = self.now()
                return any((not st and now < start + deadline_s) or
                           (st and now < st[0] + window_s) for st in stamps)
            while open_window():
                self._spin()
        finally:
            for sub in subs:
                self.node.destroy_subscription(sub)
        return [([t for t in st if t <= st[0] + window_s] if st else [], lt)
                for st, lt in zip(stamps, last, strict=True)]

    def call(self, srv_type: type, name: str, request: dict[str, Any], ok_field: str,
             deadline_s: float) -> Any:
        """Call service ``name`` with ``request``'s fields; the response, or TrialError when
        the service is not there within ``deadline_s``, does not answer in time, or answers
        ``ok_field`` false (its ``error`` / ``message`` text named)."""
        client = self.node.create_client(srv_type, name)
        try:
            self._clock_started()
            end = self.now() + deadline_s
            while not client.service_is_ready():
                if self.now() > end:
                    raise TrialError(f"service {name} is not offered (waited {deadline_s} s)")
                self._spin()
            fut = client.call_async(fill_message(srv_type.Request(), request, name))
            while not fut.done():
                if self.now() > end:
                    client.remove_pending_request(fut)
                    raise TrialError(f"service {name} did not answer within {deadline_s} s")
                self._spin()
            resp = fut.result()
            if not getattr(resp, ok_field, False):
                detail = getattr(resp, "error", "") or getattr(resp, "message", "")
                raise TrialError(f"service {name} answered {ok_field} = false"
                                  + (f": {detail}" if detail else ""))
            return resp
        finally:
            self.node.destroy_client(client)

    def close(self) -> None:
        self.executor.remove_node(self.node)
        self.executor.shutdown(timeout_sec=0.0)
        self.node.destroy_node()


def watch_push(probe: Probe, msg_type: type, topic: str, qos: Any, fz_of: Any,
               baseline_s: float, deadline_s: float, push_n: float, hold_s: float,
               prompt: Any) -> tuple:
    """The wrench-sign check: the first message of ``topic`` (subscribed with ``qos``, its
    upstream publisher's) within ``deadline_s`` [s], then
    ``baseline_s`` [s] of hands-off samples (raw f_z by ``fz_of(msg)``), then ``prompt()``, then
    samples until a push is seen (``push_sign``) or ``deadline_s``. Returns (PushReading,
    hands-off samples, push samples); TrialError when no message comes."""
    from ..robot.preflight import push_sign
    fz: list[float] = []
    times: list[float] = []

    def got(msg: Any) -> None:
        times.append(time.monotonic())
        fz.append(float(fz_of(msg)))
    sub = probe.node.create_subscription(msg_type, topic, got, qos)
    try:
        end = time.monotonic() + deadline_s
        while not fz and time.monotonic() < end:     # the first message (discovery)
            probe._spin()
        if not fz:
            raise TrialError(f"no message on {topic} within {deadline_s} s: is the robot's "
                             "bring-up running (or the topic name right)?")
        end = time.monotonic() + baseline_s
        while time.monotonic() < end:
            probe._spin()
        baseline, n0 = list(fz), len(fz)
        prompt()
        end = time.monotonic() + deadline_s
        look = time.monotonic()
        while time.monotonic() < end:
            probe._spin()
            if time.monotonic() >= look:          # evaluated every 0.1 s, not per message
                look = time.monotonic() + 0.1
                reading = push_sign(baseline, times[n0:], fz[n0:], push_n, hold_s)
                if reading.force_sign:
                    return reading, n0, len(fz) - n0
        return push_sign(baseline, times[n0:], fz[n0:], push_n, hold_s), n0, len(fz) - n0
    finally:
        probe.node.destroy_subscription(sub)
