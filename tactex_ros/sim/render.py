"""GelSight-Mini-like rendering of a fabric pressed into the gel.

Model (per touch):

1. Cut a 320x240 window out of the fabric's cached height tile at a random position and
   in-plane rotation (one affine warp) -> heights H [mm] at 0.0634 mm/px.
2. Press: loose fibres and rare peaks are squashed: H is clipped at its ``crush_percentile``
   (top T). The gel is a slightly domed surface (curvature ``dome_per_mm2``); at press depth d
   the gel indentation is D = max(0, min(H, T) - (T - d) - dome * r^2). The contact area grows
   with d.
3. Gel smoothing: the elastomer cannot follow detail finer than its thickness: Gaussian blur of
   D with ``gel_sigma_mm``.
4. Photometric stereo: surface normals from the gradient of D, lit by three coloured lights
   from distinct azimuths; the change in shading against the flat gel is added to the gel's own
   background (base colour, radial vignetting, tint).
5. Per touch: small lighting drift (light gains, background offset), sensor noise.

Output: uint8 RGB (240, 320, 3). ``no_contact`` gives the same sensor without contact.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import cv2
import numpy as np

from ..core.names import FRAME_H, FRAME_W

MM_PER_PX = 0.0634


@dataclass
class SensorModel:
    """GelSight Mini look; the defaults were fitted by eye and by colour statistics to real
    no-contact / contact frames of octopi-dev (see README, "Simulator vs real frames")."""

    mm_per_px: float = MM_PER_PX
    base_rgb: tuple[float, float, float] = (30.0, 112.0, 104.0)
    center_tint_rgb: tuple[float, float, float] = (70.0, 8.0, 40.0)   # added at the centre
    vignette: float = 0.55           # relative darkening at the corners
    dome_per_mm2: float = 0.004      # gel dome curvature [mm / mm^2]
    gel_sigma_mm: float = 0.08       # gel smoothing [mm]
    # three lights: azimuth [deg], elevation [deg], RGB weight of the light's colour
    lights: tuple = ((90.0, 35.0, (1.0, 0.15, 0.25)),
                     (210.0, 35.0, (0.15, 1.0, 0.3)),
                     (330.0, 35.0, (0.2, 0.35, 1.0)))
    gain: float = 60.0               # grey levels per unit of shading change
    noise_std: float = 1.6           # grey levels
    drift: float = 0.04              # relative light gain drift per touch (std)
    depth_mm: tuple[float, float] = (0.25, 0.6)   # uniform press depth range [mm]
    crush_percentile: float = 97.0   # heights above this percentile are pressed flat


@dataclass
class _Cache:
    background: np.ndarray
    r2_mm: np.ndarray
    noise: np.ndarray
    light_dirs: np.ndarray = field(default_factory=lambda: np.zeros((3, 3)))
    light_rgb: np.ndarray = field(default_factory=lambda: np.zeros((3, 3)))


class GelSightRenderer:
    """Renders contact and no-contact frames; precomputes everything per sensor once."""

    def __init__(self, sensor: SensorModel | None = None) -> None:
        self.sensor = s = sensor or SensorModel()
        yy, xx = np.mgrid[0:FRAME_H, 0:FRAME_W].astype(np.float32)
        cx, cy = (FRAME_W - 1) / 2, (FRAME_H - 1) / 2
        rn2 = ((xx - cx) / cx) ** 2 + ((yy - cy) / cy) ** 2          # 0 centre, 2 corners
        base = np.array(s.base_rgb, np.float32)
        tint = np.array(s.center_tint_rgb, np.float32)
        bg = base * (1 - s.vignette * rn2[..., None] / 2) + tint * np.exp(-rn2)[..., None]
        r2_mm = (((xx - cx) ** 2 + (yy - cy) ** 2) * s.mm_per_px ** 2).astype(np.float32)
        rng = np.random.default_rng(12345)
        noise = rng.normal(0, 1, (FRAME_H * 2, FRAME_W * 2, 3)).astype(np.float32)
        dirs, rgb = [], []
        for az, el, col in s.lights:
            a, e = np.deg2rad(az), np.deg2rad(el)
            dirs.append([np.cos(e) * np.cos(a), np.cos(e) * np.sin(a), np.sin(e)])
            rgb.append(col)
        self._c = _Cache(bg.astype(np.float32), r2_mm, noise, np.array(dirs, np.float32),
                         np.array(rgb, np.float32))

    def window(self, tile: np.ndarray, rng: np.random.Generator) -> np.ndarray:
        """Random position + rotation: (S, S) tile -> (240, 320) heights."""
        size = tile.shape[0]
        half_diag = 0.5 * np.hypot(FRAME_W, FRAME_H) + 2
        if size < 2 * half_diag:
            raise ValueError(f"height tile {size} px too small for a rotated frame")
        cx, cy = rng.uniform(half_diag, size - half_diag, 2)
        ang = rng.uniform(0, 360)
        m = cv2.getRotationMatrix2D((float(cx), float(cy)), float(ang), 1.0)
        m[0, 2] += (FRAME_W - 1) / 2 - cx
        m[1, 2] += (FRAME_H - 1) / 2 - cy
        return cv2.warpAffine(tile, m, (FRAME_W, FRAME_H), flags=cv2.INTER_LINEAR,
                              borderMode=cv2.BORDER_REFLECT)

    def render(self, heights: np.ndarray, depth_mm: float,
               rng: np.random.Generator) -> np.ndarray:
        """(240, 320) heights [mm] pressed to ``depth_mm`` -> uint8 RGB (240, 320, 3)."""
        s, c = self.sensor, self._c
        # Loose fibres and rare high spots are squashed flat by the press: the surface the gel
        # meets is the height map clipped at its ``crush_percentile``.
        top = float(np.percentile(heights[::4, ::4], s.crush_percentile))
        d = (np.minimum(heights, np.float32(top)) - np.float32(top - depth_mm) -
             np.float32(s.dome_per_mm2) * c.r2_mm)
        np.maximum(d, 0, out=d)
        sig = s.gel_sigma_mm / s.mm_per_px
        d = cv2.GaussianBlur(d, (0, 0), sig)
        k = np.float32(1.0 / (8.0 * s.mm_per_px))
        gx = cv2.Sobel(d, cv2.CV_32F, 1, 0, ksize=3) * k
        gy = cv2.Sobel(d, cv2.CV_32F, 0, 1, ksize=3) * k
        inv = 1.0 / np.sqrt(1.0 + gx * gx + gy * gy)
        # shading change per light: (n . l) - l_z, n = (-gx, -gy, 1) / |.|
        gains = 1.0 + s.drift * rng.standard_normal(3).astype(np.float32)
        shade = np.empty((FRAME_H, FRAME_W, 3), np.float32)
        for i, (lx, ly, lz) in enumerate(c.light_dirs):
            shade[..., i] = ((lz - gx * lx - gy * ly) * inv - lz) * (s.gain * gains[i])
        img = cv2.transform(shade, c.light_rgb.T.copy())
        img += c.background
        oy, ox = rng.integers(0, FRAME_H), rng.integers(0, FRAME_W)
        img += c.noise[oy:oy + FRAME_H, ox:ox + FRAME_W] * np.float32(s.noise_std)
        img += np.float32(rng.normal(0, 1.0))      # background brightness drift
        return np.clip(img, 0, 255).astype(np.uint8)

    def no_contact(self, rng: np.random.Generator) -> np.ndarray:
        """The same sensor with nothing pressed on it."""
        c, s = self._c, self.sensor
        oy, ox = rng.integers(0, FRAME_H), rng.integers(0, FRAME_W)
        img = c.background + c.noise[oy:oy + FRAME_H, ox:ox + FRAME_W] * np.float32(s.noise_std)
        return np.clip(img, 0, 255).astype(np.uint8)
