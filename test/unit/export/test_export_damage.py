"""Issue 49, item 5: ``tactex export`` of a damaged record or onto a full disk. A field of the
wrong type is refused naming the record's file, the line and the field (was: a traceback); a
damaged line in the middle of ``touches.jsonl`` is refused naming the file and the line (was:
dropped without a word), while the torn last line a crash leaves (and a resume closes) is
still skipped; a file-size limit that stops the parquet file leaves nothing unreadable in
``--out`` (exit 1, the file named) and the same command then succeeds."""

from __future__ import annotations

import json
import subprocess
import sys
import textwrap
from pathlib import Path

import numpy as np
import pytest

datasets = pytest.importorskip("datasets")

from tactex_ros.cli.main import main  # noqa: E402
from tactex_ros.core.errors import InputError  # noqa: E402
from tactex_ros.core.paths import config_dir  # noqa: E402
from tactex_ros.trial.record import TrialRecord, read_record  # noqa: E402


def _record(root: Path, touches: int = 6, belief: list | None = None) -> Path:
    """A record as the explorer writes it: noise images, the press's numbers, a decision after
    each touch past the baseline, a result."""
    rng = np.random.default_rng(0)
    rec = TrialRecord(root, "t", min_free_mb=0)
    rec.save_inputs(config_dir() / "scene_sim.yaml", {"trial": {"strategy": "ucb"}})
    ids = ["reference", "c1", "c2", "c3", "c4"]
    for k in range(touches):
        p = k % len(ids)
        rec.add_touch(rng.integers(0, 256, (60, 80, 3), dtype=np.uint8),
                      {"platform_id": ids[p], "platform_index": p, "accepted": True,
                       "force_n": 5.0, "depth_m": 4e-4, "stamp": 100.0 + k,
                       "requested": 99.0 + k, "pose": [0.4, 0.1, 0.08]},
                      no_contact=np.zeros((60, 80, 3), np.uint8))
        if k >= 4:
            rec.add_decision({"round": k - 3, "belief": belief or [0.4, 0.1, 0.2, 0.3],
                              "next": "c1", "touches": [1, 1, 1, 1, 1]})
    rec.finish({"prediction": "c1", "touches": touches, "stop_reason": "rounds"})
    return rec.dir


def _edit_line(path: Path, n: int, edit) -> None:
    lines = path.read_text().splitlines()
    lines[n - 1] = edit(lines[n - 1])
    path.write_text("\n".join(lines) + "\n")


def _set(field, value):
    return lambda line: json.dumps(dict(json.loads(line), **{field: value}))


@pytest.mark.parametrize("field, value", [("force_n", "strong"), ("depth_m", [1]),
                                          ("stamp", "noon"), ("pose", ["a", "b", "c"]),
                                          ("pose", 3), ("seq", "3")])
def test_a_wrong_typed_field_is_refused_naming_record_line_and_field(tmp_path, capsys, field,
                                                                     value):
    d = _record(tmp_path)
    _edit_line(d / "touches.jsonl", 3, _set(field, value))
    assert main(["export", str(d), "--out", str(tmp_path / "ds")]) == 2
    err = capsys.readouterr().err
    assert str(d / "touches.jsonl") in err and "line 3" in err and repr(field) in err, err
    assert "Traceback" not in err and not (tmp_path / "ds").exists()


def test_a_null_in_a_belief_is_exported_as_none(tmp_path):
    """NaN is written as null (strict JSON): it is a missing number, not a damage."""
    d = _record(tmp_path, belief=[0.4, None, 0.3, 0.3])
    out = tmp_path / "ds"
    assert main(["export", str(d), "--out", str(out)]) == 0
    ds = datasets.load_dataset(str(out), split="train", cache_dir=str(tmp_path / "c"))
    assert [r["belief"] for r in ds if r["belief"]][0] == [0.4, None, 0.3, 0.3]


def test_a_damaged_middle_line_is_refused_naming_file_and_line(tmp_path, capsys):
    d = _record(tmp_path)
    _edit_line(d / "touches.jsonl", 2, lambda line: line.replace(":", "=", 1))   # a bad byte
    assert main(["export", str(d), "--out", str(tmp_path / "ds")]) == 2
    err = capsys.readouterr().err
    assert str(d / "touches.jsonl") in err and "line 2" in err and "Traceback" not in err
    with pytest.raises(InputError, match="line 2"):
        read_record(d)                        # every reader of the record: report, resume


def test_the_torn_line_a_crash_leaves_is_skipped_also_once_a_resume_closed_it(tmp_path):
    d = _record(tmp_path)
    (d / "result.json").unlink()                               # an interrupted trial
    with open(d / "touches.jsonl", "a") as f:
        f.write('{"platform_id": "c1", "platf')               # a crash mid-line
    assert len(read_record(d)["touches"]) == 6                 # the last line: skipped
    rec = TrialRecord(tmp_path, "t", resume=True, min_free_mb=0)
    rec.add_touch(np.zeros((60, 80, 3), np.uint8), {"platform_id": "c1", "platform_index": 1,
                                                    "accepted": True})
    got = read_record(d)["touches"]                             # the torn line is now line 7
    assert [t["seq"] for t in got] == [1, 2, 3, 4, 5, 6, 7]
    assert any(e.get("event") == "torn_line" and e["line"] == 7
               for e in read_record(d)["events"])


def test_a_full_disk_leaves_no_unreadable_parquet_and_the_rerun_goes_through(tmp_path):
    d = _record(tmp_path, touches=12)
    out = tmp_path / "ds"
    code = textwrap.dedent(f"""
        import resource, sys
        from tactex_ros.cli.main import main
        resource.setrlimit(resource.RLIMIT_FSIZE,
                           (20000, resource.getrlimit(resource.RLIMIT_FSIZE)[1]))
        sys.exit(main(["export", {str(d)!r}, "--out", {str(out)!r}]))
    """)
    p = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                       timeout=300)
    assert p.returncode == 1, (p.stdout, p.stderr[-3000:])
    assert "parquet" in p.stderr and "Traceback" not in p.stderr, p.stderr[-3000:]
    assert not out.exists() or list(out.rglob("*")) == []        # nothing left to trip on
    assert [f.name for f in tmp_path.iterdir() if f.name.startswith(".ds")] == []
    assert main(["export", str(d), "--out", str(out)]) == 0      # the rerun is not blocked
    ds = datasets.load_dataset(str(out), split="train", cache_dir=str(tmp_path / "c"))
    assert len(ds) == 12
