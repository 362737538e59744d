"""What the operator looks at, without a running graph: viewer configs, the health grading,
the progress lines and the HTML reports built from a record on disk."""

from __future__ import annotations

import json
import re
from pathlib import Path

import numpy as np
import pytest
import yaml

from tactex_ros.paths import config_dir
from tactex_ros.trial.progress import Progress, decision_line, press_line
from tactex_ros.trial.record import TrialRecord
from tactex_ros.trial.report import regenerate, trial_html
from tactex_ros.ros import diagnostics as dg
from tactex_ros.ros.settings import (MARKER_TOPIC, POSE_TOPIC, STATE_TOPIC, TOUCH_IMAGE_TOPIC,
                                     WRENCH_TOPIC, CameraHealthSettings)


def test_rviz_subscribes_transient_local_where_the_explorer_latches() -> None:
    cfg = yaml.safe_load((config_dir() / "tactex.rviz").read_text())
    durab = {d["Topic"]["Value"]: d["Topic"]["Durability Policy"]
             for d in cfg["Visualization Manager"]["Displays"] if "Topic" in d}
    assert durab[MARKER_TOPIC] == durab[TOUCH_IMAGE_TOPIC] == "Transient Local"


def test_foxglove_layout_shows_the_graphs_topics() -> None:
    lay = json.loads((config_dir() / "tactex.foxglove.json").read_text())
    text = json.dumps(lay["configById"])
    for topic in (TOUCH_IMAGE_TOPIC, MARKER_TOPIC, STATE_TOPIC, POSE_TOPIC, WRENCH_TOPIC,
                  "/diagnostics"):
        assert topic in text, topic
    # every panel of the layout tree is configured, and every configured panel is placed
    placed = set(re.findall(r'"([A-Za-z0-9 ]+![a-z]+)"', json.dumps(lay["layout"])))
    assert placed == set(lay["configById"])


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
    assert len(re.findall(r"<polyline class='series'", html)) == 4   # one line per comparison
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
