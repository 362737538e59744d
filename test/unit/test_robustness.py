"""Issue 21 (docs/robustness.md): bad input refused with exit status 2 and the thing named,
before any work; no false success from an older file; strict JSON; nothing recorded lost.
Each test checks an exit status, a named path/option/field, or an outcome; never log wording."""

from __future__ import annotations

import json
import os
import stat
from pathlib import Path

import cv2
import numpy as np
import pytest

from tactex_ros.cli.main import main
from tactex_ros.core.errors import InputError
from tactex_ros.core.outputs import check_dir, check_file, dumps, write_json
from tactex_ros.trial.record import TrialRecord, check_new_record, check_resumable


def _file(tmp_path: Path) -> Path:
    f = tmp_path / "a_file"
    f.write_text("x")
    return f


# ---------------------------------------------------------------- output paths (exit 2, named)
def _measure_scene(out: str) -> list[str]:
    """``tactex robot measure-scene`` on the simulated scene; no robot state arrives here (the
    command would give up after 0.5 s with exit status 1)."""
    from tactex_ros.core.paths import config_dir
    return ["robot", "measure-scene", "--robot", "sim", "--scene",
            str(config_dir() / "scene_sim.yaml"), "--state-deadline-s", "0.5", "--out", out]


@pytest.mark.parametrize("argv_of, option", [
    (lambda f: ["trial", "--source", "sim", "--quiet", "--json", f"{f}/out.json"], "--json"),
    (lambda f: ["trial", "--source", "sim", "--quiet", "--json", str(f.parent)], "--json"),
    (lambda f: ["sim", "render", "--out", str(f.parent / "x.txt")], "--out"),
    (lambda f: ["sim", "render", "--out", f"{f}/x.png"], "--out"),
    (lambda f: ["experiment", "classify", "--out", f"{f}/results"], "--out"),
    (lambda f: ["graph", "run", "--sim", "--log-dir", f"{f}/logs"], "--log-dir"),
    (lambda f: ["prepare", "--library", "sim", "--out", f"{f}/rep.pt"], "--out"),
    (lambda f: ["bench", "sim", "--json", f"{f}/b.json"], "--json"),
    # issue 49: measure-scene's --out before the first press (was: after pressing every
    # platform, exit 1, no report), export's before reading anything (was: a raw error late)
    (lambda f: _measure_scene(f"{f}/scene.yaml"), "--out"),
    (lambda f: _measure_scene(str(f.parent)), "--out"),
    (lambda f: _measure_scene(str(f.parent / "scene.txt")), "--out"),
    (lambda f: ["export", str(f.parent), "--out", f"{f}/dataset"], "--out"),
    (lambda f: ["export", str(f.parent), "--out", str(f)], "--out"),
])
def test_unwritable_output_refused_before_any_work(tmp_path, capsys, argv_of, option):
    f = _file(tmp_path)
    argv = argv_of(f)
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert option in err and "Traceback" not in err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a_file"]     # nothing written


def test_output_under_a_read_only_file_system_refused():
    # /proc refuses new files also for root (a chmod does not stop root)
    with pytest.raises(InputError, match="/proc"):
        check_file("/proc/tactex_out.json", "--json", (".json",))
    with pytest.raises(InputError, match="--log-dir"):
        check_dir("/proc/tactex_logs/x", "--log-dir")


@pytest.mark.skipif(os.geteuid() == 0, reason="root writes into a read-only folder")
def test_output_in_a_folder_without_write_permission_refused(tmp_path):
    d = tmp_path / "ro"
    d.mkdir()
    d.chmod(stat.S_IRUSR | stat.S_IXUSR)
    try:
        with pytest.raises(InputError, match="ro"):
            check_file(d / "x.json", "--json", (".json",))
    finally:
        d.chmod(stat.S_IRWXU)


def test_writable_outputs_pass_and_leave_nothing(tmp_path):
    assert check_file(tmp_path / "new" / "x.json", "--json", (".json",)).name == "x.json"
    assert check_dir(tmp_path / "a" / "b", "--out") == (tmp_path / "a" / "b").absolute()
    assert list(tmp_path.iterdir()) == []


