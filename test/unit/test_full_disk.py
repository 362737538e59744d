"""A disk that fills (a file-size limit, RLIMIT_FSIZE, in a child process) at each write site of
a trial record: the write fails with a WriteError naming the file, nothing is left torn, what
was written before stays readable and the record stays resumable."""

from __future__ import annotations

import json
import subprocess
import sys
import textwrap
from pathlib import Path

import numpy as np
import pytest

from tactex_ros.core.outputs import WriteError, check_free, fsync_write, write_bytes
from tactex_ros.trial.record import TrialRecord, check_resumable, read_checkpoint, read_record

PRELUDE = """
import json, resource, sys
from pathlib import Path
import numpy as np
from tactex_ros.core.outputs import WriteError
from tactex_ros.trial.record import TrialRecord
root = Path(sys.argv[1])
out = {}
def limit(n):
    resource.setrlimit(resource.RLIMIT_FSIZE, (n, resource.getrlimit(resource.RLIMIT_FSIZE)[1]))
"""


def child(tmp_path: Path, body: str) -> dict:
    """Run ``body`` in a child process (the limit must not reach pytest's own files); the
    child prints ``out`` as JSON."""
    code = PRELUDE + textwrap.dedent(body) + "\nprint(json.dumps(out))\n"
    p = subprocess.run([sys.executable, "-c", code, str(tmp_path)], capture_output=True,
                       text=True, timeout=120)
    assert p.returncode == 0, p.stderr
    return json.loads(p.stdout.strip().splitlines()[-1])


def noise(h: int = 64, w: int = 64, seed: int = 0) -> np.ndarray:
    return np.random.default_rng(seed).integers(0, 256, (h, w, 3), dtype=np.uint8)


def test_touch_image_cut_by_the_limit_is_refused_and_the_record_stays_resumable(tmp_path):
    out = child(tmp_path, """
        rec = TrialRecord(root, "t", min_free_mb=0)
        rec.save_inputs(None, {"x": 1})
        small = np.zeros((4, 4, 3), np.uint8)
        rec.add_touch(small, {"platform_id": "c1"})
        limit(6000)                              # a 64x64 noise PNG is ~12 kB
        img = np.random.default_rng(0).integers(0, 256, (64, 64, 3), dtype=np.uint8)
        try:
            rec.add_touch(img, {"platform_id": "c2"}, no_contact=small)
            out["raised"] = None
        except WriteError as exc:
            out["raised"] = str(exc)
        out["n"] = rec.n_touches
    """)
    d = tmp_path / "t"
    assert out["raised"] and "touch_0002_c2.png" in out["raised"]
    assert out["n"] == 1
    assert sorted(f.name for f in d.glob("*.png")) == ["touch_0001_c1.png"]   # nothing torn
    assert check_resumable(d) is None
    rec = TrialRecord(tmp_path, "t", resume=True, min_free_mb=0)
    assert rec.n_touches == 1
    assert rec.add_touch(noise(), {"platform_id": "c2"}).name == "touch_0002_c2.png"
    got = read_record(d)
    assert [t["seq"] for t in got["touches"]] == [1, 2]
    assert got["touches"][1]["array"].shape == (64, 64, 3)


def test_no_contact_frame_cut_by_the_limit_takes_the_touch_back(tmp_path):
    out = child(tmp_path, """
        rec = TrialRecord(root, "t", min_free_mb=0)
        limit(6000)
        small = np.zeros((4, 4, 3), np.uint8)
        nc = np.random.default_rng(1).integers(0, 256, (64, 64, 3), dtype=np.uint8)
        try:
            rec.add_touch(small, {"platform_id": "c1"}, no_contact=nc)
        except WriteError as exc:
            out["raised"] = str(exc)
        out["n"] = rec.n_touches
    """)
    assert "no_contact_0001.png" in out["raised"] and out["n"] == 0
    assert list((tmp_path / "t").glob("*.png")) == []       # the touch image went with it
    assert not (tmp_path / "t" / "touches.jsonl").exists()


def test_touch_line_cut_by_the_limit_leaves_whole_lines(tmp_path):
    out = child(tmp_path, """
        rec = TrialRecord(root, "t", min_free_mb=0)
        rec.save_inputs(None, {"x": 1})
        limit(700)
        small = np.zeros((2, 2, 3), np.uint8)
        out["raised"] = None
        for k in range(50):
            try:
                rec.add_touch(small, {"platform_id": "c1", "note": "x" * 40})
            except WriteError as exc:
                out["raised"] = str(exc)
                break
        out["n"] = rec.n_touches
    """)
    d = tmp_path / "t"
    assert out["raised"] and "touches.jsonl" in out["raised"]
    raw = (d / "touches.jsonl").read_bytes()
    assert raw.endswith(b"\n")                              # the cut line was taken back
    lines = [json.loads(x) for x in raw.decode().splitlines()]
    assert [t["seq"] for t in lines] == list(range(1, out["n"] + 1)) and out["n"] >= 2
    assert len(list(d.glob("touch_*.png"))) == out["n"]     # the failed touch's image removed
    assert TrialRecord(tmp_path, "t", resume=True, min_free_mb=0).n_touches == out["n"]


