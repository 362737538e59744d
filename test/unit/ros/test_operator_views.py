"""What the operator looks at, without a running graph: viewer configs, the health grading,
the progress lines and the HTML reports built from a record on disk."""

from __future__ import annotations

import json
import re
from pathlib import Path

import numpy as np
import pytest
import yaml

from tactex_ros.core.paths import config_dir
from tactex_ros.trial.progress import Progress, decision_line, press_line
from tactex_ros.trial.record import TrialRecord, read_record
from tactex_ros.trial.report import regenerate, trial_html
from tactex_ros.ros import diagnostics as dg
from tactex_ros.ros.settings import (MARKER_TOPIC, POSE_TOPIC, PROMPT_TOPIC, STATE_TOPIC,
                                     TOUCH_IMAGE_TOPIC, WRENCH_TOPIC, CameraHealthSettings)


def test_rviz_subscribes_transient_local_where_the_explorer_latches() -> None:
    cfg = yaml.safe_load((config_dir() / "tactex.rviz").read_text())
    durab = {d["Topic"]["Value"]: d["Topic"]["Durability Policy"]
             for d in cfg["Visualization Manager"]["Displays"] if "Topic" in d}
    assert durab[MARKER_TOPIC] == durab[TOUCH_IMAGE_TOPIC] == "Transient Local"


def test_grade_rate_meter_and_camera_health() -> None:
    assert dg.grade(0.1, 0.3, 1.0) == dg.OK and dg.grade(0.5, 0.3, 1.0) == dg.WARN
    assert dg.grade(1.0, 0.3, 1.0) == dg.ERROR and dg.grade(None, 0.3, 1.0) == dg.ERROR
    assert dg.grade(20, 16, 10, higher_is_worse=False) == dg.OK
    assert dg.grade(12, 16, 10, higher_is_worse=False) == dg.WARN
    m = dg.RateMeter(2.0)
    for k in range(50):
        m.tick(100.0 + k * 0.04)             # 25 Hz for 2 s
    assert m.rate(101.96) == pytest.approx(25.0, abs=0.6) and m.age(102.0) == pytest.approx(0.04)
    th = CameraHealthSettings()
    cam = dg.CameraHealth(25.0, th)
    frame = np.full((240, 320, 3), 100, np.uint8)
    for k in range(50):
        cam.observe(frame, 10.0 + k * 0.04)
    level, msg, values = cam.check(11.97)
    assert level == dg.OK and values["no-contact drift [grey levels]"] == 0.0
    assert cam.check(13.0)[0] == dg.ERROR                 # the newest frame is 1 s old
    for k in range(50):                                   # lighting drifted by 20 grey levels
        cam.observe(frame + 20, 20.0 + k * 0.04)
    level, msg, _ = cam.check(21.97)
    assert level == dg.ERROR and "drift" in msg
    link = dg.link_check(m, "camera image", 0.3, 1.0, now=103.5)
    assert link[0] == dg.ERROR


def _record(tmp: Path) -> Path:
    rec = TrialRecord(tmp, "t1")
    scene = config_dir() / "scene_sim.yaml"
    rec.save_inputs(scene, {"explorer": {"seed": 4}, "trial": {"strategy": "infogain",
                                                               "stop_confidence": 0.9}})
    rng = np.random.default_rng(0)
    ids = ["reference", "c1", "c2", "c3", "c4"]
    for k, pid in enumerate(ids + ["c1"]):
        img = rng.integers(0, 255, (240, 320, 3), dtype=np.uint8)
        rec.add_touch(img, {"platform_id": pid, "platform_index": ids.index(pid),
                            "accepted": True, "force_n": 4.0 + k * 0.1, "depth_m": 4e-4,
                            "requested": 10.0 * k, "stamp": 10.0 * k + 3.0})
    rec.add_touch(None, {"platform_id": "c2", "platform_index": 2, "accepted": False,
                         "reason": "press failed", "requested": 70.0})
    rec.add_decision({"round": 1, "next": "c1", "belief": [0.4, 0.2, 0.2, 0.2],
                      "uncertainty": [0.9, 0.1, 0.2, 0.3], "touches": [1, 1, 1, 1],
                      "decision_s": 0.5, "done": False})
    rec.add_decision({"round": 2, "next": "", "belief": [0.7, 0.1, 0.1, 0.1],
                      "uncertainty": [0.1, 0.1, 0.2, 0.3], "touches": [2, 1, 1, 1],
                      "decision_s": 0.4, "done": True, "prediction": "c1"})
    rec.finish({"prediction": "c1", "touches": 6, "stop_reason": "rounds",
                "strategy": "infogain", "elapsed_s": 80.0})
    return rec.dir


