"""Issue 49, item 3: every press file of a replay folder is judged when the source opens. A
zero-byte, undecodable, garbled or cut file refuses the source with the file named (InputError:
exit status 2 on the command line), instead of failing the touches that draw it; whole files
of every kind pass."""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np
import pytest

from tactex_ros.cli.main import main
from tactex_ros.core.errors import InputError
from tactex_ros.sources import open_source
from tactex_ros.sources.replay import ReplaySource, read_video


def stripes_video(path: Path, frames: int = 30) -> Path:
    """A small MPEG-4 video of moving stripes (sensor-sized)."""
    w = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*"mp4v"), 25, (320, 240))
    x = np.arange(320)
    for i in range(frames):
        row = 127 + 100 * np.sin(2 * np.pi * (x + i) / 9)
        w.write(np.repeat(row[None, :, None], 240, 0).repeat(3, 2).astype(np.uint8))
    w.release()
    return path


def garble(path: Path) -> Path:
    """Overwrite a quarter of the file's bytes from a third of the way in (a damaged copy)."""
    data = bytearray(path.read_bytes())
    n = len(data)
    data[n // 3:n // 3 + n // 4] = np.random.default_rng(1).integers(
        0, 256, n // 4, dtype=np.uint8).tobytes()
    path.write_bytes(bytes(data))
    return path


def library(root: Path) -> Path:
    """Three classes of two whole presses each: a video and an image."""
    rng = np.random.default_rng(0)
    for cls in ("a", "b", "c"):
        d = root / "lib" / cls
        d.mkdir(parents=True)
        stripes_video(d / "0.mp4")
        cv2.imwrite(str(d / "1.png"), rng.integers(0, 255, (240, 320, 3), dtype=np.uint8))
    return root / "lib"


DAMAGE = {
    "zero_bytes": lambda p: p.write_bytes(b""),
    "garbled_middle": garble,
    "cut_in_half": lambda p: p.write_bytes(p.read_bytes()[:len(p.read_bytes()) // 2]),
    "not_a_video": lambda p: p.write_bytes(b"not a video at all" * 100),
}


def test_whole_presses_of_every_kind_open(tmp_path: Path) -> None:
    src = open_source(f"replay:{library(tmp_path)}")
    assert src.classes == ["a", "b", "c"]
    assert read_video(tmp_path / "lib" / "a" / "0.mp4").shape == (30, 240, 320, 3)


@pytest.mark.parametrize("damage", DAMAGE, ids=list(DAMAGE))
def test_a_damaged_press_refuses_the_source_naming_it(tmp_path: Path, damage: str) -> None:
    lib = library(tmp_path)
    bad = lib / "b" / "0.mp4"
    DAMAGE[damage](bad)
    with pytest.raises(InputError) as err:
        ReplaySource(lib)
    assert str(bad) in str(err.value) and "1 of 6" in str(err.value)


def test_a_damaged_image_refuses_the_source(tmp_path: Path) -> None:
    lib = library(tmp_path)
    (lib / "c" / "1.png").write_bytes(b"\x89PNG\r\n\x1a\n" + b"\0" * 40)
    with pytest.raises(InputError, match="1.png"):
        ReplaySource(lib)


def test_a_garbled_video_is_not_replayed_from_its_first_frames(tmp_path: Path) -> None:
    """Read alone, a garbled video is refused too: 12 of its 30 frames decode."""
    bad = garble(stripes_video(tmp_path / "g.mp4"))
    with pytest.raises(InputError, match="of the 30 frames"):
        read_video(bad)


def test_trial_on_a_folder_with_a_zero_byte_press_is_refused_before_any_touch(
        tmp_path: Path, capsys) -> None:
    """Was: exit 0, the zero-byte file a failed touch of each trial that drew it."""
    lib = library(tmp_path)
    (lib / "a" / "2.mov").write_bytes(b"")
    out = tmp_path / "t.json"
    assert main(["trial", "--source", f"replay:{lib}", "--quiet", "--comparisons", "2",
                 "--rounds", "3", "--json", str(out)]) == 2
    err = capsys.readouterr().err
    assert str(lib / "a" / "2.mov") in err and "empty (0 bytes)" in err
    assert not out.exists()
