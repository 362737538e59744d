"""MCAP copy of a trial's topics: ROS 2 messages written as CDR with ros2msg schemas, read back;
a file cut off mid-message (a crash) is read up to its last whole message and recovered into a
closed, indexed file."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("rclpy")
tactex_msg = pytest.importorskip("tactex.msg")

from mcap.reader import make_reader  # noqa: E402

from tactex_ros.ros import adapter  # noqa: E402
from tactex_ros.ros.bag import BagWriter, TOUCH_TOPIC, message_definition, read_bag, recover_bag  # noqa: E402,E501
from tactex_ros.cli.graph_commands import summarise_bag  # noqa: E402


def _img(i: int) -> np.ndarray:
    return np.random.default_rng(i).integers(0, 255, (240, 320, 3)).astype(np.uint8)


def _touch(i: int):
    img = _img(i)
    t = tactex_msg.Touch(platform_id=f"c{i}", platform_index=i, contact_force_n=4.0 + i)
    t.image = adapter.array_to_image(img, 0.0, "gelsight")
    return t


def _state(r: int, done: bool):
    return tactex_msg.ExplorationState(trial_id="t", round=r, belief=[0.5, 0.5],
                                       decision_s=0.1 * r, done=done,
                                       prediction="c1" if done else "")


def test_write_read_and_recover(tmp_path: Path) -> None:
    path = tmp_path / "topics.mcap"
    bag = BagWriter(path)
    for i in range(1, 4):
        bag.write(TOUCH_TOPIC, _touch(i), i * 10**9)
    bag.write("/tactex/state", _state(1, False), 4 * 10**9)
    bag.write("/tactex/state", _state(2, True), 5 * 10**9)
    bag.close()
    msgs = read_bag(path)
    assert [m[0] for m in msgs] == [TOUCH_TOPIC] * 3 + ["/tactex/state"] * 2
    assert [m[2].platform_id for m in msgs[:3]] == ["c1", "c2", "c3"]
    assert np.array_equal(adapter.image_to_array(msgs[0][2].image), _img(1))
    s = summarise_bag(msgs)
    assert (s["touches"], s["decisions"], s["prediction"]) == (3, 2, "c1")
    with open(path, "rb") as f:                    # closed: indexed, with its summary
        summary = make_reader(f).get_summary()
        assert summary.statistics.message_count == 5
        assert {s.name for s in summary.schemas.values()} == {"tactex/msg/Touch",
                                                              "tactex/msg/ExplorationState"}

    # a crash: the file cut in the middle of the last message, no summary, no footer
    data = path.read_bytes()
    crashed = tmp_path / "crashed.mcap"
    bag = BagWriter(crashed)
    for i in range(1, 4):
        bag.write(TOUCH_TOPIC, _touch(i), i * 10**9)
    size = crashed.stat().st_size
    crashed.write_bytes(crashed.read_bytes()[: size - 100])
    got = read_bag(crashed)
    assert [m[2].platform_id for m in got] == ["c1", "c2"]
    fixed = tmp_path / "fixed.mcap"
    assert recover_bag(crashed, fixed) == 2
    with open(fixed, "rb") as f:
        assert make_reader(f).get_summary().statistics.message_count == 2
    assert len(data) > 0


def test_definition_includes_every_dependency_once() -> None:
    text = message_definition("tactex/msg/Touch")
    deps = [line[5:] for line in text.splitlines() if line.startswith("MSG: ")]
    assert len(deps) == len(set(deps))
    for d in ("std_msgs/Header", "sensor_msgs/Image", "geometry_msgs/Pose",
              "builtin_interfaces/Time", "geometry_msgs/Point", "geometry_msgs/Quaternion"):
        assert d in deps