def test_trial_report_is_self_contained_and_says_what_happened(tmp_path: Path) -> None:
    d = _record(tmp_path)
    html = trial_html(d)
    assert "http://" not in html.replace("http://www.w3.org/2000/svg", "")
    assert "https://" not in html and "<script" not in html
    assert html.count("src='data:image/png;base64,") == 6            # every touch image
    # one line per comparison in each belief chart (touches; seconds, from the captures)
    assert len(re.findall(r"<polyline class='series'", html)) == 2 * 4
    # stopped by rounds with belief 0.7 < stop_confidence 0.9: "not sure"
    assert re.search(r"id='prediction'>c1<", html) and "id='not-sure'" in html
    assert re.search(r"id='touches'>6<", html)
    assert "no: press failed" in html and "3.00" in html             # press time [s]
    assert "infogain score 0.9 (highest)" in html                    # the chosen one's reason
    out = regenerate(d)
    assert out == [d / "report.html"] and (d / "report.html").read_text() == html


def test_not_sure_reads_the_engines_outcome_when_the_result_has_it() -> None:
    from tactex_ros.trial.report import not_sure
    # the engine's own verdict wins over what the stop reason and belief would suggest
    assert not_sure({"stop_reason": "rounds", "sure": True}, 0.9, 0.5) is False
    assert not_sure({"stop_reason": "confident", "sure": False}, 0.9, 0.95) is True
    # older results without the field: from the stop reason and the belief
    assert not_sure({"stop_reason": "rounds"}, 0.9, 0.7) is True
    assert not_sure({"stop_reason": "rounds", "sure": None}, 0.0, 0.7) is False


def test_progress_prints_each_press_and_decision_once(tmp_path: Path) -> None:
    d = _record(tmp_path)
    lines: list[tuple[str, str]] = []
    p = Progress(lambda text, kind: lines.append((kind, text)))
    p.follow(d)
    p.poll()
    p.poll()
    assert [k for k, _ in lines].count("press") == 7
    assert [k for k, _ in lines].count("decision") == 2
    assert press_line({"seq": 2, "platform_id": "c1", "force_n": 4.04, "requested": 1.0,
                       "stamp": 3.5, "accepted": True}) == "press 2: c1 4.0 N 2.5 s"
    assert decision_line({"round": 1, "belief": [0.5, 0.5], "next": "c2"}, ["c1", "c2"]) \
        == "decision 1: belief c1 0.50 c2 0.50 -> next c2"
    # a decision without its belief, or ids not read yet, still gives a line
    assert decision_line({"round": 0, "next": "c1"}, ["c1", "c2"]) \
        == "decision 0: belief  -> next c1"
    assert decision_line({"round": 1, "belief": [0.5, 0.5], "next": "c2"}, []) \
        == "decision 1: belief  -> next c2"


# ------------------------------------------------------------------ Foxglove: Foxglove's keys

