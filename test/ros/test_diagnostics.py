"""/diagnostics from every node of the simulated graph, the camera going stale (SIGSTOP) seen
as ERROR within 2 s; late joiners receive the latched exploration state at once."""

from __future__ import annotations

import json
import os
import signal
import time
from pathlib import Path

import pytest

from tactex_ros.ros.graph import describe
from tactex_ros.ros.launcher import Graph

pytestmark = [pytest.mark.ros, pytest.mark.slow]


def _wait(cond, timeout: float, step: float = 0.02) -> bool:
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        if cond():
            return True
        time.sleep(step)
    return False


def test_stopped_camera_turns_error_within_2_s_and_late_joiners_get_the_state(
        tmp_path: Path, listener) -> None:
    from diagnostic_msgs.msg import DiagnosticArray
    from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
    from tactex.msg import ExplorationState
    nodes = describe(True, explorer={"trial": {"rounds": 20, "stop_confidence": 0.0},
                                     "seed": 0, "record_dir": str(tmp_path),
                                     "trial_id": "t"})
    got: list[tuple[float, object]] = []
    listener.node.create_subscription(DiagnosticArray, "/diagnostics",
                                      lambda m: got.append((time.monotonic(), m)), 50)

    def latest(name: str):
        for _, m in reversed(got):
            for s in m.status:
                if s.name == name:
                    return s
        return None

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
        assert latest("motion: arm").level != b"\x02"
        assert latest("explorer: trial").level == b"\x00"
        # and the camera recovers: OK again once it runs
        assert _wait(lambda: latest("motion: camera link").level == b"\x00", 10)
        # a stopped arm (no robot state) is an ERROR of "motion: arm" within 2 s as well
        assert _wait(lambda: latest("motion: arm").level != b"\x02", 10)
        arm = g.procs["mock_arm"].pid
        os.kill(arm, signal.SIGSTOP)
        t1 = time.monotonic()
        try:
            ok = _wait(lambda: any(t > t1 and s.name == "motion: arm" and s.level == b"\x02"
                                   for t, m in got for s in m.status), 5.0)
            t_arm = next((t for t, m in got for s in m.status
                          if t > t1 and s.name == "motion: arm" and s.level == b"\x02"), None)
        finally:
            os.kill(arm, signal.SIGCONT)
        assert ok and t_arm - t1 < 2.0, t_arm and t_arm - t1
    art = Path(__file__).parents[2] / "test-artifacts"
    art.mkdir(exist_ok=True)
    (art / "diagnostics_stale.json").write_text(json.dumps(
        {"camera_sigstop_to_error_s": round(t_err - t0, 3),
         "arm_sigstop_to_error_s": round(t_arm - t1, 3)}) + "\n")


