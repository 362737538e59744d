"""The sensor's frame ring (robot/frames.py): the strongest contact of a time window."""

from __future__ import annotations

import numpy as np
import pytest

from tactex_ros.core.contact import CONTACT_SHARE, burst_indices, in_contact
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


@pytest.mark.parametrize("scores, count, want", [
    # the strongest (index 4) and its neighbours, centred; an even count takes one more before
    ([0, 0, 8, 9, 10, 9, 8, 0], 3, [4, 3, 5]),
    ([0, 0, 8, 9, 10, 9, 8, 0], 4, [4, 2, 3, 5]),
    ([0, 0, 8, 9, 10, 9, 8, 0], 5, [4, 2, 3, 5, 6]),
    # the run of in-contact frames (>= 0.7 x 10) ends the burst: 6.9 is out, so is all after it
    ([8, 6.9, 9, 10, 7, 7, 8], 4, [3, 2, 4, 5]),
    ([8, 6.9, 9, 10, 7, 6, 8], 4, [3, 2, 4]),
    # the strongest at the run's edge: the burst shifts inside the run
    ([10, 9, 8, 7.5, 0], 3, [0, 1, 2]),
    ([0, 7, 8, 10], 3, [3, 1, 2]),
    # a tie: the first strongest; one frame; count <= 1
    ([5, 5, 5], 2, [0, 1]),
    ([3], 4, [0]),
    ([0, 9, 10, 9], 1, [2]),
])
def test_burst_indices(scores: list[float], count: int, want: list[int]) -> None:
    assert burst_indices(np.array(scores, float), count) == want


def test_burst_uses_the_replay_sources_in_contact_rule() -> None:
    scores = np.array([0.0, 6.99, 7.0, 10.0, 7.0, 6.99])
    assert list(np.flatnonzero(in_contact(scores, 3))) == [2, 3, 4] == \
        sorted(burst_indices(scores, 10))
    assert CONTACT_SHARE == 0.7


def test_frame_ring_burst_returns_consecutive_in_contact_frames() -> None:
    rng = np.random.default_rng(1)
    base = rng.integers(90, 110, (240, 320, 3), dtype=np.uint8)
    ring = FrameRing(capacity=20)
    ring.set_reference(base)
    levels = [0, 0, 2, 20, 30, 40, 36, 32, 28, 4, 0, 0]     # a press seen at 1 frame per stamp
    for k, v in enumerate(levels):
        f = base.copy()
        f[60:180, 80:240] += np.uint8(v)
        ring.push(float(k), f)
    frames, score = ring.burst(0.0, 11.0, 4)
    got = [int(f[120, 160, 0]) - int(base[120, 160, 0]) for _, f in frames]
    assert got == [40, 30, 36, 32]        # strongest first, then frames 4, 6, 7 in time order
    assert [t for t, _ in frames] == [5.0, 4.0, 6.0, 7.0]
    best, s1 = ring.best(0.0, 11.0)
    assert s1 == score and np.array_equal(best, frames[0][1])
    # the window holds only the last 3 s (stamps 8..11): frame 8 is the strongest there
    frames, _ = ring.burst(3.0, 11.0, 4)
    assert [int(f[120, 160, 0]) - int(base[120, 160, 0]) for _, f in frames] == [28]
