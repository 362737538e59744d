"""The pre-flight's ROS side: a probe that samples topics and calls services while a node
configures, whether or not that node already spins in an executor (autostart: not yet; under a
lifecycle manager: configure runs inside its executor's callback). The probe is a plain node in
the same context with its own executor, spun in the calling thread; every wait has a deadline.
What the samples mean is decided in ``robot/preflight.py``. ``robot_preflight`` is the robot's
pre-flight before the arm moves, one for the motion node and ``tactex robot measure-scene``."""

from __future__ import annotations

import time
from dataclasses import replace
from typing import TYPE_CHECKING, Any

from rclpy.context import Context
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node

from ..core.errors import InputError, TrialError
from ..robot.robots import fill_message, import_interface

if TYPE_CHECKING:
    from ..robot.robots import RobotProfile
    from ..robot.scene import PressSettings
    from .settings import MotionSettings

SPIN_S = 0.02     # [s] longest single wait of the probe's executor
#: [s wall] how old a probe is before its view of the graph counts as settled: a participant
#: whose first discovery exchange was lost is seen at its next periodic announcement (Fast
#: DDS: every 3 s; here a publisher in another process was seen 0.1 s, or 2.5-2.8 s in 5 of
#: 12 tries, after a new process's probe started)
DISCOVERY_S = 4.0


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


def arm_topics(s: MotionSettings, prof: RobotProfile,
               press_action: str = "") -> list[tuple[str, str]]:
    """(what, topic) that only one graph per arm publishes (``other_graph``): the arm's target,
    the press action's status where ``press_action`` is served, the robot state (``s``: the
    settings with the profile's topics filled in, ``robots.with_profile``)."""
    state = [s.state_topic] if prof.franka_state else [s.pose_topic, s.wrench_topic]
    action = ([("the press action's status", f"{press_action}/_action/status")]
              if press_action else [])
    return ([("the arm's target", s.target_topic)] + action
            + [("the robot state", t) for t in state])


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
        self.born = time.monotonic()            # [s wall] discovery starts here
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

    def settled_graph(self, topics: list[tuple[str, str]],
                      settle_s: float = DISCOVERY_S) -> str | None:
        """``other_graph`` asked while this probe spins until it is ``settle_s`` [s wall]
        old (discovery has no deadline: the motion node asks again until its first goal, a
        command that moves the arm at once asks here until then): the first problem, None
        when there is none by then."""
        while True:
            problem = self.other_graph(topics)
            if problem or time.monotonic() >= self.born + settle_s:
                return problem
            self._spin()

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


#: how a refused collision start says the thresholds were set by hand (the motion node's)
BY_HAND = "the motion parameter collision_set_by_hand: true"


