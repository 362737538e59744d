"""/diagnostics from every node of the simulated graph, the camera going stale (SIGSTOP) seen
as ERROR within 2 s, the mock arm (the simulated clock source) stopped seen as WARN "simulation
behind", never a robot ERROR; late joiners receive the latched exploration state at once."""

from __future__ import annotations

import json
import os
import signal
import time
from pathlib import Path

import pytest

from tactex_ros.ros.graph import describe
from tactex_ros.ros.devrun.launcher import Graph

pytestmark = [pytest.mark.ros, pytest.mark.slow]


def _wait(cond, timeout: float, step: float = 0.02) -> bool:
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        if cond():
            return True
        time.sleep(step)
    return False


def test_stopped_camera_turns_error_within_2_s_and_late_joiners_get_the_state(
        tmp_path: Path, listener, quick_scene: str) -> None:
    from diagnostic_msgs.msg import DiagnosticArray
    from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
    from tactex.msg import ExplorationState
    nodes = describe(True, quick_scene,
                     explorer={"trial": {"rounds": 20, "stop_confidence": 0.0}, "seed": 0,
                               "record_dir": str(tmp_path), "trial_id": "t"})
    got: list[tuple[float, object]] = []
    listener.node.create_subscription(DiagnosticArray, "/diagnostics",
                                      lambda m: got.append((time.monotonic(), m)), 50)

    def latest(name: str):
        for _, m in reversed(got):
            for s in m.status:
                if s.name == name:
                    return s
        return None

    from geometry_msgs.msg import PoseStamped
    from rclpy.qos import qos_profile_sensor_data

    from tactex_ros.ros.settings import POSE_TOPIC
    poses: list[float] = []        # arrival of every mock arm pose at the listener [s]
    listener.node.create_subscription(PoseStamped, POSE_TOPIC,
                                      lambda _m: poses.append(time.monotonic()),
                                      qos_profile_sensor_data)

    def arm_up(since: float) -> str:
        """"" when the motion node's arm status is not ERROR now, else what the listener saw
        since ``since``: the arm status's history and the gaps in the mock arm's poses."""
        if latest("motion: arm").level != b"\x02":
            return ""
        hist = [f"{t - since:7.3f} s level {s.level[0]} {s.message}" for t, m in got
                if t >= since - 1.0 for s in m.status if s.name == "motion: arm"]
        arr = [t for t in poses if t >= since - 1.0] + [time.monotonic()]   # now: the tail
        gaps = [f"{a - since:7.3f} s +{b - a:.3f} s" for a, b in zip(arr, arr[1:], strict=False)
                if b - a > 0.1]
        return ("motion: arm ERROR; its statuses:\n" + "\n".join(hist) +
                "\nposes received: " + str(len(arr) - 1) + ", gaps over 0.1 s (the last "
                "one ends now):\n" + "\n".join(gaps))

    with Graph(nodes, tmp_path / "logs", listener.domain_id) as g:
        # every node reports, named "<node>: <task>", with a hardware id
        names = ("mock_image: camera", "motion: arm", "motion: camera link", "explorer: trial")
        assert _wait(lambda: all(latest(n) is not None for n in names), 90), \
            sorted({s.name for _, m in got for s in m.status})
        assert all(latest(n).hardware_id for n in names)
        # the first decision is on disk: a subscriber that joins now still gets the state
        dec = tmp_path / "t" / "decisions.jsonl"
        assert _wait(lambda: dec.is_file() and dec.read_text().strip(), 240)
        late: list = []
        qos = QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE,
                         durability=DurabilityPolicy.TRANSIENT_LOCAL)
        listener.node.create_subscription(ExplorationState, "/tactex/state", late.append, qos)
        assert _wait(lambda: late, 3.0), "no latched exploration state for a late joiner"
        assert late[0].round >= 1
        # the camera runs: its link is OK in the motion node
        assert _wait(lambda: latest("motion: camera link").level == b"\x00", 10)
        assert latest("motion: arm").level != b"\x02"     # WARN allowed: a loaded machine
        pid = g.procs["mock_image"].pid
        n_touch = len((tmp_path / "t" / "touches.jsonl").read_text().splitlines())
        os.kill(pid, signal.SIGSTOP)
        t0 = time.monotonic()
        try:
            ok = _wait(lambda: any(t > t0 and s.name == "motion: camera link"
                                   and s.level == b"\x02" for t, m in got for s in m.status),
                       5.0)
            t_err = next(t for t, m in got for s in m.status
                         if t > t0 and s.name == "motion: camera link" and s.level == b"\x02") \
                if ok else None
        finally:
            os.kill(pid, signal.SIGCONT)
        assert ok, "no ERROR from the camera link within 5 s of SIGSTOP"
        assert t_err - t0 < 2.0, f"ERROR after {t_err - t0:.2f} s"
        # reported before the press that would need the camera finished
        now = len((tmp_path / "t" / "touches.jsonl").read_text().splitlines())
        assert now <= n_touch + 1
        # the arm and the explorer stayed up meanwhile
        assert not arm_up(t0), arm_up(t0)
        assert latest("explorer: trial").level == b"\x00"
        # and the camera recovers: OK again once it runs
        assert _wait(lambda: latest("motion: camera link").level == b"\x00", 10)
        # a stopped mock arm is the simulated graph's clock source standing still: the
        # simulation is behind (WARN within 3 s, the clock's wall-time standstill named in
        # the values), never a robot ERROR (the state's age is in simulated time)
        assert _wait(lambda: latest("motion: arm").level != b"\x02", 10)
        arm = g.procs["mock_arm"].pid
        os.kill(arm, signal.SIGSTOP)
        t1 = time.monotonic()

        def still(st) -> float:
            return next((float(v.value) for v in st.values
                         if v.key == "simulated clock still [s wall]"), 0.0)
        try:
            ok = _wait(lambda: any(t > t1 and s.name == "motion: arm" and s.level == b"\x01"
                                   and still(s) > 1.0 for t, m in got for s in m.status), 5.0)
            t_arm = next((t for t, m in got for s in m.status if t > t1 and
                          s.name == "motion: arm" and s.level == b"\x01" and still(s) > 1.0),
                         None)
            time.sleep(max(0.0, t1 + 4.0 - time.monotonic()))  # > state_timeout_s (1 s)
        finally:
            os.kill(arm, signal.SIGCONT)
        errors = [(round(t - t1, 2), s.message) for t, m in got for s in m.status
                  if t > t1 and s.name == "motion: arm" and s.level == b"\x02"]
        assert ok and t_arm - t1 < 3.0, t_arm and t_arm - t1
        assert not errors, errors
        # the clock runs again: the warning clears, and the trial goes on
        assert _wait(lambda: latest("motion: arm").level == b"\x00" or
                     still(latest("motion: arm")) < 1.0, 10)
    art = Path(__file__).parents[2] / "test-artifacts"
    art.mkdir(exist_ok=True)
    (art / "diagnostics_stale.json").write_text(json.dumps(
        {"camera_sigstop_to_error_s": round(t_err - t0, 3),
         "arm_sigstop_to_sim_behind_warn_s": round(t_arm - t1, 3)}) + "\n")
