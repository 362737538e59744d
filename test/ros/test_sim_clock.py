"""The simulated graph keeps its own time (ros/simclock.py): the mock arm publishes /clock
advancing by dt per computed cycle, and the motion node measures its pre-flight state rate in
that simulated time. A mock arm forced to a real-time factor of 0.04 (its 100 Hz state comes at
4 Hz of wall time, below the sim graph's 5 Hz pre-flight floor) is a slow simulation, not a slow
robot: the motion node starts, its /diagnostics report the state at its simulated rate and the
real-time factor, WARN "simulation behind" (no ERROR), and the simulated camera, as slow as the
clock, is a camera link that keeps up in simulated time (no ERROR either); the same arm on wall
time is refused."""

from __future__ import annotations

import os
import signal
import time
from pathlib import Path

import pytest

from tactex_ros.ros.devrun.launcher import Graph
from tactex_ros.ros.graph import SIM_MIN_STATE_RATE_HZ, describe

pytestmark = pytest.mark.ros

RTF = 0.04        # the forced pace: 100 Hz simulated = 4 Hz wall, below SIM_MIN_STATE_RATE_HZ


def _wait(cond, timeout_s: float) -> bool:
    end = time.monotonic() + timeout_s
    while time.monotonic() < end:
        if cond():
            return True
        time.sleep(0.1)
    return bool(cond())


def _graph(sim_clock: bool, camera: bool = False):
    names = ("mock_arm", "motion") + (("mock_image",) if camera else ())
    return [n for n in describe(True, mock_arm={"max_real_time_factor": RTF},
                                sim_clock=sim_clock)
            if n.name in names]


def test_a_slow_simulation_passes_the_pre_flight_in_simulated_time(
        tmp_path: Path, listener, active) -> None:
    from diagnostic_msgs.msg import DiagnosticArray
    from geometry_msgs.msg import PoseStamped
    from rclpy.qos import qos_profile_sensor_data
    from rosgraph_msgs.msg import Clock

    from tactex_ros.ros.settings import POSE_TOPIC
    from tactex_ros.ros.simclock import clock_qos
    assert RTF * 100.0 < SIM_MIN_STATE_RATE_HZ
    nodes = _graph(True, camera=True)
    assert all(n.parameters.get("use_sim_time") is True for n in nodes)
    clocks: list[tuple[float, float]] = []      # (wall arrival [s], simulated time [s])
    listener.node.create_subscription(
        Clock, "/clock", lambda m: clocks.append(
            (time.monotonic(), m.clock.sec + m.clock.nanosec * 1e-9)), clock_qos())
    poses: list[float] = []
    listener.node.create_subscription(PoseStamped, POSE_TOPIC,
                                      lambda _m: poses.append(time.monotonic()),
                                      qos_profile_sensor_data)
    diags = listener.collect(DiagnosticArray, "/diagnostics", 50)
    timed: list = []                   # (wall arrival [s], DiagnosticArray)
    listener.node.create_subscription(DiagnosticArray, "/diagnostics",
                                      lambda m: timed.append((time.monotonic(), m)), 50)

    def status(name: str):
        return [s for m in list(diags) for s in m.status if s.name == name]

    def link_seen(after: float) -> list:      # camera link statuses arrived after ``after``
        return [s for t, m in list(timed) if t > after for s in m.status
                if s.name == "motion: camera link"
                and any(v.key == "received" and int(v.value) > 0 for v in s.values)]

    with Graph(nodes, tmp_path / "logs", listener.domain_id) as g:
        assert active("motion", 150.0), (tmp_path / "logs" / "motion.log").read_text()[-2000:]
        time.sleep(15.0)      # 0.6 s of simulated time: the state's rate window fills
        assert _wait(lambda: link_seen(0.0), 60.0), "no camera image reached the motion node"
        # the camera's process starved for 1.5 s of wall time (not scheduled: SIGSTOP) while
        # the clock went on at RTF: 0.06 s of simulated time, no stale camera in the sim
        pid = g.procs["mock_image"].pid
        os.kill(pid, signal.SIGSTOP)
        try:
            time.sleep(1.5)
        finally:
            os.kill(pid, signal.SIGCONT)
        t_cont = time.monotonic()
        assert _wait(lambda: len(link_seen(t_cont)) >= 2, 30.0), "no camera link status after"
        t_end = time.monotonic()
    # the clock advanced by dt per cycle at the forced pace (not by the wall clock)
    recent = [c for c in clocks if c[0] > clocks[0][0] + 2.0] if clocks else []
    assert len(recent) > 10, len(clocks)
    (w0, s0), (w1, s1) = recent[0], recent[-1]
    assert abs((s1 - s0) / (w1 - w0) - RTF) < 0.5 * RTF, (s1 - s0) / (w1 - w0)
    # the state's wall rate was below the pre-flight floor all along
    wall_rate = len([t for t in poses if t > t_end - 10.0]) / 10.0
    assert wall_rate < SIM_MIN_STATE_RATE_HZ, wall_rate
    arm = [s for s in status("motion: arm")
           if any(v.key == "real-time factor" for v in s.values)]
    assert arm, [s.message for s in status("motion: arm")]
    vals = {v.key: v.value for v in arm[-1].values}
    assert float(vals["real-time factor"]) < 0.5 and float(vals["state rate [Hz]"]) > 2 * RTF * 100.0, vals
    assert arm[-1].level == b"\x01", (arm[-1].level, arm[-1].message)        # WARN, no ERROR
    mock = [s for s in status("mock_arm: arm")
            if any(v.key == "real-time factor" for v in s.values)]
    assert mock and mock[-1].level == b"\x01", [(s.level, s.message) for s in mock[-1:]]
    # the camera's frames come at 25 Hz of simulated time (1 Hz of wall time): in simulated
    # time the link keeps up; never an ERROR (on wall time its frames are 1 s old: ERROR)
    link = [s for s in status("motion: camera link")
            if any(v.key == "received" and int(v.value) > 0 for v in s.values)]
    assert link, [(s.level, s.message) for s in status("motion: camera link")[-3:]]
    assert all(s.level != b"\x02" for s in link), [s.message for s in link
                                                   if s.level == b"\x02"][:3]


def test_the_same_slow_arm_on_wall_time_is_refused(tmp_path: Path, domain_id: int) -> None:
    """Without the simulated clock the pre-flight measures 4 Hz of wall time: exit 1."""
    with Graph(_graph(False), tmp_path / "logs", domain_id) as g:
        proc = g.procs["motion"]
        end = time.monotonic() + 150.0
        while proc.poll() is None and time.monotonic() < end:
            time.sleep(0.2)
        code = proc.poll()
    assert code == 1, (code, (tmp_path / "logs" / "motion.log").read_text()[-2000:])