# ---------------------------------------------------------------- strict, atomic JSON
def test_json_is_strict_nan_and_infinity_become_null(tmp_path):
    obj = {"a": float("nan"), "b": [np.float64("inf"), -np.inf, 1.5],
           "c": np.array([np.nan, 2.0]), "d": np.int64(3), "e": (1, 2)}
    text = dumps(obj)
    assert "NaN" not in text and "Infinity" not in text

    def strict(c):
        raise ValueError(c)
    assert json.loads(text, parse_constant=strict) == {
        "a": None, "b": [None, None, 1.5], "c": [None, 2.0], "d": 3, "e": [1, 2]}
    p = write_json(tmp_path / "x.json", obj)
    assert json.loads(p.read_text(), parse_constant=strict)["a"] is None
    assert [q.name for q in tmp_path.iterdir()] == ["x.json"]    # no temporary left


def test_record_files_are_strict_json(tmp_path):
    rec = TrialRecord(tmp_path, "t")
    rec.add_decision({"belief": [float("nan"), 0.5]})
    rec.finish({"p": float("inf")})
    line = (tmp_path / "t" / "decisions.jsonl").read_text()
    assert "NaN" not in line and json.loads(line)["belief"] == [None, 0.5]
    assert json.loads((tmp_path / "t" / "result.json").read_text()) == {"p": None}


def test_trial_json_has_no_nan(tmp_path):
    out = tmp_path / "t.json"
    assert main(["trial", "--source", "sim", "--quiet", "--rounds", "2", "--json",
                 str(out)]) == 0
    assert "NaN" not in out.read_text()
    json.loads(out.read_text(), parse_constant=lambda c: (_ for _ in ()).throw(ValueError(c)))


# ---------------------------------------------------------------- records: no false success
def _finished(tmp_path: Path, tid: str = "same") -> Path:
    rec = TrialRecord(tmp_path, tid)
    rec.save_inputs(None, {"explorer": {}})
    rec.add_touch(np.zeros((240, 320, 3), np.uint8), {"platform_index": 0})
    rec.finish({"prediction": "c1"})
    return rec.dir


def test_reused_trial_id_refused_and_nothing_overwritten(tmp_path):
    d = _finished(tmp_path)
    before = (d / "result.json").read_bytes()
    with pytest.raises(InputError, match="same"):
        check_new_record(tmp_path, "same")
    with pytest.raises(InputError, match="same"):
        TrialRecord(tmp_path, "same")
    assert (d / "result.json").read_bytes() == before


@pytest.mark.parametrize("tid", ["../../x", "a/b", "..", ""])
def test_trial_id_must_be_a_plain_name(tmp_path, tid):
    with pytest.raises(InputError, match="trial_id"):
        check_new_record(tmp_path, tid)


def test_finished_record_cannot_be_resumed(tmp_path):
    d = _finished(tmp_path)
    with pytest.raises(InputError, match="result"):
        check_resumable(d)


def test_torn_result_json_refused_naming_the_file(tmp_path):
    d = _finished(tmp_path)
    (d / "result.json").write_text('{"prediction": "c')
    with pytest.raises(InputError, match="result.json"):
        check_resumable(d)


def test_empty_touches_with_old_decisions_and_images_refused(tmp_path):
    rec = TrialRecord(tmp_path, "t")
    rec.save_inputs(None, {"explorer": {}})
    for i in range(6):
        rec.add_touch(np.zeros((240, 320, 3), np.uint8), {"platform_index": i % 5,
                                                          "platform_id": f"c{i}"})
    for _ in range(2):
        rec.add_decision({"round": 1})
    check_resumable(rec.dir)                     # consistent: accepted
    (rec.dir / "touches.jsonl").write_text("")   # the touch lines lost, images and decisions kept
    with pytest.raises(InputError, match="decisions.jsonl"):
        check_resumable(rec.dir)
    (rec.dir / "decisions.jsonl").write_text("")
    with pytest.raises(InputError, match="touch_0002"):
        check_resumable(rec.dir)
    with pytest.raises(InputError):
        TrialRecord(tmp_path, "t", resume=True)


def test_an_image_written_just_before_a_crash_is_not_an_orphan(tmp_path):
    rec = TrialRecord(tmp_path, "t")
    rec.save_inputs(None, {"explorer": {}})
    rec.add_touch(np.zeros((240, 320, 3), np.uint8), {"platform_index": 0, "platform_id": "r"})
    cv2.imwrite(str(rec.dir / "touch_0002_c1.png"), np.zeros((240, 320, 3), np.uint8))
    assert check_resumable(rec.dir) is None
    assert TrialRecord(tmp_path, "t", resume=True).n_touches == 2


