"""The whole press on the graph: the mock camera's capture answers a burst of in-contact
frames, the press action's touch carries them, the explorer describes each touch over 4 frames
(``learner.descriptor_frames`` 4) and records every frame; the same presses replayed offline
from the record (the engine over the recorded touches, ``trial.resume.Replay``) give the same
decisions and outcome."""

from __future__ import annotations

import json
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from tactex_ros.core.config import TrialConfig, learner_class
from tactex_ros.core.engine import TrialSpec
from tactex_ros.ros import adapter
from tactex_ros.ros.graph import describe
from tactex_ros.ros.devrun.launcher import run_graph
from tactex_ros.robot.scene import load_scene
from tactex_ros.trial.record import read_record
from tactex_ros.trial.resume import Replay, recorded_touches
from tactex_ros.trial.run import TrialRun

pytestmark = pytest.mark.ros

FRAMES = 4


def _offline(record: Path, out: Path, burst: bool = True, rounds: int | None = None) -> dict:
    """The record's touches handed, in order, to a fresh trial with the record's settings
    (``burst`` False: each touch without its extra frames; ``rounds``: so many rounds)."""
    cfg = json.loads((record / "config.json").read_text())
    ids = [p.id for p in load_scene(record / "scene.yaml").ordered]
    learner = learner_class(cfg["learner"]["model"]).check(cfg["learner"], "learner")
    trial = TrialConfig.check(cfg["trial"] | ({} if rounds is None else {"rounds": rounds}),
                              "trial")
    spec = TrialSpec(len(ids) - 1, learner, trial,
                     seed=cfg["explorer"]["seed"], platform_ids=tuple(ids))

    def no_more(platform: int) -> None:
        raise AssertionError(f"the offline trial asked for a touch of {ids[platform]} the "
                             "live one never made")
    touches = recorded_touches(read_record(record))
    if not burst:
        touches = [replace(r, touch=replace(r.touch, extra=None) if r.touch else None)
                   for r in touches]
    replay = Replay(touches, no_more, ids)
    run = TrialRun(spec, out, "offline", press=lambda p, meta: replay(p), inputs=cfg)
    res = run.run()
    assert not replay.replaying or rounds is not None     # every recorded touch was used
    return res


# 45 s of graph (make test-soak); the burst through the graph stays in make test (below), its
# replay in test/unit/test_record_burst.py
@pytest.mark.soak
def test_live_burst_trial_equals_its_offline_replay(tmp_path: Path, listener,
                                                    quick_scene: str) -> None:
    nodes = describe(True, quick_scene,
                     explorer={"trial": {"rounds": 2, "stop_confidence": 0.0}, "seed": 1,
                               "learner": {"descriptor_frames": FRAMES},
                               "record_dir": str(tmp_path), "trial_id": "live"})
    scene = load_scene(nodes[0].parameters["scene_file"])
    assert scene.press.capture_frames == FRAMES        # the default burst: 4 frames
    run = run_graph(nodes, tmp_path / "logs", timeout_s=300, domain_id=listener.domain_id)
    assert not run.timed_out and run.exit_code == 0, (tmp_path / "logs" / "explorer.log")
    live = run.result
    rec = read_record(run.record)
    accepted = [t for t in rec["touches"] if t["accepted"]]
    assert len(accepted) == live["touches"] >= 5 + 1
    # every touch carries the burst: the strongest frame and 3 more of the same press, all
    # on disk lossless, each a frame of its own (the mock renders every frame at the force
    # it holds)
    for t in accepted:
        assert len(t["extra"]) == FRAMES - 1 and len(t["extra_arrays"]) == FRAMES - 1
        frames = [t["array"]] + t["extra_arrays"]
        assert all(f.shape == (240, 320, 3) and f.dtype == np.uint8 for f in frames)
    # the MCAP's touches carry the same frames (the action result's Touch.extra_images)
    from mcap_ros2.reader import read_ros2_messages
    from tactex_ros.ros.bag import EXTRA_IMAGE_VIEW, TOUCH_TOPIC
    msgs = list(read_ros2_messages(str(run.record / "topics.mcap")))
    touches = [m.ros_msg for m in msgs if m.channel.topic == TOUCH_TOPIC]
    assert len(touches) == len(accepted)
    for msg, t in zip(touches, accepted, strict=True):
        got = [np.frombuffer(bytes(im.data), np.uint8).reshape(240, 320, 3)
               for im in msg.extra_images]
        assert all(np.array_equal(a, b) for a, b in zip(got, t["extra_arrays"], strict=True))
    assert sum(m.channel.topic == EXTRA_IMAGE_VIEW for m in msgs) == \
        (FRAMES - 1) * len(accepted)

    off = _offline(run.record, tmp_path / "offline")
    assert (off["prediction"], off["touches"], off["stop_reason"]) == \
        (live["prediction"], live["touches"], live["stop_reason"])
    for a, b in zip(live["rounds"] + [live["final"]], off["rounds"] + [off["final"]],
                    strict=True):
        assert a["platform"] == b["platform"]
        np.testing.assert_allclose(b["probs"], a["probs"], atol=1e-9, rtol=0)
    # the extra frames count: the baseline's belief (the first decision, from the same 5
    # touches either way) differs when the touches are described by their strongest frame
    one = _offline(run.record, tmp_path / "one_frame", burst=False, rounds=0)
    assert np.abs(np.subtract(one["final"]["probs"], live["rounds"][0]["probs"])).max() > 1e-6


def test_a_short_hold_still_gets_the_whole_burst(tmp_path: Path, listener, press,
                                                 quick_scene: str) -> None:
    """No hold at all (``settle_s`` 0): when the capture is asked for, few frames of the press
    are in contact yet. The motion node holds the press and asks again until the burst is
    whole, within ``capture_deadline_s``."""
    import yaml

    from tactex_ros.ros.devrun.launcher import Graph
    scene = yaml.safe_load(Path(quick_scene).read_text())
    scene["press"]["settle_s"] = 0.0
    path = tmp_path / "scene_no_hold.yaml"
    path.write_text(yaml.safe_dump(scene, sort_keys=False))
    nodes = [n for n in describe(True, str(path))
             if n.name in ("mock_arm", "mock_image", "motion")]
    assert load_scene(path).press.capture_frames == FRAMES
    with Graph(nodes, tmp_path / "logs", listener.domain_id):
        for pid in ("c1", "c2"):
            res = press(pid)
            assert res is not None and res.success, res
            assert len(res.touch.extra_images) == FRAMES - 1, pid
            stamps = [adapter.seconds(im.header.stamp)
                      for im in [res.touch.image, *res.touch.extra_images]]
            assert len(set(stamps)) == FRAMES        # four frames of their own
