"""Frames to model input: validation, rotation augmentation without black corners, normalisation.

A GelSight frame is uint8 RGB (240, 320, 3). Every view the model sees is the centre square that
stays inside the frame under *any* rotation: side = frame height / sqrt(2) (169.7 px of 240), so a
rotated view never contains the black corners that rotating the whole frame would create. The
rotation, the crop and the resize to the model input (``size`` x ``size``) are one affine warp.

With ``native`` (``learner.sensor_crops``) a view is instead a ``size`` x ``size`` crop at
sensor resolution (no down-scaling) at a random position where it fits under any rotation
(the unrotated view: the frame centre).
"""

from __future__ import annotations

import math

import cv2
import numpy as np
import torch

from tactex_ros.core.errors import InputError
from tactex_ros.core.touch import FRAME_H, FRAME_W

IMAGENET_MEAN = np.array([0.485, 0.456, 0.406], dtype=np.float32)
IMAGENET_STD = np.array([0.229, 0.224, 0.225], dtype=np.float32)


def safe_crop_side(h: int = FRAME_H, w: int = FRAME_W) -> float:
    """Side (px) of the centre square inside an (h, w) frame under every rotation."""
    return min(h, w) / math.sqrt(2.0)


def view(img: np.ndarray, angle_deg: float, size: int, native: bool = False,
         centre: tuple[float, float] | None = None) -> np.ndarray:
    """One rotated, cropped, resized view: (240, 320, 3) uint8 -> (size, size, 3) uint8.

    ``native``: no resize (a ``size`` px crop at sensor resolution) centred at ``centre``
    (x, y) [px] (default: the frame centre)."""
    h, w = img.shape[:2]
    if native and size > safe_crop_side(h, w):
        raise InputError(f"a {size} px crop at sensor resolution does not fit a {w}x{h} frame "
                         f"under rotation (at most {int(safe_crop_side(h, w))} px)")
    scale = 1.0 if native else size / safe_crop_side(h, w)
    # Map the output square's centre to the frame centre (pixel-centre convention), rotated.
    cx, cy, co = (w - 1) / 2.0, (h - 1) / 2.0, (size - 1) / 2.0
    if centre is not None:
        cx, cy = centre
    m = cv2.getRotationMatrix2D((cx, cy), angle_deg, scale)
    m[0, 2] += co - cx
    m[1, 2] += co - cy
    interp = cv2.INTER_AREA if scale < 1.0 else cv2.INTER_LINEAR
    return cv2.warpAffine(img, m, (size, size), flags=interp, borderMode=cv2.BORDER_REFLECT)


def augment(img: np.ndarray, n: int, size: int, rng: np.random.Generator,
            include_identity: bool = False, native: bool = False) -> np.ndarray:
    """``n`` views at uniformly random angles in [0, 360): (n, size, size, 3) uint8.

    With ``include_identity`` the first view is unrotated (angle 0; ``native``: at the centre).
    ``native``: ``size`` px crops at sensor resolution, centres uniform over the positions where
    the rotated crop stays inside the frame.
    """
    angles = rng.uniform(0.0, 360.0, size=n)
    if include_identity and n > 0:
        angles[0] = 0.0
    if not native:
        return np.stack([view(img, float(a), size) for a in angles])
    h, w = img.shape[:2]
    r = size / math.sqrt(2.0)                # the rotated crop's half diagonal
    xs = rng.uniform(r, max(r, w - 1 - r), size=n)
    ys = rng.uniform(r, max(r, h - 1 - r), size=n)
    if include_identity and n > 0:
        xs[0], ys[0] = (w - 1) / 2.0, (h - 1) / 2.0
    return np.stack([view(img, float(a), size, True, (float(x), float(y)))
                     for a, x, y in zip(angles, xs, ys, strict=True)])


def to_tensor(views: np.ndarray, fourier: bool = False) -> torch.Tensor:
    """(N, S, S, 3) uint8 RGB -> (N, 3, S, S) float32, ImageNet-normalised.

    With ``fourier`` each channel is replaced by its centred log-magnitude spectrum,
    standardised per image (thesis appendix A.2: training on Fourier-transformed inputs).
    """
    x = views.astype(np.float32) / 255.0
    if fourier:
        spec = np.fft.fftshift(np.fft.fft2(x - x.mean(axis=(1, 2), keepdims=True), axes=(1, 2)),
                               axes=(1, 2))
        x = np.log1p(np.abs(spec)).astype(np.float32)
        x = (x - x.mean(axis=(1, 2), keepdims=True)) / (x.std(axis=(1, 2), keepdims=True) + 1e-6)
    else:
        x = (x - IMAGENET_MEAN) / IMAGENET_STD
    return torch.from_numpy(np.ascontiguousarray(x.transpose(0, 3, 1, 2)))
