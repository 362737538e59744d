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


def test_standard_views_decode_without_ros(tmp_path: Path) -> None:
    """Beside tactex's own messages the bag carries what any viewer shows: one
    sensor_msgs/Image per touch (its pixels, the camera's frame), the press force as a
    WrenchStamped and the belief per platform as std_msgs/Float64; mcap's ROS 2 decoder reads
    them from the schemas in the file alone."""
    reader = pytest.importorskip("mcap_ros2.reader")
    from tactex_ros.ros.bag import BELIEF_VIEW, NO_CONTACT_VIEW, TOUCH_IMAGE_VIEW, WRENCH_VIEW
    path = tmp_path / "topics.mcap"
    bag = BagWriter(path)
    for i in range(1, 4):
        t = _touch(i)
        if i == 2:
            t.no_contact_image = adapter.array_to_image(_img(9), 0.0, "")
        bag.write_all(TOUCH_TOPIC, t, i * 10**9)
    s = _state(1, False)
    s.platform_ids = ["c1", "c2"]
    bag.write_all("/tactex/state", s, 4 * 10**9)
    bag.close()
    assert [m[0] for m in read_bag(path, decode=False)].count(TOUCH_TOPIC) == 3
    msgs = list(reader.read_ros2_messages(str(path)))
    by = {}
    for m in msgs:
        by.setdefault(m.channel.topic, []).append(m)
    images = by[TOUCH_IMAGE_VIEW]
    assert [m.schema.name for m in images] == ["sensor_msgs/msg/Image"] * 3
    for i, m in enumerate(images, 1):
        im = m.ros_msg
        assert (im.encoding, im.height, im.width, im.header.frame_id) == ("rgb8", 240, 320,
                                                                         "gelsight")
        assert np.array_equal(np.frombuffer(bytes(im.data), np.uint8).reshape(240, 320, 3),
                              _img(i))
        assert m.log_time_ns == i * 10**9
    nc = by[NO_CONTACT_VIEW]                       # only the touch that brought one
    assert len(nc) == 1 and nc[0].ros_msg.header.frame_id == "gelsight"
    assert np.array_equal(np.frombuffer(bytes(nc[0].ros_msg.data), np.uint8).reshape(
        240, 320, 3), _img(9))
    assert [m.schema.name for m in by[WRENCH_VIEW]] == ["geometry_msgs/msg/WrenchStamped"] * 3
    assert [m.ros_msg.wrench.force.z for m in by[WRENCH_VIEW]] == [5.0, 6.0, 7.0]
    assert [m.ros_msg.data for m in by[BELIEF_VIEW + "c1"]] == [0.5]
    assert by[BELIEF_VIEW + "c2"][0].schema.name == "std_msgs/msg/Float64"


def test_the_bag_is_chunked_compressed_and_indexed(tmp_path: Path) -> None:
    """What readers that seek need (rerun's MCAP import, ``mcap info``, ``ros2 bag``): zstd
    chunks, one per write (a touch with its views in one), their index and the statistics in
    the summary; the indexed read gives every message."""
    path = tmp_path / "topics.mcap"
    bag = BagWriter(path)
    for i in range(1, 4):
        bag.write_all(TOUCH_TOPIC, _touch(i), i * 10**9)
    bag.write("/tactex/state", _state(1, True), 4 * 10**9)
    bag.close()
    with open(path, "rb") as f:
        reader = make_reader(f)
        summary = reader.get_summary()
        chunks = summary.chunk_indexes
        assert len(chunks) == 4 == summary.statistics.chunk_count
        assert {c.compression for c in chunks} == {"zstd"}
        assert all(c.message_index_offsets for c in chunks)          # message indexes
        # a touch's chunk holds the touch, its image and its force: 3 messages at one time
        assert [c.message_start_time for c in chunks] == [10**9, 2 * 10**9, 3 * 10**9,
                                                          4 * 10**9]
        assert summary.statistics.message_count == 3 * 3 + 1
        assert chunks[0].uncompressed_size > 2 * 240 * 320 * 3          # touch + image
        topics = [c.topic for _, c, _ in reader.iter_messages(log_time_order=True)]
    assert topics.count(TOUCH_TOPIC) == 3 and topics[-1] == "/tactex/state"
    assert [m[0] for m in read_bag(path)] == topics                  # the stream reader too


def test_a_resumed_trials_bags_are_listed_in_its_record(tmp_path: Path) -> None:
    from tactex_ros.ros.bag import recorded_bags
    from tactex_ros.trial.record import read_record
    rec = tmp_path / "trial"
    rec.mkdir()
    (rec / "config.json").write_text("{}")                           # a trial record
    for k, name in enumerate(["topics.mcap", "topics.1.mcap"]):      # started, then resumed
        bag = BagWriter(rec / name)
        bag.write(TOUCH_TOPIC, _touch(k + 1), (k + 1) * 10**9)
        bag.close()
    assert recorded_bags(rec) == [rec / "topics.mcap", rec / "topics.1.mcap"]
    events = [e for e in read_record(rec, images=False)["events"]
              if e["event"] == "mcap_started"]
    assert [e["file"] for e in events] == ["topics.mcap", "topics.1.mcap"]
    assert [read_bag(p)[0][2].platform_id for p in recorded_bags(rec)] == ["c1", "c2"]
    plain = tmp_path / "elsewhere.mcap"                               # not in a record
    BagWriter(plain).close()
    assert not (tmp_path / "events.jsonl").exists()


