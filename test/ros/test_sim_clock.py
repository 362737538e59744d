"""The simulated graph keeps its own time (ros/simclock.py): the mock arm publishes /clock
advancing by dt per computed cycle, and the motion node measures its pre-flight state rate in
that simulated time. A mock arm forced to a real-time factor of 0.04 (its 100 Hz state comes at
4 Hz of wall time, below the sim graph's 5 Hz pre-flight floor) is a slow simulation, not a slow
robot: the motion node starts, its /diagnostics report the state at its simulated rate and the
real-time factor, WARN "simulation behind" (no ERROR); the same arm on wall time is refused."""

from __future__ import annotations

import time
from pathlib import Path

import pytest

from tactex_ros.ros.devrun.launcher import Graph
from tactex_ros.ros.graph import SIM_MIN_STATE_RATE_HZ, describe

pytestmark = pytest.mark.ros

RTF = 0.04        # the forced pace: 100 Hz simulated = 4 Hz wall, below SIM_MIN_STATE_RATE_HZ


def _graph(sim_clock: bool):
    return [n for n in describe(True, mock_arm={"max_real_time_factor": RTF},
                                sim_clock=sim_clock)
            if n.name in ("mock_arm", "motion")]


def test_a_slow_simulation_passes_the_pre_flight_in_simulated_time(
        tmp_path: Path, listener, active) -> None:
    from diagnostic_msgs.msg import DiagnosticArray
    from geometry_msgs.msg import PoseStamped
    from rclpy.qos import qos_profile_sensor_data
    from rosgraph_msgs.msg import Clock

    from tactex_ros.ros.settings import POSE_TOPIC
    from tactex_ros.ros.simclock import clock_qos
    assert RTF * 100.0 < SIM_MIN_STATE_RATE_HZ
    nodes = _graph(True)
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

    def status(name: str):
        return [s for m in list(diags) for s in m.status if s.name == name]

    with Graph(nodes, tmp_path / "logs", listener.domain_id):
        assert active("motion", 150.0), (tmp_path / "logs" / "motion.log").read_text()[-2000:]
        time.sleep(15.0)      # 0.6 s of simulated time: the state's rate window fills
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


def test_the_same_slow_arm_on_wall_time_is_refused(tmp_path: Path, domain_id: int) -> None:
    """Without the simulated clock the pre-flight measures 4 Hz of wall time: exit 1."""
    with Graph(_graph(False), tmp_path / "logs", domain_id) as g:
        proc = g.procs["motion"]
        end = time.monotonic() + 150.0
        while proc.poll() is None and time.monotonic() < end:
            time.sleep(0.2)
        code = proc.poll()
    assert code == 1, (code, (tmp_path / "logs" / "motion.log").read_text()[-2000:])
