"""Real-process ROS 2 test helpers: an isolated DDS domain per test and a listener node."""

from __future__ import annotations

import itertools
import os
import threading
import time

import pytest

rclpy = pytest.importorskip("rclpy")



def _domain_ids() -> itertools.cycle[int]:
    """DDS domains of this test process: 1..159 shared out among pytest-xdist workers (each its
    own block, so parallel workers never share a graph; 160..199 are the session module's);
    cycled from a place set by the process id, so two test runs at once on one machine rarely
    share a domain (a latched message of the other would arrive), and a long run stays within
    Fast DDS's valid ids (<= 232)."""
    worker = os.environ.get("PYTEST_XDIST_WORKER", "gw0")
    index = int(worker[2:]) if worker[2:].isdigit() else 0
    count = max(1, int(os.environ.get("PYTEST_XDIST_WORKER_COUNT", "1")))
    size = 159 // count
    block = list(range(1 + index * size, 1 + (index + 1) * size))
    start = os.getpid() % size       # two test runs on one machine (two checkouts) rarely meet
    return itertools.cycle(block[start:] + block[:start])


_domains = _domain_ids()


class Listener:
    """A node in the test process with its own context, spun in a background thread."""

    def __init__(self, domain_id: int) -> None:
        from rclpy.executors import SingleThreadedExecutor
        self.domain_id = domain_id
        self.ctx = rclpy.Context()
        rclpy.init(context=self.ctx, domain_id=domain_id)
        self.node = rclpy.create_node("test_listener", context=self.ctx)
        self.ex = SingleThreadedExecutor(context=self.ctx)
        self.ex.add_node(self.node)
        self.errors: list[str] = []     # exceptions raised in the listener's callbacks
        self.thread = threading.Thread(target=self._spin, daemon=True)
        self.thread.start()

    def _spin(self) -> None:
        """Spin until the context shuts down. A callback's exception is kept in ``errors`` and
        the spin goes on: a listener that stopped silently would leave every later future of
        the test unanswered."""
        while self.ctx.ok():
            try:
                self.ex.spin_once(timeout_sec=0.1)
            except Exception as exc:  # noqa: BLE001 - kept for the test's failure message
                if not self.ctx.ok():
                    return          # the context shut down at teardown
                self.errors.append(repr(exc))

    def collect(self, msg_type, topic: str, qos=10) -> list:
        """Subscribe and return the list that receives every message."""
        got: list = []
        self.node.create_subscription(msg_type, topic, got.append, qos)
        return got

    def close(self) -> None:
        self.ex.shutdown(timeout_sec=1.0)
        self.node.destroy_node()
        rclpy.shutdown(context=self.ctx)


class ForceTrace:
    """What the mock arm reports and what it is told, as the listener receives them: the
    normal force (``f``, N), the pose's height (``z``, m) and the equilibrium target's height
    (``target``, m), each row ``(arrival time [s, monotonic], kind, value)``. ``check`` holds
    the force limit at every sample and, where it is broken, names when, with the rows around
    the peak. Topics and QoS: the sim profile's (config/robots/sim.yaml)."""

    def __init__(self, listener: Listener) -> None:
        from geometry_msgs.msg import PoseStamped, WrenchStamped
        from rclpy.qos import qos_profile_sensor_data

        from tactex_ros.ros.settings import POSE_TOPIC, TARGET_TOPIC, WRENCH_TOPIC
        self.rows: list[tuple[float, str, float]] = []
        add = self.rows.append
        node = listener.node
        node.create_subscription(WrenchStamped, WRENCH_TOPIC, lambda m: add(
            (time.monotonic(), "f", m.wrench.force.z)), qos_profile_sensor_data)
        node.create_subscription(PoseStamped, POSE_TOPIC, lambda m: add(
            (time.monotonic(), "z", m.pose.position.z)), qos_profile_sensor_data)
        node.create_subscription(PoseStamped, TARGET_TOPIC, lambda m: add(
            (time.monotonic(), "target", m.pose.position.z)), 10)

    def forces(self, since: float = 0.0) -> list[float]:
        """[N] every normal force received at or after ``since`` (monotonic s)."""
        return [v for t, k, v in list(self.rows) if k == "f" and t >= since]

    def check(self, limit: float, since: float = 0.0, label: str = "") -> None:
        """Every force since ``since`` at most ``limit`` [N]; else an AssertionError naming the
        peak, its time after ``since`` and the rows of the second before it."""
        rows = [r for r in list(self.rows) if r[0] >= since]
        forces = [r for r in rows if r[1] == "f"]
        assert forces, f"{label}: no force received"
        t, _, peak = max(forces, key=lambda r: r[2])
        if peak <= limit:
            return
        near = "\n".join(f"  {r[0] - since:8.3f} s {r[1]:>6} {r[2]:+.4f}" for r in rows
                         if t - 1.0 <= r[0] <= t + 0.2)
        raise AssertionError(f"{label}: force {peak:.2f} N > {limit} N at {t - since:.3f} s "
                             f"after the start; the rows around it:\n{near}")


