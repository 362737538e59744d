"""Robot state that stops for a while mid-press (a stalled state broadcaster, a loaded machine):
the motion node holds the target where it is until fresh state arrives, so the arm is never
commanded deeper on a force it has not seen; the press then goes on and ends as usual. The
graph keeps wall time here (``sim_clock=False``), as the robot graph does: on the simulated
clock a stopped mock arm stops time as well, and no state is ever stale."""

from __future__ import annotations

import os
import signal
import threading
import time
from pathlib import Path

import pytest

from tactex_ros.robot.scene import load_scene
from tactex_ros.ros.graph import describe
from tactex_ros.ros.devrun.launcher import Graph

pytestmark = pytest.mark.ros

FREEZE_S = 2.0          # the mock arm stopped (no state) this long, in the descent
TIMEOUT_S = 5.0         # the motion node's state_timeout_s here: the press must not abort
SLACK_S = 0.5           # state_hold_s (0.1 s) and delivery, before the target must stand


def _wait(cond, timeout: float) -> bool:
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        if cond():
            return True
        time.sleep(0.01)
    return False


def test_stale_state_holds_the_target_and_the_press_goes_on(tmp_path: Path, listener, press,
                                                            force_trace) -> None:
    nodes = [n for n in describe(True, motion={"state_timeout_s": TIMEOUT_S}, sim_clock=False)
             if n.name in ("mock_arm", "mock_image", "motion")]
    scene = load_scene(nodes[0].parameters["scene_file"])
    platform = scene.platform("c2")
    # 2 mm into the descent (config/scene_sim.yaml: 20 mm above the surface at 10 mm/s)
    descending = platform.position[2] + scene.press.approach_height - 0.002
    from diagnostic_msgs.msg import DiagnosticArray
    diags = listener.collect(DiagnosticArray, "/diagnostics", 50)

    def held_ticks() -> int:
        return max((int(v.value) for m in list(diags) for st in m.status
                    if st.name == "motion: arm" for v in st.values
                    if v.key == "ticks held on stale state"), default=0)

    got: dict = {}
    with Graph(nodes, tmp_path / "logs", listener.domain_id) as g:
        th = threading.Thread(target=lambda: got.update(res=press("c2", timeout=150.0)))
        th.start()
        assert _wait(lambda: any(k == "target" and v < descending
                                 for _, k, v in list(force_trace.rows)), 150.0)
        pid = g.procs["mock_arm"].pid
        os.kill(pid, signal.SIGSTOP)
        t_stop = time.monotonic()
        time.sleep(FREEZE_S)
        os.kill(pid, signal.SIGCONT)
        t_cont = time.monotonic()
        th.join(timeout=180.0)
        # the operator sees the holds on the arm's /diagnostics (one status a second)
        assert _wait(lambda: held_ticks() > 0, 30.0)
    res = got.get("res")
    assert res is not None and res.success, res and res.reason
    held = [v for t, k, v in list(force_trace.rows)
            if k == "target" and t_stop + SLACK_S <= t <= t_cont]
    # without the hold the target descends 15 mm in this window (10 mm/s x 1.5 s)
    assert held and max(held) == min(held), (min(held, default=None), max(held, default=None))
    assert min(held) > platform.position[2]          # held above the surface: not pressing
    force_trace.check(scene.press.max_force, label="the press")
