"""Every node through configure -> activate -> deactivate -> activate -> cleanup -> shutdown,
driven by its lifecycle services (as a lifecycle manager would), in this process with its own
context and DDS domain. Checked: the node publishes only while active; after cleanup it holds
exactly the ROS entities it had before configure; the press action server exists once and takes
goals only while active; shutdown ends in ``finalized``."""

from __future__ import annotations

import contextlib
import json
import threading
import time
from pathlib import Path

import cv2
import numpy as np
import pytest

rclpy = pytest.importorskip("rclpy")

from geometry_msgs.msg import PoseStamped  # noqa: E402
from lifecycle_msgs.msg import State, Transition  # noqa: E402
from lifecycle_msgs.srv import ChangeState, GetState  # noqa: E402
from rclpy.action import ActionClient  # noqa: E402
from rclpy.executors import SingleThreadedExecutor  # noqa: E402
from rclpy.parameter import Parameter  # noqa: E402
from rclpy.qos import qos_profile_sensor_data  # noqa: E402
from sensor_msgs.msg import Image  # noqa: E402
from visualization_msgs.msg import MarkerArray  # noqa: E402

from tactex_ros.ros.nodes.lifecycle import entities, wait_for  # noqa: E402
from tactex_ros.core.paths import config_dir  # noqa: E402

pytestmark = pytest.mark.ros
SCENE = str(config_dir() / "scene_sim.yaml")


class Bench:
    """The node under test and a manager node in one context, spun by one executor thread."""

    def __init__(self, domain_id: int, factory, params: dict) -> None:
        self.ctx = rclpy.Context()
        rclpy.init(context=self.ctx, domain_id=domain_id)
        overrides = [Parameter(k, value=v) for k, v in {"autostart": False, **params}.items()]
        self.node = factory(context=self.ctx, parameter_overrides=overrides)
        self.manager = rclpy.create_node("lifecycle_manager", context=self.ctx)
        self.ex = SingleThreadedExecutor(context=self.ctx)
        self.ex.add_node(self.node)
        self.ex.add_node(self.manager)
        self.thread = threading.Thread(target=self._spin, daemon=True)
        self.thread.start()
        name = self.node.get_name()
        self.change = self.manager.create_client(ChangeState, f"/{name}/change_state")
        self.get = self.manager.create_client(GetState, f"/{name}/get_state")

    def _spin(self) -> None:
        with contextlib.suppress(Exception):   # the context shut down at the end
            self.ex.spin()

    #: the state each transition ends in (lifecycle_msgs Transition -> State ids)
    ENDS_IN = {Transition.TRANSITION_CONFIGURE: State.PRIMARY_STATE_INACTIVE,
               Transition.TRANSITION_CLEANUP: State.PRIMARY_STATE_UNCONFIGURED,
               Transition.TRANSITION_ACTIVATE: State.PRIMARY_STATE_ACTIVE,
               Transition.TRANSITION_DEACTIVATE: State.PRIMARY_STATE_INACTIVE}

    def transition(self, tid: int) -> None:
        """Ask for transition ``tid`` until it is answered (60 s in all). A request sent while
        DDS discovery is still matching the service's reply writer to this client can go
        unanswered on a loaded machine: if the node is then already in the transition's end
        state the reply was lost, else the request was, and it is sent again."""
        assert self.change.wait_for_service(timeout_sec=10.0)
        deadline = time.monotonic() + 60.0
        while True:
            fut = self.change.call_async(ChangeState.Request(transition=Transition(id=tid)))
            while not wait_for(fut, 10.0):
                assert time.monotonic() < deadline, f"transition {tid} not answered in 60 s"
                now = self.state()
                if now == self.ENDS_IN.get(tid):
                    return                           # done; only its reply was lost
                if now < State.TRANSITION_STATE_CONFIGURING:
                    break                            # not started: the request was lost
                # still in the transition (a slow configure): wait for its reply
            else:
                # a resent request after the first one did arrive fails: the state decides
                assert fut.result().success or self.state() == self.ENDS_IN.get(tid), \
                    f"transition {tid} failed"
                return

    def state(self) -> int:
        """The node's lifecycle state id (asked again while a request goes unanswered, 60 s)."""
        deadline = time.monotonic() + 60.0
        while True:
            fut = self.get.call_async(GetState.Request())
            if wait_for(fut, 10.0):
                return fut.result().current_state.id
            assert time.monotonic() < deadline, "get_state not answered in 60 s"

    def close(self) -> None:
        self.ex.shutdown(timeout_sec=2.0)
        self.node.destroy_node()
        self.manager.destroy_node()
        rclpy.shutdown(context=self.ctx)