@pytest.fixture(scope="session")
def quick_scene() -> str:
    """config/scene_sim.yaml as shipped: its press is the lab scene's (config/scene.yaml, about
    3 s a press: docs/research/press_speed.md), so the graph tests press as a lab does. (It
    used to be a shortened copy of a 22 s press.)"""
    from tactex_ros.core.paths import config_dir
    return str(config_dir() / "scene_sim.yaml")


#: The small scene's platforms: the shipped simulated scene's reference and its first two
#: comparisons (c1 holds the reference's fabric)
SMALL_PLATFORMS = ("reference", "c1", "c2")


@pytest.fixture(scope="session")
def small_scene(tmp_path_factory) -> str:
    """config/scene_sim.yaml as shipped with its reference and first two comparisons only
    (``SMALL_PLATFORMS``, 1 + 2): the shipped press settings, layout and fabrics, a baseline
    of 3 presses instead of 5. For the tests whose point is a trial's or a session's course
    (resume, faults, operator actions, outputs), not how many platforms a scene has; the
    sessions they run list two comparisons (test/data/session_*_small.yaml)."""
    import yaml
    from tactex_ros.core.paths import config_dir
    doc = yaml.safe_load((config_dir() / "scene_sim.yaml").read_text())
    doc["platforms"] = [p for p in doc["platforms"] if p["id"] in SMALL_PLATFORMS]
    if [p["id"] for p in doc["platforms"]] != list(SMALL_PLATFORMS):
        raise ValueError(f"config/scene_sim.yaml no longer has platforms {SMALL_PLATFORMS}")
    path = tmp_path_factory.mktemp("scene") / "scene_sim_small.yaml"
    path.write_text(yaml.safe_dump(doc, sort_keys=False))
    return str(path)


@pytest.fixture
def domain_id() -> int:
    return next(_domains)


@pytest.fixture
def listener(domain_id):
    lst = Listener(domain_id)
    yield lst
    lst.close()


def press_goal(listener: Listener, platform_id: str, timeout: float = 90.0,
               answer_s: float = 2.0, client=None, run_id: str = ""):
    """Send a Press goal to ``/tactex/press`` and return its result (``None``: rejected).

    Through ``tactex_ros.ros.goal.GoalRequest``, as the explorer does: a goal whose response
    is lost (right after discovery) is re-sent after ``answer_s`` and the first one followed by
    its goal id. ``client``: an ActionClient to use (default: a new one on the listener);
    ``run_id``: the graph identity the goal carries (an explorer's).
    Fails the test at ``timeout`` seconds.
    """
    import time

    from action_msgs.msg import GoalStatus
    from rclpy.action import ActionClient
    from tactex.action import Press

    from tactex_ros.ros.goal import GoalRequest

    ac = client or ActionClient(listener.node, Press, "/tactex/press")
    if not ac.wait_for_server(timeout_sec=30.0):
        pytest.fail("no /tactex/press server within 30 s")
    end = time.monotonic() + timeout
    goal = Press.Goal(platform_id=platform_id, run_id=run_id)
    # a request whose every send went unanswered (the server's readers not yet matched on a
    # loaded machine) is asked again as a new request after 30 s, as the explorer's is
    req = GoalRequest(ac, goal, answer_s=answer_s, renew_s=30.0)
    while not req.finished() and time.monotonic() < end:
        time.sleep(0.02)
    if not req.answered():
        pytest.fail(f"press goal for {platform_id} not answered within {timeout} s "
                    f"(listener callback errors: {listener.errors or 'none'})")
    if req.refused:
        return None
    if not req.finished():
        pytest.fail(f"press of {platform_id} did not finish within {timeout} s")
    if req.result.status == GoalStatus.STATUS_UNKNOWN:
        pytest.fail(f"press goal for {platform_id} lost: the server never took it")
    return req.result.result


@pytest.fixture
def press(listener):
    """``press(platform_id, timeout=90.0)``: :func:`press_goal` through the test's listener."""
    return lambda platform_id, timeout=90.0: press_goal(listener, platform_id, timeout)


@pytest.fixture
def force_trace(listener) -> ForceTrace:
    """The test's :class:`ForceTrace`, subscribed from the start."""
    return ForceTrace(listener)


@pytest.fixture
def active(listener):
    """``active(node, deadline_s)``: True once lifecycle node ``node`` reports the active state
    (its get_state service, asked through the test's listener), False at the deadline."""
    from lifecycle_msgs.msg import State
    from lifecycle_msgs.srv import GetState

    def wait(node: str, deadline_s: float) -> bool:
        client = listener.node.create_client(GetState, f"/{node}/get_state")
        end = time.monotonic() + deadline_s
        try:
            while time.monotonic() < end:
                if client.wait_for_service(timeout_sec=1.0):
                    fut = client.call_async(GetState.Request())
                    while not fut.done() and time.monotonic() < end:
                        time.sleep(0.05)
                    if (fut.done() and
                            fut.result().current_state.id == State.PRIMARY_STATE_ACTIVE):
                        return True
                time.sleep(0.2)
            return False
        finally:
            listener.node.destroy_client(client)
    return wait


@pytest.fixture
def press_as(listener):
    """``press_as(platform_id, run_id, timeout=90.0)``: :func:`press_goal` carrying an
    explorer's ``run_id`` (its graph identity)."""
    return lambda platform_id, run_id, timeout=90.0: press_goal(listener, platform_id, timeout,
                                                                run_id=run_id)