def test_foxglove_layouts_use_only_keys_foxglove_reads() -> None:
    from tactex_ros.ros.viewer_layout import check_layout, layout_text
    shipped = {"fr3_crisp": config_dir() / "tactex.foxglove.json"}
    for r in ("fr3_crisp", "panda_crisp", "sim"):
        shipped[f"layouts/{r}"] = config_dir() / "layouts" / f"tactex_{r}.foxglove.json"
    for name, path in shipped.items():
        lay = json.loads(path.read_text())
        assert check_layout(lay) == [], (name, check_layout(lay))
        robot = name.rpartition("/")[2]
        # shipped = generated (`tactex layout --robot R` writes it again)
        assert path.read_text() == layout_text(robot), f"{path} is stale: tactex layout"
    lay = json.loads(shipped["fr3_crisp"].read_text())
    cfg = lay["configById"]
    # fr3_crisp: CRISP's pose broadcaster, followed in franka's base frame
    assert cfg["3D!tactex"]["followTf"] == "fr3_link0"
    assert set(cfg["3D!tactex"]["topics"]) == {MARKER_TOPIC, "/current_pose"}
    assert cfg["Plot!wrench"]["paths"][0]["value"].startswith(WRENCH_TOPIC)
    assert cfg["DiagnosticSummary!health"]["topicToRender"] == "/diagnostics"
    assert cfg["CallService!confirm"]["serviceName"] == "/explorer/confirm"
    assert cfg["CallService!confirm"]["datatype"] == "std_srvs/srv/Trigger"
    assert cfg["RawMessages!prompt"]["topicPath"].startswith(PROMPT_TOPIC)
    assert [p["value"] for p in cfg["Plot!belief"]["paths"]] == [
        f"{STATE_TOPIC}.belief[{k}]" for k in range(4)]
    assert cfg["Image!touch"]["imageMode"]["imageTopic"] == TOUCH_IMAGE_TOPIC
    sim = json.loads(shipped["layouts/sim"].read_text())["configById"]
    assert POSE_TOPIC in sim["3D!tactex"]["topics"]
    # a trial's MCAP played in the layout: every plot has a line on a topic the file holds
    from tactex_ros.ros.bag import WRENCH_VIEW
    recorded = {STATE_TOPIC, WRENCH_VIEW}
    for name, panel in cfg.items():
        if name.startswith("Plot!"):
            assert {p["value"].split(".")[0] for p in panel["paths"]} & recorded, name
    assert cfg["Plot!wrench"]["paths"][1]["value"] == f"{WRENCH_VIEW}.wrench.force.z"
    # the state indicator reads the level of the explorer's trial status; the log is /rosout
    from tactex_ros.ros.diagnostics import ERROR, OK, WARN
    ind = cfg["Indicator!state"]
    assert ind["path"] == '/diagnostics.status[:]{name=="explorer: trial"}.level'
    assert [(r["operator"], r["rawValue"]) for r in ind["rules"]] == [
        ("=", str(OK)), ("=", str(WARN)), ("=", str(ERROR))]
    assert cfg["RosOut!log"]["topicToRender"] == "/rosout"
    assert cfg["RosOut!log"]["minLogLevel"] == 2          # INFO and above


def test_foxglove_layout_check_names_a_key_foxglove_ignores() -> None:
    from tactex_ros.ros.viewer_layout import check_layout, foxglove_layout
    lay = foxglove_layout("fr3_crisp")
    cfg = lay["configById"]["3D!tactex"]
    cfg["followTfFrame"] = cfg.pop("followTf")          # the old, unread key
    problems = check_layout(lay)
    assert len(problems) == 1 and "followTfFrame" in problems[0]
    lay = foxglove_layout("fr3_crisp")
    lay["configById"]["3D!tactex"]["followMode"] = "follow"
    lay["configById"]["Plot!belief"]["paths"][0]["colour"] = "red"
    lay["configById"]["Image!orphan"] = {}
    lay["configById"]["Indicator!state"]["rules"][0]["value"] = "0"
    assert len(check_layout(lay)) == 4