def robot_preflight(probe: Probe, prof: RobotProfile, press: PressSettings,
                    s: MotionSettings, graph_topics: list[tuple[str, str]], log: Any,
                    by_hand: str = BY_HAND) -> None:
    """The robot's pre-flight before any target is published (the motion node's module doc,
    docs/hardware_checks.md), in this order: franka's collision request against ``press``
    (the press that will run), the robot state sampled over ``s.preflight_window_s`` after its
    first message (within ``s.preflight_deadline_s``), one graph per arm (``graph_topics``:
    at most one publisher each, the caller's own target publisher counted), the state rate
    (at least ``s.min_state_rate_hz``), franka's ``robot_mode`` (the state's, or the profile's
    mode topic), then the collision thresholds set through the profile's service (or
    ``s.collision_set_by_hand``; ``by_hand`` names that switch in the refusal). ``s``: the
    settings with the profile's topics and rate filled in (``robots.with_profile``); ``log``:
    a logger (info, warning). The first problem is raised: DeviceError (state silent),
    DeviceNotReady (state slow, not in move mode), InputError (another graph, collision
    thresholds, no robot_mode message)."""
    from geometry_msgs.msg import PoseStamped, WrenchStamped

    from ..robot import preflight as checks
    from . import adapter
    if prof.collision is not None:
        problem = checks.collision_problem(prof.collision.request, press.max_force,
                                           press.tare_max_offset_n)
        if problem:
            raise InputError(str(problem))
    if prof.franka_state:
        topics = [(import_interface(prof.state_type), s.state_topic, prof.state_qos)]
    else:
        topics = [(PoseStamped, s.pose_topic, prof.pose_qos),
                  (WrenchStamped, s.wrench_topic, prof.wrench_qos)]
    mode = None
    min_rate = s.min_state_rate_hz
    samples = probe.sample_all([(mtype, topic, adapter.qos_profile(qos))
                                for mtype, topic, qos in topics],
                               s.preflight_window_s, s.preflight_deadline_s)
    # one graph per arm, checked once the sampling gave discovery its time (the motion node
    # checks again until its first goal)
    problem_text = probe.other_graph(graph_topics)
    if problem_text:
        raise InputError(f"pre-flight: {problem_text}")
    for (_, topic, _), (stamps, last) in zip(topics, samples, strict=True):
        problem = checks.state_problem(stamps, min_rate, s.preflight_window_s, topic)
        if problem and problem.check == "state_rate" and prof.name == "sim":
            problem = replace(problem, text=problem.text + "; in this simulated graph "
                              "the simulation is behind: the mock arm could not keep "
                              "its rate on this machine")
        if problem:     # silent: DeviceError; slow: DeviceNotReady (exit status 1)
            raise problem.error()
        log.info(f"pre-flight: {topic} at {checks.rate_hz(stamps):.0f} Hz")
        if prof.franka_state:
            mode = int(last.robot_mode)
    if mode is None and prof.mode_topic:
        mode = _preflight_mode(probe, prof, s, log)
    problem = checks.mode_problem(mode)
    if problem:
        raise problem.error()       # not in move mode: DeviceNotReady (exit status 1)
    if prof.collision is not None:
        _preflight_collision(probe, prof, s, log, by_hand)
    else:
        log.info(f"pre-flight: robot profile {prof.name!r} names no collision-threshold "
                 "service (nothing to set)")


def _preflight_mode(probe: Probe, prof: RobotProfile, s: MotionSettings,
                    log: Any) -> int | None:
    """robot_mode from the profile's full state topic; None where its type is missing."""
    from ..robot import preflight as checks
    from . import adapter
    try:
        mtype = import_interface(prof.mode_type)
    except InputError as exc:
        log.warning(f"pre-flight: robot mode not checked: {exc}")
        return None
    topic = s.mode_topic
    _stamps, last = probe.sample(mtype, topic, adapter.qos_profile(prof.mode_qos), 0.0,
                                 s.preflight_deadline_s)
    if last is None:
        raise InputError(str(checks.Problem(
            "robot_mode", f"no message on {topic} within preflight_deadline_s "
                          f"({s.preflight_deadline_s} s)")))
    return int(last.robot_mode)


def _preflight_collision(probe: Probe, prof: RobotProfile, s: MotionSettings, log: Any,
                         by_hand: str) -> None:
    """Set franka's collision thresholds (the profile's request) through the profile's
    service; refuse with the command to run where its type is not installed or franka
    refuses (it takes the call only while no controller claims the arm), unless
    ``s.collision_set_by_hand``."""
    from ..robot import preflight as checks
    col = prof.collision
    if col is None:
        return
    command = checks.collision_command(col.service, col.type, col.request)
    if s.collision_set_by_hand:
        log.warning("pre-flight: collision thresholds set by hand (collision_set_by_hand; "
                    f"{col.request_file}), not verified here")
        return
    try:
        ctype = import_interface(col.type)
    except InputError as exc:
        raise InputError(str(checks.Problem(
            "collision", f"the thresholds cannot be set from here ({exc}); set them with "
                         f"`{command}` and start again with {by_hand}"))) from None
    try:
        probe.call(ctype, col.service, col.request, "success", s.preflight_deadline_s)
    except TrialError as exc:
        raise InputError(str(checks.Problem(
            "collision", f"{exc}; franka takes the call only while no controller claims "
                         f"the arm: run `{command}` before the controller is spawned (the "
                         f"bring-up in docs/hardware.md does) and start again with "
                         f"{by_hand}"))) from None
    log.info(f"pre-flight: franka collision thresholds set ({col.request_file})")