def _quiet(got: list, quiet_s: float = 0.5, deadline_s: float = 10.0) -> None:
    """Wait until nothing has arrived in ``got`` for ``quiet_s`` (what was sent before a
    deactivation reaches a loaded machine late), up to ``deadline_s``."""
    end = time.monotonic() + deadline_s
    n, since = len(got), time.monotonic()
    while time.monotonic() < end and time.monotonic() - since < quiet_s:
        time.sleep(0.02)
        if len(got) != n:
            n, since = len(got), time.monotonic()


def _cycle(bench: Bench, got: list, active_s: float = 1.5, on_active=None) -> None:
    """The transition sequence; ``got`` receives the node's messages: none while inactive,
    some while active. ``on_active(bench, round)`` runs in each active phase."""
    node = bench.node
    before = entities(node)
    bench.transition(Transition.TRANSITION_CONFIGURE)
    assert entities(node) > before                 # configure made its entities
    time.sleep(1.0)
    assert got == [], "published while inactive (configured)"
    for rnd in (1, 2):
        bench.transition(Transition.TRANSITION_ACTIVATE)
        assert bench.state() == State.PRIMARY_STATE_ACTIVE
        n0 = len(got)
        if on_active is not None:
            on_active(bench, rnd)
        end = time.monotonic() + active_s + 10.0
        while len(got) == n0 and time.monotonic() < end:
            time.sleep(0.05)
        time.sleep(active_s)
        assert len(got) > n0, f"nothing published while active (round {rnd})"
        bench.transition(Transition.TRANSITION_DEACTIVATE)
        _quiet(got)                                # messages already on the wire arrive
        n1 = len(got)
        time.sleep(1.0)                            # a window in which nothing may arrive
        assert len(got) == n1, f"published while inactive (round {rnd})"
    bench.transition(Transition.TRANSITION_CLEANUP)
    assert bench.state() == State.PRIMARY_STATE_UNCONFIGURED
    assert entities(node) == before, "cleanup left entities behind"
    bench.transition(Transition.TRANSITION_UNCONFIGURED_SHUTDOWN)
    assert bench.state() == State.PRIMARY_STATE_FINALIZED


@pytest.fixture
def bench(domain_id):
    made: list[Bench] = []

    def make(factory, params: dict) -> Bench:
        made.append(Bench(domain_id, factory, params))
        return made[-1]
    yield make
    for b in made:
        b.close()


def test_mock_arm_lifecycle(bench) -> None:
    from tactex_ros.ros.nodes.mock_arm_node import MockArmNode
    b = bench(MockArmNode, {"scene_file": SCENE, "rate_hz": 20.0})
    got: list = []
    b.manager.create_subscription(PoseStamped, "/franka_robot_state_broadcaster/current_pose",
                                  got.append, qos_profile_sensor_data)
    _cycle(b, got)


def test_mock_image_lifecycle(bench) -> None:
    from tactex_ros.ros.nodes.mock_image_node import MockImageNode
    b = bench(MockImageNode, {"scene_file": SCENE, "fps": 10.0,
                              "image_topic": "/lifecycle_test/image"})
    got: list = []
    b.manager.create_subscription(Image, "/lifecycle_test/image", got.append,
                                  qos_profile_sensor_data)
    _cycle(b, got)


