"""Test frames of the core tests: distinct textures a learner can tell apart."""

from __future__ import annotations

import numpy as np


def stripe_frames(seed: int, n: int) -> list[np.ndarray]:
    """n (240, 320, 3) uint8 frames; class k = stripes of period 12 * 2**k px, with Gaussian
    noise (std 8 grey levels) drawn from ``seed``."""
    rng = np.random.default_rng(seed)
    yy, xx = np.mgrid[0:240, 0:320]
    out = []
    for k in range(n):
        base = 120 + 60 * np.sin(2 * np.pi * (xx + yy * 0.3) / (12 * 2**k))
        img = base[..., None] + rng.normal(0, 8, (240, 320, 3))
        out.append(np.clip(img, 0, 255).astype(np.uint8))
    return out