def _two_part_record(tmp_path: Path) -> tuple[Path, int]:
    """A trial record whose run was interrupted and resumed: ``topics.mcap`` (2 touches and a
    state) and ``topics.1.mcap`` (1 touch and 2 states, the first part's schemas again);
    returns the folder and the messages of both parts."""
    from tactex_ros.ros.bag import count_messages
    rec = tmp_path / "trial"
    rec.mkdir()
    (rec / "config.json").write_text("{}")
    first = BagWriter(rec / "topics.mcap")
    for i in (1, 2):
        first.write_all(TOUCH_TOPIC, _touch(i), i * 10**9)
    first.write("/tactex/state", _state(1, False), 3 * 10**9)
    first.close()
    second = BagWriter(rec / "topics.1.mcap")
    second.write_all(TOUCH_TOPIC, _touch(3), 10 * 10**9)
    second.write("/tactex/state", _state(2, False), 11 * 10**9)
    second.write("/tactex/state", _state(3, True), 12 * 10**9)
    second.close()
    n = count_messages(rec / "topics.mcap") + count_messages(rec / "topics.1.mcap")
    return rec, n


def test_a_resumed_trials_parts_merge_into_one_bag(tmp_path: Path) -> None:
    from tactex_ros.ros.bag import merge_bags, recorded_bags
    from tactex_ros.trial.record import read_record
    rec, n = _two_part_record(tmp_path)
    # each touch: the touch, its image and its force; the first part 2 + 1, the second 1 + 2
    assert n == (2 * 3 + 1) + (3 + 2)
    before = read_bag(rec / "topics.mcap", decode=False) + read_bag(rec / "topics.1.mcap",
                                                                    decode=False)
    assert merge_bags(rec) == rec / "topics.mcap"
    assert sorted(p.name for p in rec.glob("*.mcap*")) == ["topics.mcap"]
    after = read_bag(rec / "topics.mcap", decode=False)
    assert len(after) == n and after == before            # every message, in order, same bytes
    assert [m.platform_id for t, _, m in read_bag(rec / "topics.mcap") if t == TOUCH_TOPIC] \
        == ["c1", "c2", "c3"]
    with open(rec / "topics.mcap", "rb") as f:            # indexed, one schema per type
        summary = make_reader(f).get_summary()
        assert summary.statistics.message_count == n
        names = [s.name for s in summary.schemas.values()]
        assert len(names) == len(set(names)) == 4          # Touch, Image, Wrench, State
        assert len(summary.channels) == 4
    assert recorded_bags(rec) == [rec / "topics.mcap"]
    merged = [e for e in read_record(rec, images=False)["events"] if e["event"] == "mcap_merged"]
    assert merged[0]["parts"] == ["topics.mcap", "topics.1.mcap"]
    assert merged[0]["messages"] == n
    # the next resume writes a part again: listed after the merged file, merged again
    third = BagWriter(rec / "topics.1.mcap")
    third.write("/tactex/state", _state(4, True), 20 * 10**9)
    third.close()
    assert recorded_bags(rec) == [rec / "topics.mcap", rec / "topics.1.mcap"]
    assert merge_bags(rec) == rec / "topics.mcap"
    assert len(read_bag(rec / "topics.mcap", decode=False)) == n + 1
    assert merge_bags(rec) == rec / "topics.mcap"         # one bag: nothing to do


def test_a_crashed_part_merges_up_to_its_last_whole_message(tmp_path: Path) -> None:
    from tactex_ros.ros.bag import merge_bags
    rec, n = _two_part_record(tmp_path)
    part = rec / "topics.1.mcap"
    data = part.read_bytes()
    with open(rec / "topics.1.mcap", "rb") as f:
        cut = make_reader(f).get_summary().chunk_indexes[-1].chunk_start_offset + 10
    part.write_bytes(data[:cut])                   # the second run crashed in its last chunk
    assert merge_bags(rec) == rec / "topics.mcap"
    assert len(read_bag(rec / "topics.mcap", decode=False)) == n - 1    # its last state lost


def test_a_failed_merge_keeps_every_part_and_says_so(tmp_path: Path, monkeypatch) -> None:
    from tactex_ros.ros import bag
    from tactex_ros.trial.record import read_record
    rec, n = _two_part_record(tmp_path)
    sizes = {p.name: p.stat().st_size for p in rec.glob("*.mcap")}

    def full(parts, out):
        out.write_bytes(b"\x89MCAP0\r\n")                # a torn file, then the disk is full
        raise OSError(28, "No space left on device")
    monkeypatch.setattr(bag, "_merge_into", full)
    assert bag.merge_bags(rec) is None
    assert {p.name: p.stat().st_size for p in rec.glob("*.mcap*")} == sizes
    ev = [e for e in read_record(rec, images=False)["events"]
          if e["event"] == "mcap_merge_failed"]
    assert ev and ev[0]["parts"] == ["topics.mcap", "topics.1.mcap"]
    assert bag.recorded_bags(rec) == [rec / "topics.mcap", rec / "topics.1.mcap"]
    # a merged file that reads back short is not taken either
    monkeypatch.undo()
    real = bag.count_messages
    monkeypatch.setattr(bag, "count_messages",
                        lambda p: real(p) - (Path(p).name.endswith(".merging")))
    assert bag.merge_bags(rec) is None
    assert {p.name: p.stat().st_size for p in rec.glob("*.mcap*")} == sizes
