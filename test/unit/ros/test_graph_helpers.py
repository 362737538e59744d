"""Pure helpers of the ROS graph, tested without rclpy.init: scene, message adapter, trial record, graph description, frame ring."""

from __future__ import annotations

import json
import re

import numpy as np
import pytest
import yaml

from tactex_ros.core.errors import InputError
from tactex_ros.core.paths import config_dir
from tactex_ros.robot.scene import load_scene, parse_scene


def _scene_dict() -> dict:
    return yaml.safe_load((config_dir() / "scene_sim.yaml").read_text())


@pytest.mark.parametrize("path,value,field", [
    (("platforms", 1, "position"), [0.38, -0.9, 0.08], "platforms.1.position: "),
    (("press", "max_force"), -3.0, "press.max_force: "),
    (("press", "force_threshold"), 20.0, "press.force_threshold: "),
    (("press", "bogus"), 1.0, "press.bogus: unknown name"),
    (("platforms", 0, "role"), "comparison", "platforms: need exactly one role: reference"),
    (("workspace", "min"), [0.25, -0.4], "workspace.min.2: "),
    (("platforms", 2, "id"), "c1", "platforms.2.id: duplicate platform id"),
])
def test_scene_errors_name_the_field(path, value, field) -> None:
    d = _scene_dict()
    target = d
    for k in path[:-1]:
        target = target[k]
    target[path[-1]] = value
    with pytest.raises(InputError, match="^scene: " + re.escape(field)):
        parse_scene(d)


def test_scene_files_load(tmp_path) -> None:
    for name in ("scene.yaml", "scene_sim.yaml"):
        s = load_scene(config_dir() / name)
        assert s.reference.role == "reference" and len(s.comparisons) == 4
        assert [p.id for p in s.ordered][0] == "reference"
    with pytest.raises(InputError, match="not found"):
        load_scene(tmp_path / "missing.yaml")
    (tmp_path / "bad.yaml").write_text("platforms: [\n")
    with pytest.raises(InputError, match="scene file .*bad.yaml.*YAML"):
        load_scene(tmp_path / "bad.yaml")


def test_adapter_images_roundtrip_and_rejects() -> None:
    from tactex_ros.ros import adapter
    rng = np.random.default_rng(0)
    img = rng.integers(0, 255, (240, 320, 3), dtype=np.uint8)
    msg = adapter.array_to_image(img, 12.5, "cam")
    assert msg.header.stamp.sec == 12 and msg.header.stamp.nanosec == 500_000_000
    np.testing.assert_array_equal(adapter.image_to_array(msg), img)
    msg.encoding = "bgr8"
    np.testing.assert_array_equal(adapter.image_to_array(msg), img[:, :, ::-1])
    bad = adapter.array_to_image(img[:200], 0.0, "cam")
    with pytest.raises(InputError, match="size"):
        adapter.image_to_array(bad)
    msg2 = adapter.array_to_image(img, 0.0, "cam")
    msg2.data = msg2.data[:-10]
    with pytest.raises(InputError, match="bytes"):
        adapter.image_to_array(msg2)
    msg3 = adapter.array_to_image(img, 0.0, "cam")
    msg3.encoding = "mono16"
    with pytest.raises(InputError, match="encoding"):
        adapter.image_to_array(msg3)
    with pytest.raises(InputError, match="constant"):
        adapter.image_to_array(adapter.array_to_image(np.zeros_like(img), 0.0, "cam"))


def test_adapter_state_and_markers() -> None:
    from tactex_ros.ros import adapter
    from tactex_ros.core.engine import RoundRecord, TrainingDetail
    scene = load_scene(config_dir() / "scene_sim.yaml")
    rec = RoundRecord(round=2, platform=3, probs=[0.1, 0.2, 0.6, 0.1],
                      scores=[0.01, 0.02, 0.3, 0.0], predictive_entropy=1.0,
                      score_s=0.1, choose_s=0.0, touches=[1, 2, 1, 1],
                      model="small_inception",
                      detail=TrainingDetail(input_size=48, train_s=0.2, train_loss=0.5))
    st = adapter.state_msg(rec, trial_id="t", strategy="variance",
                           platform_ids=["c1", "c2", "c3", "c4"], reference_touches=1,
                           done=False, prediction="", t=1.0, frame_id="base")
    assert st.next_platform == "c3" and list(st.touches) == [1, 2, 1, 1]
    assert st.decision_s == pytest.approx(0.3)
    assert st.sure is False                      # not done: never sure
    kw = dict(trial_id="t", strategy="infogain", platform_ids=["c1", "c2", "c3", "c4"],
              reference_touches=1, prediction="c3", t=1.0, frame_id="base")
    assert adapter.state_msg(rec, done=True, sure=True, **kw).sure is True
    assert adapter.state_msg(rec, done=True, sure=False, **kw).sure is False
    assert adapter.state_msg(rec, done=False, sure=True, **kw).sure is False
    ma = adapter.markers(scene, st, 1.0)
    cubes = [m for m in ma.markers if m.ns == "platforms"]
    assert len(cubes) == 5
    nxt = [m for m in ma.markers if m.ns == "next"]
    assert len(nxt) == 1
    assert nxt[0].pose.position.x == pytest.approx(scene.platform("c3").position[0])
    c3 = cubes[3]
    assert c3.color.r == pytest.approx(0.6) and c3.color.a == 1.0


