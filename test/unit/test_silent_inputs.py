"""Issue 49, item 7: inputs that were silently accepted (a run went on with a value that means
nothing, or with another one than given) are refused: a clear error naming the input and the
values it may take, exit status 2 on the command line (``InputError`` from the API)."""

from __future__ import annotations

from pathlib import Path
from collections.abc import Callable

import cv2
import numpy as np
import pytest
import yaml

from tactex_ros.cli.main import main
from tactex_ros.core.errors import InputError
from tactex_ros.core.paths import config_dir

SESSION = str(Path(__file__).parents[1] / "data" / "session_short.yaml")


def cli(argv: list[str]) -> int:
    """``tactex ARGV``'s exit status (argparse's refusals included)."""
    try:
        return main(argv)
    except SystemExit as e:
        return int(e.code)


def api(fn: Callable[[], object]) -> int:
    """2 when ``fn`` raises InputError (its message printed as the command line would)."""
    try:
        fn()
    except InputError as exc:
        print(f"tactex: error: {exc}", file=__import__("sys").stderr)
        return 2
    return 0


def _images(root: Path, classes: int = 3, presses: int = 2) -> Path:
    rng = np.random.default_rng(0)
    for k in range(classes):
        (root / "lib" / f"f{k}").mkdir(parents=True)
        for i in range(presses):
            cv2.imwrite(str(root / "lib" / f"f{k}" / f"{i}.png"),
                        rng.integers(0, 255, (240, 320, 3), dtype=np.uint8))
    return root / "lib"


