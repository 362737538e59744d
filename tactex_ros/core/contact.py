"""Contact detection on GelSight frames: which frame of a press shows the strongest contact.

Contact changes a GelSight Mini frame by only a few grey levels on average, so the score is
computed on blurred frames (sensor noise averages out) against a no-contact reference frame:
score = mean |blur(frame) - blur(reference)| over pixels and channels, in grey levels.
Used by the replay source (per recorded press) and by the sensor's frame ring
(``robot/frames.py``).

"In contact" is one rule for both: a frame whose score is at least ``CONTACT_SHARE`` of the
press's strongest (``in_contact``). The replay source keeps up to ``EXTRA_FRAMES`` such frames
of a recorded press besides the strongest; the ring's burst (``burst_indices``) returns the
strongest and its consecutive in-contact neighbours.
"""

from __future__ import annotations

import cv2
import numpy as np

from .errors import InputError
from .touch import FRAME_H, FRAME_W

_BLUR = (5, 5)
EXTRA_FRAMES = 3       # in-contact frames of a press kept besides the strongest (replay, burst)
CONTACT_SHARE = 0.7    # in contact: at least this share of the press's strongest contact score


def blur(frame: np.ndarray) -> np.ndarray:
    """float32 Gaussian-blurred copy of a uint8 frame."""
    return cv2.GaussianBlur(frame, _BLUR, 0).astype(np.float32)


def contact_score(frame: np.ndarray, reference_blurred: np.ndarray,
                  drift_robust: bool = False) -> float:
    """Mean absolute difference (grey levels) of a blurred (H, W, 3) uint8 frame to a blurred
    (float32) reference; ``drift_robust``: the per-channel mean difference is removed first, so
    a lighting drift does not count as contact."""
    d = blur(frame) - reference_blurred
    if drift_robust:
        d -= d.reshape(-1, d.shape[-1]).mean(axis=0)
    return float(np.abs(d).mean())


def contact_scores(frames: np.ndarray, reference: np.ndarray | None = None) -> np.ndarray:
    """(F, H, W, 3) frames -> (F,) contact scores. Reference: median of the first 3 frames."""
    if reference is None:
        reference = np.median(frames[:3], axis=0).astype(np.uint8)
    ref = blur(reference)
    return np.array([contact_score(f, ref) for f in frames])


def strongest_contact(frames: np.ndarray, reference: np.ndarray | None = None,
                      smooth: int = 3) -> tuple[int, np.ndarray]:
    """Index of the strongest-contact frame and the (F,) scores.

    Scores are smoothed over ``smooth`` consecutive frames before the argmax so a single noisy
    frame cannot win; the returned index is the best raw frame inside the best window.
    """
    s = contact_scores(frames, reference)
    if smooth > 1 and len(s) >= smooth:
        k = np.ones(smooth) / smooth
        sm = np.convolve(s, k, mode="same")
        c = int(np.argmax(sm))
        lo, hi = max(0, c - smooth // 2), min(len(s), c + smooth // 2 + 1)
        return lo + int(np.argmax(s[lo:hi])), s
    return int(np.argmax(s)), s


def in_contact(scores: np.ndarray, best: int) -> np.ndarray:
    """(F,) bool: the frames whose contact score is at least ``CONTACT_SHARE`` of frame
    ``best``'s (the press's strongest); ``scores``: (F,) contact scores [grey levels]."""
    s = np.asarray(scores, dtype=float)
    return s >= CONTACT_SHARE * s[best]


def burst_indices(scores: np.ndarray, count: int) -> list[int]:
    """A burst of up to ``count`` consecutive frames around the strongest contact.

    ``scores``: (F,) contact scores of consecutive frames [grey levels]. Returns indices into
    them: the strongest frame (raw argmax; the first on a tie) first, then its in-contact
    neighbours (``in_contact``) in time order, taken from the unbroken run of in-contact frames
    around it, as centred on it as the run allows (an even count: one more frame before it).
    Fewer than ``count`` when the run is shorter; ``count <= 1``: the strongest alone."""
    s = np.asarray(scores, dtype=float)
    if s.ndim != 1 or len(s) == 0:
        raise ValueError(f"burst_indices: need a non-empty (F,) score vector, got {s.shape}")
    best = int(np.argmax(s))
    mask = in_contact(s, best)
    lo, hi = best, best + 1                 # the unbroken in-contact run [lo, hi)
    while lo > 0 and mask[lo - 1]:
        lo -= 1
    while hi < len(s) and mask[hi]:
        hi += 1
    n = max(1, min(int(count), hi - lo))
    start = min(max(lo, best - n // 2), hi - n)
    return [best] + [i for i in range(start, start + n) if i != best]


def to_sensor_frame(img: np.ndarray) -> np.ndarray:
    """An (H, W, 3) uint8 frame -> (240, 320, 3): a portrait frame (H > W, e.g. another
    GelSight's 300 x 400) is first turned a quarter clockwise to landscape; then centre-crop to
    4:3 and shrink. A frame still smaller than the sensor's is refused (InputError): up-scaling
    would invent the texture the classifier judges."""
    h, w = img.shape[:2]
    if (h, w) == (FRAME_H, FRAME_W):
        return img
    if h > w:                                   # portrait: the sensor's long side is W
        img = cv2.rotate(img, cv2.ROTATE_90_CLOCKWISE)   # as the sensor node's ``landscape``
        h, w = w, h
    if h < FRAME_H or w < FRAME_W:
        raise InputError(f"frame of {w}x{h} px (landscape) is smaller than the sensor frame "
                          f"{FRAME_W}x{FRAME_H} px (not up-scaled)")
    target = FRAME_W / FRAME_H
    if w / h > target:
        nw = int(round(h * target))
        img = img[:, (w - nw) // 2:(w - nw) // 2 + nw]
    elif w / h < target:
        nh = int(round(w / target))
        img = img[(h - nh) // 2:(h - nh) // 2 + nh]
    return cv2.resize(img, (FRAME_W, FRAME_H), interpolation=cv2.INTER_AREA)


def crop_border(frame: np.ndarray, fraction: float) -> np.ndarray:
    """Crop ``fraction`` of each border (the GelSight Mini's dark rim), resize to (240, 320)."""
    if not 0.0 <= fraction < 0.5:
        raise ValueError(f"crop fraction {fraction} outside [0, 0.5)")
    h, w = frame.shape[:2]
    dy, dx = int(round(h * fraction)), int(round(w * fraction))
    inner = frame[dy:h - dy, dx:w - dx]
    return cv2.resize(inner, (FRAME_W, FRAME_H), interpolation=cv2.INTER_AREA)