def test_record_writes_every_touch(tmp_path) -> None:
    from tactex_ros.trial.record import TrialRecord, read_record
    r = TrialRecord(tmp_path, "t1")
    img = np.random.default_rng(1).integers(0, 255, (240, 320, 3), dtype=np.uint8)
    r.add_touch(img, {"platform_id": "c1", "accepted": True})
    r.add_touch(None, {"platform_id": "c2", "accepted": False, "reason": "no contact"})
    r.reject_touch(1, "guard: blank")
    with open(r.dir / "touches.jsonl", "a") as f:
        f.write('{"torn": ')                      # a crash in the middle of a line
    back = read_record(r.dir)
    assert len(back["touches"]) == 2 and back["result"] is None
    np.testing.assert_array_equal(back["touches"][0]["array"], img)
    assert back["touches"][1]["image"] is None
    assert back["touches"][0]["accepted"] is False
    r.finish({"prediction": "c1"})
    assert json.loads((r.dir / "result.json").read_text())["prediction"] == "c1"
    with pytest.raises(InputError, match="already exists"):
        TrialRecord(tmp_path, "t1")


def test_graph_description() -> None:
    from tactex_ros.ros.graph import describe
    sim = describe(True)
    assert [n.executable for n in sim] == ["mock_arm_node", "mock_image_node", "motion_node",
                                           "explorer_node"]
    hw = describe(False, gelsight={"device": "/dev/video0"})
    assert [n.executable for n in hw] == ["gelsight_node", "motion_node", "explorer_node"]
    assert all(n.parameters["scene_file"].endswith("scene.yaml") for n in hw[1:])
    with pytest.raises(InputError, match="^explorer parameters: roundz: unknown name"):
        describe(True, explorer={"roundz": 3})
    with pytest.raises(InputError, match=r"^explorer parameters: trial\.strategy: .*'greedy'"):
        describe(True, explorer={"trial": {"strategy": "greedy"}})


def test_record_summary(tmp_path) -> None:
    from tactex_ros.cli.graph_commands import summarise
    from tactex_ros.trial.record import TrialRecord, read_record
    r = TrialRecord(tmp_path, "s")
    img = np.random.default_rng(2).integers(0, 255, (240, 320, 3), dtype=np.uint8)
    for k, dur in enumerate([2.0, 3.0, 5.0]):
        r.add_touch(img, {"platform_id": f"c{k}", "requested": 10.0 * k + 1.0,
                          "stamp": 10.0 * k + 1.0 + dur, "accepted": True})
    r.add_touch(None, {"platform_id": "c9", "requested": 50.0, "accepted": False})
    # a request time never taken (0.0: before a simulated clock's first tick) is left out
    r.add_touch(None, {"platform_id": "c8", "requested": 0.0, "stamp": 1.8e9, "accepted": False})
    r.add_decision({"decision_s": 0.5})
    r.add_decision({"decision_s": 1.5})
    s = summarise(read_record(r.dir))
    assert s["touches"] == 5 and s["accepted"] == 3 and s["decisions"] == 2
    assert s["press_s_median"] == pytest.approx(3.0) and s["press_s_total"] == pytest.approx(10.0)
    assert s["decision_s_median"] == pytest.approx(1.0) and s["prediction"] is None
    # the motion node's own press time (approach start to lift-off) counts where recorded
    r.add_touch(img, {"platform_id": "c5", "requested": 60.0, "stamp": 69.0, "press_s": 4.0,
                      "accepted": True})
    s = summarise(read_record(r.dir))
    assert s["press_s_median"] == pytest.approx(3.5) and s["press_s_total"] == pytest.approx(14.0)