def test_aggregator_has_an_analyzer_for_every_node() -> None:
    doc = yaml.safe_load((config_dir() / "diagnostics_aggregator.yaml").read_text())
    params = doc["analyzers"]["ros__parameters"]
    prefixes = [p for a in params.values() if isinstance(a, dict)
                for p in a.get("startswith", [])]
    assert all(a["type"] == "diagnostic_aggregator/GenericAnalyzer"
               for a in params.values() if isinstance(a, dict))
    for status in ("explorer: trial", "motion: arm", "motion: camera link", "gelsight: camera",
                   "mock_image: camera", "mock_arm: arm"):
        assert sum(status.startswith(p) for p in prefixes) == 1, status


# ------------------------------------------------------------------ expected pauses

def test_a_phase_is_its_own_level_until_its_deadline() -> None:
    ph = dg.Phase(settle_s=2.0)
    ph.begin("placement change", 10.0, now=100.0)
    stale = (dg.ERROR, "newest frame 3.00 s old", {})
    level, msg, values = ph.apply(stale, now=103.0)
    assert level == dg.WARN and values["state"] == "placement change"
    assert values["state for [s]"] == pytest.approx(3.0)
    assert ph.apply((dg.OK, "ok", {}), now=103.0)[0] == dg.OK
    assert ph.apply((dg.OK, "ok", {}), now=110.5)[0] == dg.ERROR    # overran its deadline
    ph.end(now=104.0)
    assert ph.apply(stale, now=105.0)[0] == dg.WARN                  # settling
    assert ph.apply(stale, now=106.5)[0] == dg.ERROR                 # a fault again
    # start-up: no message yet is WARN until the deadline, then ERROR; the first ends it
    m = dg.RateMeter(2.0)
    start = dg.startup_phase("camera image", 30.0)
    assert dg.link_check(m, "camera image", 0.2, 0.5, phase=start)[0] == dg.WARN
    start.since -= 31.0
    assert dg.link_check(m, "camera image", 0.2, 0.5, phase=start)[0] == dg.ERROR
    m.tick()
    assert dg.link_check(m, "camera image", 0.2, 0.5, phase=start)[0] == dg.OK
    assert not start.active
    assert dg.robot_mode_name(4) == "reflex (4)" and dg.robot_mode_name(2) == "move (2)"
    assert dg.robot_mode_name(None).startswith("not reported")


# ------------------------------------------------------------------ reports a person trusts

def _wrong_trial(root: Path, name: str = "trial_2") -> Path:
    """A session-like record whose answer c1 is wrong (the truth is c2), with a run section,
    decision times and a failed attempt."""
    rec = TrialRecord(root, name)
    rec.save_inputs(config_dir() / "scene_sim.yaml", {
        "explorer": {"seed": 5, "config": "default",
                     "scene_file": str(config_dir() / "scene_sim.yaml")},
        "trial": {"strategy": "infogain", "stop_confidence": 0.9, "rounds": 8},
        "learner": {"model": "descriptor"},
        "run": {"started": 1_764_000_000.0, "version": "9.9.9", "commit": "abc123def456",
                "host": "lab", "command": "tactex graph run --sim --session s.yaml --yes",
                "non_default": {"explorer.seed": 5}},
        "session": {"name": "s", "trial": "2", "truth": ["c2"],
                    "placement": {"reference": "satin", "c1": "denim", "c2": "satin",
                                  "c3": "felt", "c4": "linen"}}})
    rng = np.random.default_rng(1)
    ids = ["reference", "c1", "c2", "c3", "c4"]
    nc = np.full((240, 320, 3), 90, np.uint8)
    for k, pid in enumerate(ids):
        rec.add_touch(rng.integers(0, 255, (240, 320, 3), dtype=np.uint8),
                      {"platform_id": pid, "platform_index": k, "accepted": True,
                       "force_n": 4.0, "depth_m": 4e-4, "attempts": 2 if k == 0 else 1,
                       "attempt_failures": "attempt 1: capture failed" if k == 0 else None,
                       "requested": 1_764_000_010.0 + 10 * k,
                       "stamp": 1_764_000_012.0 + 10 * k}, no_contact=nc)
    for r, (b, t) in enumerate([([0.4, 0.3, 0.2, 0.1], 1_764_000_055.0),
                                ([0.6, 0.3, 0.05, 0.05], 1_764_000_070.0)], 1):
        rec.add_decision({"round": r, "next": "c1" if r == 1 else "", "belief": b,
                          "uncertainty": [0.5, 0.2, 0.2, 0.1], "touches": [r, 1, 1, 1],
                          "decision_s": 1.5, "done": r == 2, "time": t,
                          "prediction": "c1" if r == 2 else ""})
    rec.finish({"prediction": "c1", "touches": 5, "stop_reason": "rounds", "sure": False,
                "strategy": "infogain", "model": "descriptor", "elapsed_s": 60.0,
                "truth_platforms": ["c2"], "correct": False})
    return rec.dir


