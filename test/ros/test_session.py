"""Study sessions on the simulated graph as real processes: scripted confirmations through the
explorer's confirm service, one record + report per trial, the session report (checked in a
headless Chromium), a resume after the explorer is killed mid-session."""

from __future__ import annotations

import json
import os
import shutil
import signal
import threading
import time
from pathlib import Path

import pytest

from tactex_ros.trial import session as sess
from tactex_ros.trial.record import read_record
from tactex_ros.ros.graph import describe
from tactex_ros.ros.devrun.session_runner import run_session
from tactex_ros.robot.scene import load_scene

pytestmark = [pytest.mark.ros, pytest.mark.slow]

SHORT = Path(__file__).parents[1] / "data" / "session_short_small.yaml"   # 1 + 2 platforms
ARTIFACTS = Path(__file__).parents[2] / "test-artifacts"


def _nodes(tmp: Path, scene: str):
    """The simulated graph running SHORT's trials (one round each) in ``scene`` (the small
    scene: conftest.small_scene)."""
    return describe(True, scene, explorer={"trial": {"rounds": 1, "stop_confidence": 0.0},
                                           "seed": 3, "record_dir": str(tmp),
                                           "session_file": str(SHORT)})


@pytest.fixture(scope="module")
def session_run(tmp_path_factory, small_scene):
    """One scripted 2-trial session (module-wide: the browser test reads its records)."""
    tmp = tmp_path_factory.mktemp("session")
    lines: list[tuple[str, str]] = []
    domain = 160 + os.getpid() % 40
    run = run_session(_nodes(tmp, small_scene), tmp / "logs", tmp / "sess", confirm="yes",
                      timeout_s=900, domain_id=domain,
                      out=lambda text, kind: lines.append((kind, text)))
    return run, lines, tmp


def test_scripted_session_runs_every_trial_with_its_truth(session_run, small_scene: str) -> None:
    run, lines, tmp = session_run
    assert run.result is not None, (run.failure, tmp / "logs" / "explorer.log")
    assert run.exit_code == 0 and run.confirmations == 2
    d = run.session_dir
    trials = sess.load_session(SHORT, [p.id for p in load_scene(small_scene).platforms], seed=3).trials
    assert run.result["done"] == 2 and run.result["total"] == 2
    correct = []
    for t in trials:
        rec = d / t.record_name
        res = json.loads((rec / "result.json").read_text())
        # correctness from the trial file's truth; each trial its own seed
        assert res["truth_platforms"] == t.truth
        assert res["correct"] == (res["prediction"] in t.truth)
        assert res["seed"] == t.seed == json.loads((rec / "config.json").read_text())[
            "explorer"]["seed"]
        correct.append(res["correct"])
        # the record's scene holds what the operator placed (the mock camera's placement)
        import yaml
        scene = yaml.safe_load((rec / "scene.yaml").read_text())
        assert {p["id"]: p["sim_fabric"] for p in scene["platforms"]} == t.placement
        assert (rec / "report.html").stat().st_size > 10_000
    assert run.result["accuracy"] == sum(correct) / 2
    assert (d / "report.html").is_file()
    # the fabric library (in the session folder, not record_dir: issue 49): trial 1 saw it
    # empty, trial 2 saw trial 1's presses
    from tactex_ros.core import library as flib
    lib = flib.load(d / flib.LIBRARY_FILE)
    assert not (tmp / flib.LIBRARY_FILE).exists()
    seen = [json.loads((d / t.record_name / "result.json").read_text())["fabric_library"]
            for t in trials]
    accepted = [sum(x["accepted"] for x in read_record(d / t.record_name,
                                                       images=False)["touches"])
                for t in trials]
    assert [s["used"] for s in seen] == [True, True]
    assert (seen[0]["presses"], seen[1]["presses"], lib.presses) == (
        0, accepted[0], sum(accepted))
    ev = sess.events(d)
    assert [e["trial"] for e in ev if e["event"] == "confirmed"] == ["1", "2"]
    assert all(e["by"] == "yes_flag" and e["caller"].startswith("tactex graph run")
               for e in ev if e["event"] == "confirmed")
    # progress: one line per press and per decision of every trial
    n_touch = sum(len(read_record(d / t.record_name, images=False)["touches"]) for t in trials)
    n_dec = sum(len(read_record(d / t.record_name, images=False)["decisions"]) for t in trials)
    assert sum(k == "press" for k, _ in lines) == n_touch
    assert sum(k == "decision" for k, _ in lines) == n_dec


def _driver(profile_dir: Path):
    wd = pytest.importorskip("selenium.webdriver")
    chrome, driver = shutil.which("chromium"), shutil.which("chromedriver")
    if not chrome or not driver:
        pytest.skip("headless chromium + chromedriver not installed (scripts/setup_env.sh "
                    "installs them with apt when run as root: apt install chromium "
                    "chromium-driver)")
    from selenium.webdriver.chrome.service import Service
    opts = wd.ChromeOptions()
    opts.binary_location = chrome
    for a in ("--headless", "--no-sandbox", "--disable-gpu", "--disable-quic",
              "--no-first-run", "--disable-background-networking",
              "--disable-component-update", "--disable-sync", "--window-size=1200,1600",
              f"--user-data-dir={profile_dir}"):
        opts.add_argument(a)
    return wd.Chrome(service=Service(driver), options=opts)