def test_gelsight_lifecycle(bench, tmp_path: Path) -> None:
    from tactex_ros.ros.nodes.gelsight_node import GelsightNode
    video = tmp_path / "gel.avi"
    w = cv2.VideoWriter(str(video), cv2.VideoWriter_fourcc(*"MJPG"), 20.0, (320, 240))
    rng = np.random.default_rng(0)
    for _ in range(20):
        w.write(rng.integers(0, 255, (240, 320, 3), dtype=np.uint8))
    w.release()
    b = bench(GelsightNode, {"device": str(video), "fps": 20.0, "warmup_frames": 0,
                             "reference_frames": 2, "preflight": False})   # noise frames
    got: list = []
    b.manager.create_subscription(Image, "/tactex/gelsight/image_raw", got.append,
                                  qos_profile_sensor_data)
    _cycle(b, got)


def test_explorer_lifecycle(bench, tmp_path: Path) -> None:
    """Markers (1 Hz) only while active; the trial thread starts on the first activation (no
    press server here: it ends with an error result after server_timeout_s)."""
    from tactex_ros.ros.nodes.explorer_node import ExplorerNode
    b = bench(ExplorerNode, {"scene_file": SCENE, "record_dir": str(tmp_path),
                             "trial_id": "lc", "nice": 0, "server_timeout_s": 0.5})
    got: list = []
    b.manager.create_subscription(MarkerArray, "/tactex/markers", got.append, 10)
    _cycle(b, got, active_s=1.5)
    assert (tmp_path / "lc" / "config.json").is_file()
    # an absent press server is a device absent at run time (core/errors.py), not bad input
    res = json.loads((tmp_path / "lc" / "result.json").read_text())
    assert res["error"].split(":")[0] == "DeviceError", res


def test_motion_lifecycle(bench) -> None:
    """The press action server is made once (configure): a goal is rejected while inactive,
    accepted while active (it fails: no robot state here), and the server is gone after
    cleanup. The node publishes targets only while pressing: none in the whole cycle."""
    from tactex.action import Press

    from tactex_ros.ros.nodes.motion_node import MotionNode
    b = bench(MotionNode, {"scene_file": SCENE, "robot": "sim", "state_timeout_s": 0.05,
                           "preflight": False,                     # no robot state here
                           "capture_wait_s": 1.0})                 # and no camera
    got: list = []
    b.manager.create_subscription(PoseStamped,
                                  "/cartesian_impedance_controller/equilibrium_pose",
                                  got.append, 10)
    client = ActionClient(b.manager, Press, "/tactex/press")

    def goal() -> bool:
        fut = client.send_goal_async(Press.Goal(platform_id="c1"))
        assert wait_for(fut, 15.0), "goal not answered"
        handle = fut.result()
        if handle.accepted:
            res = handle.get_result_async()
            assert wait_for(res, 30.0), "accepted goal did not end"
            assert not res.result().result.success
        return handle.accepted

    def servers() -> int:
        return sum(1 for e in entities(b.node) if type(e).__name__ == "ActionServer")

    before = entities(b.node)
    b.transition(Transition.TRANSITION_CONFIGURE)
    assert servers() == 1
    assert client.wait_for_server(timeout_sec=10.0)
    assert goal() is False                        # inactive: rejected
    for _ in range(2):
        b.transition(Transition.TRANSITION_ACTIVATE)
        assert servers() == 1                     # not made again
        assert goal() is True
        b.transition(Transition.TRANSITION_DEACTIVATE)
        assert goal() is False
    b.transition(Transition.TRANSITION_CLEANUP)
    assert entities(b.node) == before and servers() == 0
    b.transition(Transition.TRANSITION_UNCONFIGURED_SHUTDOWN)
    assert b.state() == State.PRIMARY_STATE_FINALIZED
    assert got == []