def test_trial_report_marks_chosen_true_and_wrong_and_gives_its_context(tmp_path: Path
                                                                        ) -> None:
    from tactex_ros.trial.report import time_split
    d = _wrong_trial(tmp_path)
    html = trial_html(d)
    assert re.search(r"class='platform wrong' data-platform='c1'", html)
    assert re.search(r"class='platform truth' data-platform='c2'", html)
    assert "id='verdict' class='bad'>wrong" in html and "id='truth'>c2 (satin)" in html
    ctx = html[html.index("id='context'"):]
    for text in ("2025-11-24", "9.9.9", "abc123def456", "tactex graph run --sim",
                 "default", "descriptor", "0.9", ">8<", "explorer.seed=5",
                 "simulation", "scene_sim.yaml"):
        assert text in ctx, text
    # both belief charts, the stop line in each, the legends name the fabrics
    for chart in ("belief-chart", "belief-time-chart"):
        svg = html[html.index(f"<svg id='{chart}'"):]
        svg = svg[:svg.index("</svg>")]
        assert svg.count("class='series'") == 4 and "class='stop-line'" in svg
        assert "c1 (denim)" in svg and "c2 (satin)" in svg
    # the no-contact frame once (CSS), the failed attempt counted and shown
    assert html.count("background-image:url(data:image/png;base64,") == 1
    assert re.search(r"id='failed-attempts'>1<", html) and "capture failed" in html
    split = time_split(read_record(d, images=False))
    assert split["pressing"] == pytest.approx(10.0) and split["deciding"] == pytest.approx(3.0)
    assert split["total"] == pytest.approx(60.0) and split["waiting"] == pytest.approx(47.0)


def test_unfinished_trial_report_says_why_and_how_to_continue(tmp_path: Path) -> None:
    from tactex_ros.trial.record import append_event
    from tactex_ros.trial.report import time_split
    rec = TrialRecord(tmp_path, "t9")
    rec.save_inputs(config_dir() / "scene_sim.yaml",
                    {"trial": {"stop_confidence": 0.9, "rounds": 4},
                     "run": {"command": "tactex graph run --sim --scene x.yaml"}})
    for k in range(3):
        rec.add_touch(np.zeros((240, 320, 3), np.uint8),
                      {"platform_id": "c1", "platform_index": 1, "accepted": True,
                       "requested": 100.0 + 10 * k, "stamp": 102.0 + 10 * k})
    append_event(rec.dir, {"event": "trial_ended", "reason": "SIGINT", "time": 125.0})
    append_event(rec.dir, {"event": "resumed", "after_touch": 3, "touches_replayed": 3,
                           "time": 500.0, "how": "re-training"})
    rec.add_touch(np.zeros((240, 320, 3), np.uint8),
                  {"platform_id": "c2", "platform_index": 2, "accepted": True,
                   "requested": 510.0, "stamp": 512.0})
    append_event(rec.dir, {"event": "trial_ended", "reason": "node motion ended",
                           "time": 520.0})
    html = trial_html(rec.dir)
    assert "id='unfinished-reason'>node motion ended<" in html
    assert f"--resume {rec.dir}" in html and "--sim" in html
    tl = html[html.index("id='timeline'"):]
    assert tl.count("interrupted") == 2 and "resumed after touch 3" in tl
    # both runs count: 100..122 and 500..512
    assert time_split(read_record(rec.dir, images=False))["total"] == pytest.approx(34.0)