def test_runner_ignores_a_result_that_was_there_before(tmp_path):
    from tactex_ros.ros.devrun.launcher import _result_stamp, new_result
    d = _finished(tmp_path)
    before = _result_stamp(d / "result.json")
    assert new_result(d / "result.json", before) == (None, None)
    (d / "result.json").unlink()
    TrialRecord(tmp_path, "other").finish({"prediction": "c2"})
    got, why = new_result(tmp_path / "other" / "result.json", None)
    assert got == {"prediction": "c2"} and why is None


def test_runner_names_a_torn_result(tmp_path):
    from tactex_ros.ros.devrun.launcher import new_result
    (tmp_path / "result.json").write_text("{")
    got, why = new_result(tmp_path / "result.json", None)
    assert got is None and "result.json" in why


def test_node_reason_is_the_first_error_line(tmp_path):
    from tactex_ros.ros.devrun.launcher import node_reason
    log = tmp_path / "n.log"
    log.write_text("[INFO] [1.0] [mock_image]: starting\n"
                   "[ERROR] [1.2] [mock_image]: configuration refused: source 'sim:7': bad\n"
                   "[ERROR] [1.3] [mock_image]: later\n")
    assert "sim:7" in node_reason(log) and "later" not in node_reason(log)
    log.write_text("Traceback (most recent call last):\n  File x\nImportError: cannot import\n")
    assert node_reason(log).startswith("ImportError")
    log.write_text("[INFO] [1.0] [x]: fine\n")
    assert node_reason(log) is None


