"""What one touch delivers: the contact frame, the sensor's no-contact frame, more contact frames.

Every touch source returns a ``Touch``: the replay source (a press video holds its no-contact
frames at the start and tens of in-contact frames), the simulator (it renders the same sensor
without contact) and the ROS explorer (``tactex/Touch`` carries ``no_contact_image``). Frames are
uint8 RGB (240, 320, 3). A bare frame (numpy array) is accepted wherever a Touch is, as a touch
without a no-contact frame.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .errors import InputError

FRAME_H, FRAME_W = 240, 320            # GelSight Mini frame [px]


@dataclass(frozen=True)
class Touch:
    """One press of one platform.

    ``frame``: the strongest-contact frame (240, 320, 3) uint8 RGB.
    ``no_contact``: the same sensor without contact (240, 320, 3) uint8 RGB, or None.
    ``extra``: further in-contact frames of the same press (K, 240, 320, 3), or None.
    ``descriptor``: the press's texture descriptor (``core/texture.py``, (DIM,)) when it is
    already known (a library press described once, e.g. ``tactex prepare``'s calibration); the
    descriptor learner then uses it instead of describing ``frame``.
    """

    frame: np.ndarray
    no_contact: np.ndarray | None = None
    extra: np.ndarray | None = None
    descriptor: np.ndarray | None = None


def as_touch(touch: Touch | np.ndarray) -> Touch:
    """A Touch as it is, or a bare frame wrapped as a Touch without a no-contact frame."""
    return touch if isinstance(touch, Touch) else Touch(frame=touch)


def validate_frame(img: np.ndarray, what: str = "image") -> np.ndarray:
    """Check a frame is uint8 RGB 240x320 with some content; return it C-contiguous.

    Raises InputError naming ``what`` when the shape, dtype or content is wrong (a constant
    frame, e.g. a blank or corrupt capture, is rejected: it carries no texture).
    """
    if not isinstance(img, np.ndarray):
        raise InputError(f"{what}: expected a numpy array, got {type(img).__name__}")
    if img.dtype != np.uint8:
        raise InputError(f"{what}: expected dtype uint8, got {img.dtype}")
    if img.shape != (FRAME_H, FRAME_W, 3):
        raise InputError(f"{what}: expected shape ({FRAME_H}, {FRAME_W}, 3), got {img.shape}")
    if int(img.max()) == int(img.min()):
        raise InputError(f"{what}: constant frame (every pixel {int(img.max())}), no texture")
    return np.ascontiguousarray(img)
