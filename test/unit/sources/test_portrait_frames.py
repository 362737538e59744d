"""Frames of another shape: a portrait recording (another GelSight's 300 x 400) is turned to the
sensor's landscape and cropped/shrunk (``core.contact.to_sensor_frame``), so `tactex trial` runs
it; a frame still too small after turning is refused by name (exit 2)."""

from pathlib import Path

import cv2
import numpy as np
import pytest

from tactex_ros.cli.main import main
from tactex_ros.core.contact import to_sensor_frame
from tactex_ros.core.errors import InputError


def test_portrait_frame_turned_to_landscape():
    rng = np.random.default_rng(1)
    img = rng.integers(0, 255, (400, 300, 3), dtype=np.uint8)      # H 400 > W 300
    out = to_sensor_frame(img)
    assert out.shape == (240, 320, 3)
    # the turned frame is 300 x 400 (H x W), 4:3 already: only shrunk, so it equals the
    # clockwise turn shrunk; its top-left pixel block comes from the portrait's bottom-left
    want = cv2.resize(cv2.rotate(img, cv2.ROTATE_90_CLOCKWISE), (320, 240),
                      interpolation=cv2.INTER_AREA)
    assert np.array_equal(out, want)
    assert not np.array_equal(out, cv2.resize(img[50:350], (320, 240),
                                              interpolation=cv2.INTER_AREA))
    with pytest.raises(InputError, match="200x150"):
        to_sensor_frame(np.zeros((200, 150, 3), np.uint8))          # portrait, too small


def _folder(root: Path, shape: tuple[int, int]) -> Path:
    rng = np.random.default_rng(0)
    for k, cls in enumerate("abcd"):
        (root / cls).mkdir(parents=True)
        for i in range(3):
            img = np.clip(rng.normal(60 + 40 * k, 30, (*shape, 3)), 0, 255).astype(np.uint8)
            cv2.imwrite(str(root / cls / f"{i}.png"), img)
    return root


def test_trial_runs_portrait_presses(tmp_path):
    lib = _folder(tmp_path / "lib", (400, 300))
    assert main(["trial", "--source", f"replay:{lib}", "--quiet", "--comparisons", "2",
                 "--rounds", "2", "--set", "learner.guards=false",
                 "--record-dir", str(tmp_path / "rec"), "--json", str(tmp_path / "t.json")]) == 0
    assert (tmp_path / "t.json").is_file()


def test_trial_refuses_unusable_portrait_presses_by_name(tmp_path, capsys):
    lib = _folder(tmp_path / "lib", (300, 200))
    assert main(["trial", "--source", f"replay:{lib}", "--quiet", "--comparisons", "2",
                 "--record-dir", str(tmp_path / "rec")]) == 2
    err = capsys.readouterr().err
    assert "300x200" in err and "0.png" in err