def test_a_session_interrupted_and_resumed_raises_no_error(tmp_path: Path, listener) -> None:
    """A simulated 3-trial session, its explorer killed (SIGKILL) in trial 2 and the session
    continued with the same session folder: no ERROR on /diagnostics from graph start to the
    kill and from the second start to the session's end (start-up, placement changes and the
    operator's confirmations are named states), every press attempt on record, the reports
    written."""
    import threading

    from diagnostic_msgs.msg import DiagnosticArray

    from tactex_ros.ros.session_runner import run_session
    from tactex_ros.trial import session as sess
    from tactex_ros.trial.record import read_record
    short = Path(__file__).parents[1] / "data" / "session_three.yaml"
    got: list[tuple[float, object]] = []
    listener.node.create_subscription(DiagnosticArray, "/diagnostics",
                                      lambda m: got.append((time.monotonic(), m)), 100)
    d = tmp_path / "sess"
    cut: dict[str, float] = {}

    def nodes():
        # this machine runs at load 10-25: the mock camera's 25 Hz timer then falls to 11-13 Hz
        # and an image gap reached 0.55 s (measured), past the defaults' ERROR (half the
        # rate, 0.5 s); the test asks for ERROR below 5 Hz and past 1.5 s
        return describe(True, explorer={"trial": {"rounds": 1, "stop_confidence": 0.0},
                                        "seed": 3, "record_dir": str(tmp_path),
                                        "session_file": str(short),
                                        # a placement took over 30 s to prepare at load 24
                                        "server_timeout_s": 120.0},
                        mock_image={"diag_rate_error": 0.2},
                        motion={"diag_camera_error_s": 1.5})

    def kill_in_trial_2(graph) -> None:
        def watch() -> None:
            f = d / "trial_2" / "touches.jsonl"
            end = time.monotonic() + 900
            while time.monotonic() < end:
                if f.is_file() and len(f.read_text().splitlines()) >= 2:
                    cut["kill"] = time.monotonic()
                    os.kill(graph.procs["explorer"].pid, signal.SIGKILL)
                    return
                time.sleep(0.05)
        threading.Thread(target=watch, daemon=True).start()

    def done_watch(graph) -> None:
        def watch() -> None:
            end = time.monotonic() + 900
            while time.monotonic() < end:
                if any(e.get("event") == "session_done" for e in sess.events(d)):
                    cut["done"] = time.monotonic()
                    return
                time.sleep(0.05)
        cut["restart"] = time.monotonic()
        threading.Thread(target=watch, daemon=True).start()

    first = run_session(nodes(), tmp_path / "logs1", d, confirm="yes", timeout_s=900,
                        domain_id=listener.domain_id, on_start=kill_in_trial_2,
                        out=lambda *_: None)
    assert first.result is None and "kill" in cut, first.failure
    second = run_session(nodes(), tmp_path / "logs2", d, confirm="yes", timeout_s=900,
                         domain_id=listener.domain_id, on_start=done_watch,
                         out=lambda *_: None)
    assert second.result is not None, (second.failure, tmp_path / "logs2")
    assert second.result["done"] == 3 and "done" in cut

    def errors(t0: float, t1: float) -> list[str]:
        return sorted({f"{s.name}: {s.message}" for t, m in got if t0 <= t <= t1
                       for s in m.status if s.level == b"\x02"})
    seen = {s.name for _, m in got for s in m.status}
    assert {"mock_image: camera", "mock_arm: arm", "motion: arm", "motion: camera link",
            "explorer: trial"} <= seen, seen
    assert errors(0.0, cut["kill"]) == []
    assert errors(cut["restart"], cut["done"]) == []
    states = {kv.value for _, m in got for s in m.status for kv in s.values
              if kv.key == "state"}
    assert any(v.startswith("placement change") for v in states), states
    # every press attempt on record: each touch line says how many attempts it took
    for t in ("1", "2", "3"):
        rec = read_record(d / sess.record_name(t), images=False)
        assert all(int(x.get("attempts") or 0) >= 1 for x in rec["touches"]
                   if x.get("accepted"))
        assert (d / sess.record_name(t) / "report.html").is_file()
    assert (d / "report.html").is_file()
    ev = sess.events(d)
    assert {e["by"] for e in ev if e["event"] == "confirmed"} == {"yes_flag"}
    art = Path(__file__).parents[2] / "test-artifacts"
    art.mkdir(exist_ok=True)
    _screenshots(d, art, tmp_path)
    (art / "session_diagnostics.json").write_text(json.dumps(
        {"statuses": len(got), "names": sorted(seen), "states": sorted(states),
         "errors_outside_the_kill": errors(0.0, cut["kill"]) +
         errors(cut["restart"], cut["done"])}, indent=1) + "\n")


def _screenshots(d: Path, art: Path, tmp: Path) -> None:
    """The resumed trial's report and the session report in headless Chromium: the context
    table, the marked outcome, both belief charts; screenshots kept in test-artifacts/."""
    import shutil
    wd = pytest.importorskip("selenium.webdriver")
    chrome, driver = shutil.which("chromium"), shutil.which("chromedriver")
    if not chrome or not driver:
        return
    from selenium.webdriver.chrome.service import Service
    opts = wd.ChromeOptions()
    opts.binary_location = chrome
    for a in ("--headless", "--no-sandbox", "--disable-gpu", "--no-first-run",
              "--disable-background-networking", "--window-size=1200,3000",
              f"--user-data-dir={tmp / 'chrome-profile'}"):
        opts.add_argument(a)
    drv = wd.Chrome(service=Service(driver), options=opts)
    try:
        drv.get((d / "trial_2" / "report.html").as_uri())
        assert drv.find_element("id", "context").is_displayed()
        assert drv.find_element("id", "verdict").text in ("correct", "wrong")
        assert drv.find_elements("css selector", ".platform.chosen, .platform.wrong")
        for chart in ("belief-chart", "belief-time-chart"):
            assert len(drv.find_elements("css selector", f"#{chart} polyline.series")) == 4
        assert "resumed after touch" in drv.find_element("id", "timeline").text
        drv.save_screenshot(str(art / "session_trial_2_report.png"))
        drv.get((d / "report.html").as_uri())
        assert len(drv.find_elements("css selector", "table.trials tr")) == 1 + 3
        drv.save_screenshot(str(art / "session_report.png"))
    finally:
        drv.quit()
