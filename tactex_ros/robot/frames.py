"""The sensor's recent frames: a ring of stamped frames that finds the strongest contact of a
time window against the no-contact frame, and the burst of consecutive in-contact frames around
it (scores and the in-contact rule from ``core.contact``, the replay source's). No ROS: the
GelSight node and the mock image node push frames into it and answer capture requests from
it."""

from __future__ import annotations

import numpy as np

from ..core.contact import blur, burst_indices, contact_score


class FrameRing:
    """The last ``capacity`` sensor frames with their stamps [s], and a no-contact reference.

    ``best(window_s, now)`` returns the strongest-contact frame of the frames stamped within
    ``window_s`` before ``now`` (the whole buffer when ``window_s <= 0``) and its contact score
    [grey levels] against the reference; ``burst(window_s, now, count)`` that frame and its
    consecutive in-contact neighbours (``core.contact.burst_indices``), at the sensor's frame
    rate. Used by the GelSight node and the mock image node.
    """

    def __init__(self, capacity: int = 60) -> None:
        if capacity < 1:
            raise ValueError(f"capacity must be >= 1, got {capacity}")
        self.capacity = capacity
        self._frames: list[tuple[float, np.ndarray]] = []
        self.reference: np.ndarray | None = None
        self._ref_blur: np.ndarray | None = None

    def __len__(self) -> int:
        return len(self._frames)

    def set_reference(self, frame: np.ndarray) -> None:
        """Set the no-contact frame (240, 320, 3) uint8."""
        self.reference = frame.copy()
        self._ref_blur = blur(frame)

    def push(self, stamp: float, frame: np.ndarray) -> None:
        self._frames.append((stamp, frame))
        if len(self._frames) > self.capacity:
            del self._frames[0]

    def best(self, window_s: float, now: float) -> tuple[np.ndarray, float]:
        """Strongest-contact frame in the window and its score; ValueError if none/no reference."""
        frames, score = self.burst(window_s, now, 1)
        return frames[0][1], score

    def burst(self, window_s: float, now: float,
              count: int) -> tuple[list[tuple[float, np.ndarray]], float]:
        """Up to ``count`` consecutive (stamp [s], frame) of the window: the strongest-contact
        frame first, then its in-contact neighbours in time order
        (``core.contact.burst_indices``), and the strongest's contact score [grey levels];
        ValueError if no frame / no reference."""
        if self._ref_blur is None:
            raise ValueError("no no-contact reference frame yet")
        frames = [(t, f) for t, f in self._frames if window_s <= 0 or t >= now - window_s]
        if not frames:
            raise ValueError(f"no frame in the last {window_s:.2f} s")
        scores = [contact_score(f, self._ref_blur) for _, f in frames]
        pick = burst_indices(np.array(scores), count)
        return [frames[i] for i in pick], float(scores[pick[0]])