def test_session_report_has_n_wilson_bands_duration_and_links_both_ways(tmp_path: Path
                                                                        ) -> None:
    from tactex_ros.trial import session as sess
    from tactex_ros.core.stats import wilson
    from tactex_ros.trial.report import session_html
    d = tmp_path / "s"
    trials = []
    for k, truth in ((1, "c2"), (2, "c2"), (3, "c3")):
        trials.append({"id": str(k), "position": k - 1, "seed": k, "truth": [truth],
                       "placement": {"reference": "satin", "c1": "denim", "c2": "satin",
                                     "c3": "felt", "c4": "linen"}})
    d.mkdir()
    (d / "session.json").write_text(json.dumps({"name": "s", "path": "s.yaml",
                                                "session_id": "s-1", "trial_file_sha256":
                                                "0" * 64, "trials": trials,
                                                "settings": {"seed": 0}}))
    sess.add_event(d, {"event": "started", "time": 1_764_000_000.0})
    for k in (1, 2):
        r = _wrong_trial(d, f"trial_{k}")
        res = json.loads((r / "result.json").read_text())
        # trial 1 sure and right, trial 2 not sure (a not-sure answer never counts as
        # correct: issue 47)
        res.update(prediction="c2" if k == 1 else "c1", correct=k == 1, sure=k == 1)
        (r / "result.json").write_text(json.dumps(res))
    sess.add_event(d, {"event": "run_ended", "reason": "SIGINT", "time": 1_764_000_900.0})
    regenerate(d)                          # the trial reports the session links to
    html = session_html(d)
    lo, hi = wilson(1, 2)
    assert f"{lo:.2f}&ndash;{hi:.2f}" in html and re.search(r"id='n'>2<", html)
    assert "id='duration'>15 min 0 s<" in html and "SIGINT" in html
    assert "--session-dir" in html                        # trial 3 not done
    assert "href='trial_1/report.html'" in html
    assert "class='band'" in html and "n=2" in html
    assert "id='session-link' href='../report.html'" in trial_html(d / "trial_1")
    assert wilson(0, 0) == (0.0, 1.0)
    assert wilson(5, 5)[0] == pytest.approx(0.566, abs=1e-3) and wilson(5, 5)[1] == 1.0