# ---------------------------------------------------------------- accepted although wrong
@pytest.mark.parametrize("argv, named", [
    (["trial", "--source", "sim", "--quiet", "--classes", "denim,denim,felt"], "denim"),
    (["prepare", "--library", "sim", "--frames", "-1", "--out", "x.pt"], "--frames"),
    (["bench", "latency", "--touches", "-5"], "--touches"),
    (["bench", "latency", "--repeats", "0"], "--repeats"),
])
def test_wrong_numbers_and_duplicates_refused(argv, named, capsys, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    try:
        code = main(argv)
    except SystemExit as e:       # argparse refusals
        code = e.code
    assert code == 2
    assert named in capsys.readouterr().err
    assert list(tmp_path.iterdir()) == []


def test_representation_with_a_cnn_config_refused(tmp_path, capsys):
    rep = tmp_path / "rep.pt"
    rep.write_bytes(b"not used")
    assert main(["trial", "--source", "sim", "--quiet", "--config", "cnn",
                 "--representation", str(rep)]) == 2
    assert "representation" in capsys.readouterr().err


def _replay(tmp_path: Path, sizes: dict[str, list[tuple[int, int]]]) -> Path:
    rng = np.random.default_rng(0)
    for cls, shapes in sizes.items():
        (tmp_path / "lib" / cls).mkdir(parents=True)
        for i, (h, w) in enumerate(shapes):
            img = rng.integers(0, 255, (h, w, 3), dtype=np.uint8)
            cv2.imwrite(str(tmp_path / "lib" / cls / f"{i}.png"), img)
    return tmp_path / "lib"


@pytest.mark.parametrize("shape", [(12, 16), (1, 1), (239, 320)])
def test_presses_smaller_than_the_sensor_frame_refused(tmp_path, capsys, shape):
    lib = _replay(tmp_path, {c: [shape] * 3 for c in ("a", "b", "c", "d")})
    assert main(["trial", "--source", f"replay:{lib}", "--quiet", "--comparisons", "2",
                 "--json", str(tmp_path / "t.json")]) == 2
    err = capsys.readouterr().err
    assert f"{shape[1]}x{shape[0]}" in err and "0.png" in err
    assert not (tmp_path / "t.json").exists()


def test_larger_presses_are_shrunk_not_refused(tmp_path):
    lib = _replay(tmp_path, {c: [(480, 640)] * 3 for c in ("a", "b", "c")})
    assert main(["trial", "--source", f"replay:{lib}", "--quiet", "--comparisons", "2",
                 "--rounds", "2", "--json", str(tmp_path / "t.json")]) == 0


def test_a_press_damaged_after_the_source_opened_is_a_failed_touch(tmp_path):
    """A damaged file is refused when the source opens (test/unit/sources/
    test_replay_files.py); one damaged later (while a trial runs) fails the touch that draws
    it, named, and the engine draws another press."""
    from tactex_ros.core.engine import TouchFailed
    from tactex_ros.sources.replay import ReplaySource
    lib = _replay(tmp_path, {c: [(240, 320)] * 4 for c in ("a", "b", "c")})
    src = ReplaySource(lib)
    trial = src.trial(["a", "b", "c"], seed=0)
    for f in src.presses("a"):
        f.write_bytes(b"")                       # every press of class a, after the open
    failed = []
    for _ in range(4):
        try:
            trial(0)
        except TouchFailed as exc:
            failed.append(str(exc))
    assert len(failed) >= 3 and all("a/" in f and ".png" in f for f in failed), failed
    assert trial(1).frame.shape == (240, 320, 3)          # the other classes go on


def test_record_with_a_missing_image_refused_up_front(tmp_path):
    rec = TrialRecord(tmp_path, "t")
    rec.save_inputs(None, {"explorer": {}})
    path = rec.add_touch(np.zeros((240, 320, 3), np.uint8), {"platform_index": 0,
                                                             "platform_id": "reference"})
    path.unlink()
    with pytest.raises(InputError, match=path.name):
        check_resumable(rec.dir)


@pytest.mark.parametrize("spec, named", [("sim:7", "sim:7"), ("replay:/nonexistent/x", "x"),
                                         ("sim:a:b", "sim:a:b"), ("camera", "camera")])
def test_bad_source_spec_named(spec, named):
    from tactex_ros.sources import open_source
    with pytest.raises(InputError, match=named):
        open_source(spec)


@pytest.mark.parametrize("what", ["empty_folder", "text_file", "png_file"])
def test_graph_summary_refuses_what_is_not_a_record(tmp_path, capsys, what):
    target = tmp_path / what
    if what == "empty_folder":
        target.mkdir()
    elif what == "text_file":
        target.write_text("hello\n")
    else:
        cv2.imwrite(str(target.with_suffix(".png")), np.zeros((4, 4, 3), np.uint8))
        target = target.with_suffix(".png")
    assert main(["graph", "summary", str(target)]) == 2
    assert str(target) in capsys.readouterr().err


def test_idle_deadline_counts_from_the_last_progress(tmp_path):
    from tactex_ros.ros.devrun.launcher import Deadlines
    now = [0.0]
    d = Deadlines(tmp_path, None, 100.0, clock=lambda: now[0])
    for _ in range(10):                  # a decision every 90 s: 900 s in all, never idle
        now[0] += 90.0
        with open(tmp_path / "decisions.jsonl", "a") as f:
            f.write("{}\n")
        assert d.expired() is None
    now[0] += 101.0                      # then nothing for 101 s
    assert "100" in d.expired()
    total = Deadlines(tmp_path, 50.0, 100.0, clock=lambda: now[0])
    now[0] += 51.0
    assert "50" in total.expired()


def test_idle_deadline_waits_for_an_explorer_that_is_working(tmp_path):
    """A decision longer than the idle deadline (the thesis CNN on a loaded machine) is not
    idle while the explorer uses CPU; a stopped explorer (no CPU) is, after idle_s."""
    from tactex_ros.ros.devrun.launcher import BUSY_WINDOW_S, Deadlines, process_cpu_s
    now, cpu = [0.0], [0.0]
    d = Deadlines(tmp_path, None, 100.0, clock=lambda: now[0], cpu=lambda: cpu[0])
    for _ in range(20):                  # 600 s of training at a third of a core, no new line
        now[0] += BUSY_WINDOW_S
        cpu[0] += BUSY_WINDOW_S / 3
        assert d.expired() is None
    for _ in range(3):                   # then SIGSTOP: no CPU, no line
        now[0] += BUSY_WINDOW_S
        assert d.expired() is None       # 90 s
    now[0] += BUSY_WINDOW_S
    assert "100" in d.expired()          # 120 s without progress
    idle = Deadlines(tmp_path, None, 100.0, clock=lambda: now[0], cpu=lambda: cpu[0])
    for _ in range(4):                   # a 10 ms poll loop: 2 % of a core is not work
        now[0] += BUSY_WINDOW_S
        cpu[0] += 0.02 * BUSY_WINDOW_S
    assert "100" in idle.expired()
    assert process_cpu_s(os.getpid()) > 0
    with pytest.raises(OSError):
        process_cpu_s(2 ** 22 + 7)       # no such process