def garbled_video(tmp: Path) -> tuple[int, list[str]]:
    """30 frames of moving stripes (MPEG-4), a quarter of its bytes overwritten from a third
    of the way in: 12 frames decode (as test/unit/sources/test_replay_files.py)."""
    lib = _images(tmp)
    bad = lib / "f1" / "2.mp4"
    w = cv2.VideoWriter(str(bad), cv2.VideoWriter_fourcc(*"mp4v"), 25, (320, 240))
    x = np.arange(320)
    for i in range(30):
        row = 127 + 100 * np.sin(2 * np.pi * (x + i) / 9)
        w.write(np.repeat(row[None, :, None], 240, 0).repeat(3, 2).astype(np.uint8))
    w.release()
    data = bytearray(bad.read_bytes())
    n = len(data)
    data[n // 3:n // 3 + n // 4] = np.random.default_rng(1).integers(
        0, 256, n // 4, dtype=np.uint8).tobytes()
    bad.write_bytes(bytes(data))
    return cli(["trial", "--source", f"replay:{lib}", "--quiet", "--comparisons", "2"]), \
        [str(bad), "garbled or cut", "12 of the 30 frames"]


def thresholds(tmp: Path, value: str) -> tuple[int, list[str]]:
    pytest.importorskip("tactex_lab")
    return cli(["experiment", "real", "--source", "replay:x", "--thresholds", "0.9", value,
                "--out", str(tmp / "out")]), [f"--thresholds {value}", "0..1.01"]


def press_s(tmp: Path) -> tuple[int, list[str]]:
    pytest.importorskip("tactex_lab")
    bench = tmp / "bench.json"
    bench.write_text('{"press_s_median": -1}')
    return cli(["experiment", "real", "--source", "replay:x", "--press-time", str(bench),
                "--out", str(tmp / "out")]), ["--press-time", str(bench), "0.1..3600"]


def ladder_rung(tmp: Path) -> tuple[int, list[str]]:
    return cli(["trial", "--source", "sim", "--quiet", "--model", "auto", "--rounds", "1",
                "--set", "learner.ladder=descriptor+representation+descriptor"]), \
        ["ladder", "'descriptor' given twice"]


def cnn_ladder_rung(tmp: Path) -> tuple[int, list[str]]:
    from tactex_ros.core.ladder import parse_cnn_rungs
    return api(lambda: parse_cnn_rungs("small_inception@48,small_inception", 48)), \
        ["auto_ladder", "'small_inception@48' given twice"]


def platforms_at_one_position(tmp: Path) -> tuple[int, list[str]]:
    scene = yaml.safe_load((config_dir() / "scene_sim.yaml").read_text())
    scene["platforms"][3]["position"] = list(scene["platforms"][1]["position"])
    bad = tmp / "scene.yaml"
    bad.write_text(yaml.safe_dump(scene))
    return cli(["graph", "describe", "--sim", "--scene", str(bad)]), \
        ["platforms.3.position", f"overlaps platform {scene['platforms'][1]['id']!r}"]


def temperature_inf(tmp: Path) -> tuple[int, list[str]]:
    from tactex_ros.core import representation as rp
    rng = np.random.default_rng(0)
    r = rp.fit({f"f{k}": rng.normal(size=(4, rp.DIM)) for k in range(3)})
    p = rp.save(r, tmp / "rep.npz")
    with np.load(p) as z:
        d = {k: z[k] for k in z.files}
    d["temperature"] = np.array(np.inf)
    np.savez(p, **d)
    return cli(["trial", "--source", "sim", "--quiet", "--representation", str(p)]), \
        [str(p), "temperature inf", "must be > 0 and finite"]


def trial_id(tmp: Path, tid: str) -> tuple[int, list[str]]:
    return cli(["graph", "run", "--sim", "--record-dir", str(tmp / "rec"), "--trial-id", tid,
                "--log-dir", str(tmp / "logs")]), ["trial_id", repr(tid)]


def trial_file_id(tmp: Path, tid: str) -> tuple[int, list[str]]:
    doc = yaml.safe_load(Path(SESSION).read_text())
    doc["trials"][1]["id"] = tid
    f = tmp / "trials.yaml"
    f.write_text(yaml.safe_dump(doc))
    return cli(["graph", "describe", "--sim", "--session", str(f)]), \
        ["entry 2", repr(tid), "plain name"]


def trials_comma(tmp: Path) -> tuple[int, list[str]]:
    return cli(["graph", "describe", "--sim", "--session", SESSION, "--trials", ","]), \
        ["trials ','", "empty id", "its ids: 1, 2"]


def prepare_frames(tmp: Path) -> tuple[int, list[str]]:
    lib = _images(tmp)
    return cli(["prepare", "--library", f"replay:{lib}", "--frames", "16", "--calibration",
                "off", "--out", str(tmp / "rep.npz")]), ["--frames 16", "at most 1",
                                                        "--frames 1..1"]


def _env(tmp: Path):
    pytest.importorskip("gymnasium")
    from tactex_lab.env.touch_env import TouchEnv
    return TouchEnv(f"replay:{_images(tmp, classes=3, presses=2)}", comparisons=2, budget=1)


def env_float_action(tmp: Path) -> tuple[int, list[str]]:
    env = _env(tmp)
    env.reset(seed=1)
    return api(lambda: env.step({"action": 1.7, "prediction": np.zeros(2)})), \
        ["action 1.7", "an integer 0..3", "float"]


def env_nan_prediction(tmp: Path) -> tuple[int, list[str]]:
    env = _env(tmp)
    env.reset(seed=1)
    return api(lambda: env.step({"action": 3, "prediction": np.full(2, np.nan)})), \
        ["prediction", "NaN"]


def env_big_seed(tmp: Path) -> tuple[int, list[str]]:
    env = _env(tmp)
    return api(lambda: env.reset(seed=2**31)), ["seed 2147483648", "0..2147483647"]


CASES = {
    "garbled_video": garbled_video,
    "thresholds_5": lambda t: thresholds(t, "5"),
    "thresholds_-1": lambda t: thresholds(t, "-1"),
    "press_s_-1": press_s,
    "duplicate_ladder_rung": ladder_rung,
    "duplicate_cnn_ladder_rung": cnn_ladder_rung,
    "two_platforms_at_one_position": platforms_at_one_position,
    "temperature_inf": temperature_inf,
    "trial_id_newline": lambda t: trial_id(t, "a\nb"),
    "trial_id_space": lambda t: trial_id(t, " "),
    "trial_file_id_newline": lambda t: trial_file_id(t, "a\nb"),
    "trial_file_id_space": lambda t: trial_file_id(t, " "),
    "trials_comma": trials_comma,
    "prepare_frames_16_on_images": prepare_frames,
    "env_float_action": env_float_action,
    "env_all_nan_prediction": env_nan_prediction,
    "env_seed_above_2_31": env_big_seed,
}


@pytest.mark.parametrize("case", CASES, ids=list(CASES))
def test_silently_accepted_input_is_refused_naming_it(tmp_path: Path, capsys, monkeypatch,
                                                      case: str) -> None:
    monkeypatch.chdir(tmp_path)
    code, words = CASES[case](tmp_path)
    err = capsys.readouterr().err
    assert code == 2, err[-2000:]
    for w in words:
        assert w in err, (w, err[-2000:])
    assert "Traceback" not in err
    assert not (tmp_path / "logs").exists() and not (tmp_path / "rec").exists()