def test_trial_report_in_a_real_browser(session_run, tmp_path: Path) -> None:
    run, _, _ = session_run
    assert run.result is not None, run.failure
    rec = run.session_dir / "trial_1"
    res = json.loads((rec / "result.json").read_text())
    touches = read_record(rec, images=False)["touches"]
    with_image = [t for t in touches if t.get("image")]
    drv = _driver(tmp_path / "chrome-profile")
    try:
        drv.get((rec / "report.html").as_uri())
        find = drv.find_element
        assert find("id", "prediction").text == res["prediction"]
        assert int(find("id", "touches").text) == res["touches"]
        assert find("id", "stop-reason").text == res["stop_reason"]
        imgs = drv.find_elements("css selector", "img.touch")
        assert len(imgs) == len(with_image)
        widths = [drv.execute_script("return arguments[0].naturalWidth", i) for i in imgs]
        assert all(w == 320 for w in widths), widths
        lines = drv.find_elements("css selector", "#belief-chart polyline.series")
        assert len(lines) == 2                               # one per comparison platform
        box = drv.execute_script("const b = document.querySelector('#belief-chart')"
                                 ".getBBox(); return [b.width, b.height];")
        assert box[0] > 100 and box[1] > 50
        shot = tmp_path / "trial_report.png"
        drv.set_window_size(1200, 2400)
        assert drv.save_screenshot(str(shot)) and shot.stat().st_size > 10_000
        ARTIFACTS.mkdir(exist_ok=True)
        shutil.copy(shot, ARTIFACTS / "trial_report.png")
        drv.get((run.session_dir / "report.html").as_uri())
        assert f"{run.result['accuracy']:.3f}" in find("id", "accuracy").text
        rows = drv.find_elements("css selector", "table.trials tr")
        assert len(rows) == 1 + 2
        drv.save_screenshot(str(ARTIFACTS / "session_report.png"))
    finally:
        drv.quit()


def test_killed_explorer_resumes_with_no_touch_lost_or_repeated(tmp_path: Path, domain_id,
                                                                 small_scene: str) -> None:
    d = tmp_path / "sess"
    killed: dict = {}

    def kill_after_touches(graph) -> None:
        def watch() -> None:
            f = d / "trial_1" / "touches.jsonl"
            end = time.monotonic() + 600
            while time.monotonic() < end:
                if f.is_file() and len(f.read_text().splitlines()) >= 3:
                    killed["touches"] = len(f.read_text().splitlines())
                    os.kill(graph.procs["explorer"].pid, signal.SIGKILL)
                    return
                time.sleep(0.05)
        threading.Thread(target=watch, daemon=True).start()

    first = run_session(_nodes(tmp_path, small_scene), tmp_path / "logs1", d, confirm="yes",
                        timeout_s=900, domain_id=domain_id, on_start=kill_after_touches,
                        out=lambda *_: None)
    assert first.result is None and first.node_exit["explorer"] == -signal.SIGKILL
    before = [json.loads(x) for x in (d / "trial_1" / "touches.jsonl").read_text()
              .splitlines() if x.strip()]
    assert len(before) >= killed["touches"]
    second = run_session(_nodes(tmp_path, small_scene), tmp_path / "logs2", d, confirm="yes",
                         timeout_s=900, domain_id=domain_id, out=lambda *_: None)
    assert second.result is not None, (second.failure, tmp_path / "logs2" / "explorer.log")
    assert second.result["done"] == 2
    rec = read_record(d / "trial_1", images=False)
    seqs = [t["seq"] for t in rec["touches"]]
    assert seqs == list(range(1, len(seqs) + 1))            # nothing overwritten or repeated
    assert [t["seq"] for t in rec["touches"][:len(before)]] == [t["seq"] for t in before]
    resumed = [e for e in rec["events"] if e["event"] == "resumed"]
    kept = [t for t in before if not t.get("interrupted")]
    assert len(resumed) == 1 and resumed[0]["touches_replayed"] == len(kept)
    res = rec["result"]
    # every accepted touch on disk went into the result: none lost, none pressed twice
    assert res["touches"] == sum(bool(t.get("accepted")) for t in rec["touches"])
    assert [e["event"] for e in sess.events(d)].count("resumed") == 1
    asked = [e["trial"] for e in sess.events(d) if e["event"] == "awaiting_confirmation"]
    assert asked.count("1") == 1            # its confirmed placement was not asked again


def test_unconfirmed_placement_ends_the_session_cleanly(tmp_path: Path, domain_id,
                                                         small_scene: str) -> None:
    nodes = _nodes(tmp_path, small_scene)
    # 20 s: every other node has started before the session ends
    next(n for n in nodes if n.name == "explorer").parameters["confirm_timeout_s"] = 20.0
    d = tmp_path / "sess"
    run = run_session(nodes, tmp_path / "logs", d, confirm="none", timeout_s=300,
                      domain_id=domain_id, out=lambda *_: None)
    assert run.result is None and run.exit_code == 1 and run.signal is None
    assert run.failure == [e for e in sess.events(d) if e["event"] == "session_ended"][0][
        "reason"]
    ev = sess.events(d)
    ended = [e for e in ev if e["event"] == "session_ended"]
    assert len(ended) == 1 and ended[0]["trial"] == "1"
    assert not any(e["event"] == "confirmed" for e in ev)
    assert not (d / "trial_1").exists()                  # nothing moved, nothing recorded
    assert all(code == 0 for name, code in run.node_exit.items() if name != "explorer")

