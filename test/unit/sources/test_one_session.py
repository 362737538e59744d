"""``replay:DIR:one-session``: recorded presses moved onto one background per trial."""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np
import pytest

from tactex_ros.core.errors import InputError
from tactex_ros.core.touch import Touch
from tactex_ros.sources import open_source
from tactex_ros.sources.replay import rebase


def _video(path: Path, level: int, seed: int) -> None:
    """A press video: 3 no-contact frames at grey ``level`` (+ a fixed pattern), then 4
    frames with a +/-20 checker pressed in, then 2 without."""
    rng = np.random.default_rng(seed)
    base = np.clip(level + rng.integers(-3, 4, (240, 320, 3)), 0, 255).astype(np.uint8)
    yy, xx = np.mgrid[0:240, 0:320]
    checker = np.where(((yy // 10) + (xx // 10)) % 2 == 0, 20, -20)[..., None]
    contact = np.clip(base.astype(int) + checker, 0, 255).astype(np.uint8)
    w = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*"MJPG"), 25, (320, 240))
    for f in [base] * 3 + [contact] * 4 + [base] * 2:
        w.write(f)
    w.release()


@pytest.fixture()
def folder(tmp_path: Path) -> Path:
    for k, (cls, level) in enumerate((("a", 60), ("b", 120), ("c", 180))):
        (tmp_path / cls).mkdir()
        for i in range(2):
            _video(tmp_path / cls / f"{i}.avi", level, 10 * k + i)
    return tmp_path


def test_rebase_moves_every_frame_onto_the_background():
    nc = np.full((240, 320, 3), 100, np.uint8)
    frame = nc.copy()
    frame[:10] = 140
    extra = np.stack([nc + 5, nc + 250 - 100])           # the second one saturates
    bg = np.full((240, 320, 3), 30, np.uint8)
    t = rebase(Touch(frame=frame, no_contact=nc, extra=extra), bg)
    assert t.frame[0, 0, 0] == 70 and t.frame[20, 0, 0] == 30
    np.testing.assert_array_equal(t.no_contact, bg)
    assert t.extra[0, 0, 0, 0] == 35 and t.extra[1, 0, 0, 0] == 180
    plain = Touch(frame=frame)
    assert rebase(plain, bg) is plain


def test_one_session_trial_shares_the_first_touch_background(folder):
    raw = open_source(f"replay:{folder}")
    one = open_source(f"replay:{folder}:one-session")
    assert one.one_session and not raw.one_session and one.classes == ["a", "b", "c"]
    classes = ["b", "a", "c", "b"]
    rt, ot = raw.trial(classes, seed=1), one.trial(classes, seed=1)
    r = [rt(p) for p in (0, 1, 2, 3)]
    o = [ot(p) for p in (0, 1, 2, 3)]
    # raw: each class's own background level; one session: every touch on class b's
    levels = [float(t.no_contact.mean()) for t in r]
    np.testing.assert_allclose(levels, [120, 60, 180, 120], atol=2)   # (video compression)
    for t in o:
        np.testing.assert_array_equal(t.no_contact, o[0].no_contact)
        assert abs(float(t.frame.mean()) - 120) < 2
    # the contact pattern is kept: contact minus no contact equal in both
    for a, b in zip(r, o, strict=True):
        da = a.frame.astype(int) - a.no_contact
        db = b.frame.astype(int) - b.no_contact
        assert np.abs(da - db).mean() < 0.5


def test_bad_replay_spec_named():
    with pytest.raises(InputError, match="needs a folder"):
        open_source("replay::one-session")
