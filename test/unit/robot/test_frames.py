"""The sensor's frame ring (robot/frames.py): the strongest contact of a time window."""

from __future__ import annotations

import numpy as np
import pytest

from tactex_ros.robot.frames import FrameRing


def test_frame_ring_picks_strongest_contact() -> None:
    rng = np.random.default_rng(0)
    base = rng.integers(90, 110, (240, 320, 3), dtype=np.uint8)
    ring = FrameRing(capacity=5)
    with pytest.raises(ValueError):
        ring.best(0.0, 0.0)
    ring.set_reference(base)
    for k in range(8):
        f = base.copy()
        f[100:140, 100:140] += np.uint8(5 * k % 40)
        ring.push(float(k), f)
    assert len(ring) == 5
    frame, score = ring.best(0.0, 7.0)
    assert int(frame[120, 120, 0]) - int(base[120, 120, 0]) == 35
    # +35 grey levels on 40 x 40 of 240 x 320 pixels: mean |difference| 35 * 1600 / 76800
    # (the blur keeps the sum away from the border; it rounds to whole grey levels)
    assert score == pytest.approx(35 * 1600 / 76800, abs=0.02)
    with pytest.raises(ValueError):
        ring.best(0.5, 100.0)