def test_reports_in_a_real_browser(tmp_path: Path) -> None:
    """Headless Chromium: the context table, the marked outcome, both belief charts, a touch
    at full size with the no-contact frame on click, no network request; screenshots kept in
    test-artifacts/."""
    import shutil
    wd = pytest.importorskip("selenium.webdriver")
    chrome, driver = shutil.which("chromium"), shutil.which("chromedriver")
    if not chrome or not driver:
        pytest.skip("headless chromium + chromedriver not installed")
    from selenium.webdriver.chrome.service import Service
    d = _wrong_trial(tmp_path)
    regenerate(d)
    opts = wd.ChromeOptions()
    opts.binary_location = chrome
    for a in ("--headless", "--no-sandbox", "--disable-gpu", "--no-first-run",
              "--disable-background-networking", "--disable-component-update",
              "--disable-sync", "--window-size=1200,1600",
              f"--user-data-dir={tmp_path / 'chrome-profile'}"):
        opts.add_argument(a)
    drv = wd.Chrome(service=Service(driver), options=opts)
    art = Path(__file__).parents[3] / "test-artifacts"
    art.mkdir(exist_ok=True)
    try:
        drv.get((d / "report.html").as_uri())
        find = drv.find_element
        assert find("id", "context").is_displayed()
        assert "abc123def456" in find("id", "context").text
        assert find("id", "verdict").text == "wrong"
        assert find("css selector", ".platform.wrong .tag.wrong").is_displayed()
        assert find("css selector", ".platform.truth .tag.truth").is_displayed()
        for chart in ("belief-chart", "belief-time-chart"):
            assert len(drv.find_elements("css selector", f"#{chart} polyline.series")) == 4
            assert len(drv.find_elements("css selector", f"#{chart} .stop-line")) == 1
            box = drv.execute_script(f"return document.getElementById('{chart}').getBBox()"
                                     ".width")
            assert box > 300
        drv.set_window_size(1200, 3000)
        drv.save_screenshot(str(art / "trial_report_context.png"))
        fig = find("css selector", "figure.touch")
        img = fig.find_element("css selector", "img")
        assert img.size["width"] == 116
        fig.click()
        assert img.size["width"] == 320 and img.size["height"] == 240   # full size
        nc = fig.find_element("css selector", ".nc")
        assert nc.is_displayed() and nc.size["width"] == 320
        drv.save_screenshot(str(art / "trial_report_touch.png"))
        net = drv.execute_script("return performance.getEntriesByType('resource')"
                                 ".map(e => e.name).filter(n => !n.startsWith('data:'))")
        assert net == []
    finally:
        drv.quit()


def test_progress_says_round_k_of_n_time_and_marks_replayed_touches(tmp_path: Path) -> None:
    from tactex_ros.trial.record import append_event
    now = [0.0]
    lines: list[tuple[str, str]] = []
    p = Progress(lambda text, kind: lines.append((kind, text)), clock=lambda: now[0])
    p.follow(tmp_path / "not_yet")
    for t in (2.0, 6.0, 11.0, 36.0):    # the nodes are starting: said after 5 s, then every
        #                                 30 s (not every 5 s: issue 47)
        now[0] = t
        p.poll()
    assert [k for k, _ in lines] == ["info", "info"]
    d = _wrong_trial(tmp_path)
    append_event(d, {"event": "resumed", "after_touch": 3, "touches_replayed": 3,
                     "decisions_on_disk": 1, "how": "re-training", "time": 1.0})
    lines.clear()
    p.follow(d)
    p.poll()
    presses = [t for k, t in lines if k == "press"]
    assert ["replayed" in t for t in presses] == [True, True, True, False, False]
    assert "(1 failed attempt)" in presses[0]
    decisions = [t for k, t in lines if k == "decision"]
    # round 1 of 8, 45 s after the first request: at most 45 / 2 * 7 s left
    assert decisions[0].startswith("decision 1/8:") and "[replayed]" in decisions[0]
    assert "0:45 elapsed, at most about 2:38 left" in decisions[0]
    assert decisions[1].startswith("decision 2/8:") and "replayed" not in decisions[1]


def test_a_starved_simulated_camera_is_behind_not_broken() -> None:
    """11 frames a second of 25 (the CI machine's starved mock camera): a real camera's
    ERROR, the simulated camera's WARN "simulation behind"; a stale frame stays ERROR."""
    th = CameraHealthSettings()
    frame = np.full((240, 320, 3), 100, np.uint8)
    real, sim = dg.CameraHealth(25.0, th), dg.CameraHealth(25.0, th, simulated=True)
    for cam in (real, sim):
        cam.phase.end(0.0)
        for k in range(22):
            cam.observe(frame, 10.0 + k / 11.0)
    t = 10.0 + 21 / 11.0 + 0.01
    assert real.check(t)[0] == dg.ERROR
    level, msg, values = sim.check(t)
    assert level == dg.WARN and msg.startswith("simulation behind")
    assert values["frame rate [Hz]"] == pytest.approx(11.0, abs=0.6)
    assert sim.check(t + 1.0)[0] == dg.ERROR                # the newest frame is 1 s old