def test_result_cut_by_the_limit_is_not_written(tmp_path):
    out = child(tmp_path, """
        rec = TrialRecord(root, "t", min_free_mb=0)
        rec.save_inputs(None, {"x": 1})
        limit(2000)
        try:
            rec.finish({"prediction": "c1", "notes": "y" * 5000})
        except WriteError as exc:
            out["raised"] = str(exc)
    """)
    d = tmp_path / "t"
    assert "result.json" in out["raised"]
    assert not (d / "result.json").exists() and not (d / "result.json.tmp").exists()
    assert check_resumable(d) is None               # no result: the trial is resumable


def test_checkpoint_cut_by_the_limit_keeps_the_previous_one(tmp_path):
    out = child(tmp_path, """
        rec = TrialRecord(root, "t", min_free_mb=0)
        rec.write_checkpoint({"round": 1}, b"a" * 100, 1)
        limit(3000)
        try:
            rec.write_checkpoint({"round": 2}, b"b" * 5000, 2)
        except WriteError as exc:
            out["raised"] = str(exc)
    """)
    assert "learner_0002.state" in out["raised"]
    state, after, blob = read_checkpoint(tmp_path / "t")
    assert state == {"round": 1} and after == 1 and blob == b"a" * 100
    assert sorted(f.name for f in (tmp_path / "t").iterdir()) == ["checkpoint.json",
                                                                 "learner_0001.state"]


def test_report_cut_by_the_limit_leaves_no_torn_report(tmp_path):
    out = child(tmp_path, """
        from tactex_ros.trial.report import write_trial_report
        rec = TrialRecord(root, "t", min_free_mb=0)
        rec.save_inputs(None, {"trial": {"strategy": "ucb"}})
        rec.add_touch(np.zeros((4, 4, 3), np.uint8), {"platform_id": "c1", "accepted": True})
        rec.finish({"prediction": "c1", "touches": 1, "stop_reason": "confident"})
        limit(1000)
        try:
            write_trial_report(rec.dir)
        except WriteError as exc:
            out["raised"] = str(exc)
    """)
    assert "report.html" in out["raised"]
    assert [f.name for f in (tmp_path / "t").glob("*report*")] == []


def test_mcap_cut_by_the_limit_stops_the_copy_and_keeps_whole_messages(tmp_path):
    pytest.importorskip("rclpy")
    out = child(tmp_path, """
        from std_msgs.msg import String
        from tactex_ros.ros.bag import BagWriter
        bag = BagWriter(root / "topics.mcap")
        bag.write("/a", String(data="first"), 1)
        limit(1500)
        out["raised"] = None
        for k in range(100):
            try:
                bag.write("/a", String(data="m" * 100), 2 + k)
            except WriteError as exc:
                out["raised"] = str(exc)
                break
        bag.write("/a", String(data="after"), 999)        # nothing, no error
        bag.close()                                       # never raises
        out["failed"] = bag.failed
    """)
    from tactex_ros.ros.bag import read_bag
    assert "topics.mcap" in out["raised"] and out["failed"]
    msgs = read_bag(tmp_path / "topics.mcap")
    assert msgs[0][2].data == "first" and len(msgs) >= 2
    assert all(m.data != "after" for _, _, m in msgs)


def test_free_space_margin_refuses_a_trial_and_a_touch(tmp_path):
    with pytest.raises(WriteError, match="min_free_mb"):
        TrialRecord(tmp_path, "t", min_free_mb=1e12)
    assert not (tmp_path / "t").exists()
    rec = TrialRecord(tmp_path, "u", min_free_mb=0)
    rec.min_free_mb = 1e12
    with pytest.raises(WriteError, match="min_free_mb"):
        rec.add_touch(noise(4, 4), {"platform_id": "c1"})
    assert rec.n_touches == 0
    check_free(tmp_path, 0.001, "x")           # a margin that holds


def test_write_helpers_refuse_an_unwritable_folder(tmp_path):
    d = tmp_path / "ro"
    d.mkdir()
    d.chmod(0o500)
    try:
        if (d / "probe").parent.stat().st_mode and not _writable(d):
            with pytest.raises(WriteError, match="ro"):
                write_bytes(d / "x.json", b"{}")
            with pytest.raises(WriteError, match="ro"):
                fsync_write(d / "x.jsonl", b"{}\n", True)
    finally:
        d.chmod(0o700)


def _writable(d: Path) -> bool:
    import os
    return os.access(d, os.W_OK)
