"""GelSight Mini rendering of a fabric pressed into the gel, from a real sensor's calibration.

Model (per touch):

1. Cut a 320x240 window out of the fabric's cached height tile at a random position and
   in-plane rotation (one affine warp) -> heights H [mm] at 0.0634 mm/px.
2. Lie and press: the fabric undulates on its platform (a smooth random field) and the sensor
   meets it slightly tilted; the cloth buckles at the millimetre scale (puckers: a finer smooth
   random field, ``pucker_mm``, pressed flat on soft fabrics); loose fibres and rare peaks are squashed (H clipped at its ``crush_percentile``, top
   T); a soft fabric's relief is compressed by the press (scaled by
   1 - softness * min(1, depth / ``soft_depth_mm``)). At press depth d the gel's indentation is
   D = max(0, min(H, T) - (T - d)).
3. Gel mechanics: the elastomer bridges narrow gaps between yarns instead of following them
   down (D <- max(D, ``elastic_fill`` * blur(D, ``elastic_sigma_mm``))) and cannot follow
   detail finer than its skin (Gaussian blur ``gel_sigma_mm``).
4. Optics from the real GelSight Mini calibration shipped by PyPI's ``taxim``
   (``sim/calibration.py``): the slope angle and direction of the indented gel select a bin of
   the calibration's table, whose quadratic in the pixel position gives each channel's
   intensity; the change against the flat gel is added to the calibration's recorded
   no-contact frame (``shade_step`` > 1 evaluates it on a coarser grid, faster but it loses
   weaves finer than ~4 px).
5. Per touch: light-gain drift, background brightness drift, sensor noise.

Output: uint8 RGB (240, 320, 3). ``no_contact`` gives the same sensor without contact.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from ..core.touch import FRAME_H, FRAME_W
from .calibration import OpticalCalibration, load_calibration

MM_PER_PX = 0.0634

try:  # numba (pinned in requirements.txt): the calibration lookup in one compiled pass
    from numba import njit
except ImportError:  # pragma: no cover - exercised by forcing the numpy path in the tests
    njit = None


def _lookup_rows_kernel(slope, ang, mag_scale, dir_scale, nb, table, feats, out):  # noqa: ANN001
    """The calibration lookup in one pass (compiled by numba; too slow uncompiled). Per pixel
    i: slope bin min(slope * mag_scale, nb - 1) and direction bin min(ang * dir_scale, nb - 1)
    (truncated, as numpy's astype) -> row of ``table`` (bins, 18); out[i, c] = row[6c:6c+6] .
    feats[i] (float32, summed in pairs). slope, ang: (N,) float32 [rad]; feats: (N, 6)
    float32; out: (N, 3) float32, written in place."""
    top = np.float32(nb - 1)
    for i in range(slope.shape[0]):
        row = np.int64(min(slope[i] * mag_scale, top)) * nb + np.int64(min(ang[i] * dir_scale, top))
        if row == 0:  # the flat gel: the table's row 0 is 0 (the change against itself)
            out[i, 0] = out[i, 1] = out[i, 2] = 0.0
            continue
        f0, f1, f2 = feats[i, 0], feats[i, 1], feats[i, 2]
        f3, f4, f5 = feats[i, 3], feats[i, 4], feats[i, 5]
        for c in range(3):
            k = 6 * c
            out[i, c] = ((table[row, k] * f0 + table[row, k + 1] * f1)
                         + (table[row, k + 2] * f2 + table[row, k + 3] * f3)
                         + (table[row, k + 4] * f4 + table[row, k + 5] * f5))


def _compile_lookup():  # noqa: ANN202
    """The lookup compiled by numba (cached on disk next to this module, or numba's user-wide
    cache where that is read-only), or None without numba."""
    if njit is None:
        return None
    try:
        return njit(cache=True, nogil=True, boundscheck=False)(_lookup_rows_kernel)
    except RuntimeError:  # no writable cache location: compile on first use in each process
        return njit(cache=False, nogil=True, boundscheck=False)(_lookup_rows_kernel)


_lookup_rows = _compile_lookup()


@dataclass
class SensorModel:
    """GelSight Mini: optics from the taxim calibration; gel mechanics and noise tuned so that
    contact differences match real octopi-dev presses in level and spatial spectrum (README,
    "Simulator vs real frames", ``tactex sim compare``)."""

    mm_per_px: float = MM_PER_PX
    calibration: str = "gelsight_mini"   # folder of taxim's calibrations
    # Units differ in LED colour and crop: the calibration unit's no-contact frame is recoloured
    # per channel (gain, offset) to the mean and spread of octopi-dev's no-contact frames
    # (RGB 58.7/97.0/106.6, spread 32.0/15.4/26.2): those two statistics match by construction.
    background_gain_rgb: tuple[float, float, float] = (0.985, 1.612, 1.214)
    background_offset_rgb: tuple[float, float, float] = (-23.1, -62.9, -30.7)
    elastic_sigma_mm: float = 0.25       # reach of the gel bridging gaps [mm]
    elastic_fill: float = 0.8            # how far it fills them (0 = follows every valley)
    gel_sigma_mm: float = 0.14           # gel skin smoothing [mm]
    shading_gain: float = 1.0            # multiplier on the calibrated intensity change
    noise_std: float = 0.35              # sensor noise per frame [grey levels]
    noise_sigma_px: float = 1.3          # its spatial correlation (video compression) [px]
    brightness_drift: float = 0.5        # per-touch background offset (std) [grey levels]
    drift: float = 0.04                  # relative light gain drift per touch (std)
    depth_mm: tuple[float, float] = (0.25, 0.6)   # uniform press depth range [mm]
    crush_percentile: float = 97.0       # heights above this percentile are pressed flat
    tilt_deg: float = 1.0                # sensor tilt against the fabric per press (std) [deg]
    drape_mm: float = 0.25               # fabric undulation on the platform (std) [mm]
    drape_len_mm: float = 3.0            # its correlation length [mm]
    # The cloth's millimetre-scale relief that the yarn model lacks: the sheet buckles between
    # yarn crossings (puckers, cockles) and yarns vary in thickness along their length. A
    # smooth random field (std for a rigid fabric, Gaussian correlation length); a soft
    # fabric's is pressed flat: scaled by (1 - softness). It moves contact-difference power
    # from the largest scales to periods of 0.6-3 mm (README, "Simulator vs real frames").
    pucker_mm: float = 0.025             # std for a rigid fabric [mm]
    pucker_len_mm: float = 0.25          # correlation length (Gaussian sigma) [mm]
    soft_depth_mm: float = 0.3           # depth at which a soft fabric is fully compressed
    compression: float = 0.3             # share of every fabric's relief a full press flattens
    shade_step: int = 1                  # table evaluated on every shade_step-th pixel
    # Recording sessions (``session_background``, ``press_background``): the no-contact frame
    # changes between sessions (LED brightness, exposure, how the gel sits) and, less, from
    # press to press within one. Measured on octopi-dev, whose classes were each recorded in
    # one session (README, "Recording sessions"): the channel means move together (one
    # brightness factor, correlation 0.95-0.99), each channel's spatial spread moves with it
    # (correlation below) plus independently, and the large-scale pattern changes.
    session_offset_rgb: tuple[float, float, float] = (5.78, 2.88, 5.22)   # [grey levels]
    session_contrast_rgb: tuple[float, float, float] = (0.1, 0.55, 1.0)    # spread std [grey]
    session_pattern: float = 0.16        # large-scale pattern std [units of channel spread]
    press_offset_rgb: tuple[float, float, float] = (0.13, 0.1, 0.1)       # [grey levels]
    press_contrast_rgb: tuple[float, float, float] = (0.065, 0.05, 0.045)  # [grey levels]
    press_pattern: float = 0.01         # [units of channel spread]
    contrast_brightness_corr: tuple[float, float, float] = (0.22, -0.87, -0.7)


class GelSightRenderer:
    """Renders contact and no-contact frames; precomputes everything per sensor once."""

    def __init__(self, sensor: SensorModel | None = None) -> None:
        self.sensor = s = sensor or SensorModel()
        if s.shade_step not in (1, 2, 4):
            raise ValueError(f"shade_step {s.shade_step}: use 1, 2 or 4")
        self.calib: OpticalCalibration = load_calibration(s.calibration, (FRAME_H, FRAME_W))
        c = self.calib
        bg = (c.background * np.array(s.background_gain_rgb, np.float32) +
              np.array(s.background_offset_rgb, np.float32))
        self._background = np.clip(bg, 0, 255).astype(np.float32)
        k = s.shade_step
        self._hs, self._ws = FRAME_H // k, FRAME_W // k
        feats = c.features.reshape(FRAME_H, FRAME_W, 6)[k // 2::k, k // 2::k].reshape(-1, 6)
        # One row of 18 coefficients per bin (channel-major: channel * 6 + coefficient), less
        # the flat gel's (slope bin 0, the same for every direction): a pixel's change against
        # the flat gel is then the dot product of its bin's row with its features, gathered in
        # one row lookup per pixel; the flat gel gives exactly 0.
        table = c.table - c.table[:1, :, :]
        self._table = np.ascontiguousarray(table.reshape(-1, 18), np.float32)   # (bins, 18)
        self._feats = np.ascontiguousarray(np.tile(feats, (1, 3)), np.float32)  # (N, 18)
        self._feats6 = np.ascontiguousarray(feats, np.float32)                   # (N, 6)
        self._ones = np.ones((self._hs, self._ws), np.float32)
        # numba's one-pass lookup where numba is installed (the default: requirements.txt),
        # else the numpy row gather below; both give the same frames (test_sim_optics.py)
        self._compiled_lookup = _lookup_rows
        self._mag_scale = np.float32((c.num_bins - 1) / (0.5 * np.pi))
        self._dir_scale = np.float32((c.num_bins - 1) / (2 * np.pi))
        rng = np.random.default_rng(12345)
        noise = rng.normal(0, 1, (FRAME_H * 2, FRAME_W * 2, 3)).astype(np.float32)
        if s.noise_sigma_px > 0:
            noise = cv2.GaussianBlur(noise, (0, 0), s.noise_sigma_px)
        self._noise = noise / noise.std()
        drape = rng.normal(0, 1, (FRAME_H * 2, FRAME_W * 2)).astype(np.float32)
        drape = cv2.GaussianBlur(drape, (0, 0), s.drape_len_mm / s.mm_per_px)
        self._drape = drape / drape.std()
        pucker = rng.normal(0, 1, (FRAME_H * 2, FRAME_W * 2)).astype(np.float32)
        pucker = cv2.GaussianBlur(pucker, (0, 0), s.pucker_len_mm / s.mm_per_px)
        self._pucker = pucker / pucker.std()
        yy, xx = np.mgrid[0:FRAME_H, 0:FRAME_W].astype(np.float32)
        self._xmm = (xx - (FRAME_W - 1) / 2) * np.float32(s.mm_per_px)
        self._ymm = (yy - (FRAME_H - 1) / 2) * np.float32(s.mm_per_px)

    @property
    def background(self) -> np.ndarray:
        """(240, 320, 3) float32 RGB: the sensor's no-contact frame (the calibration's,
        recoloured)."""
        return self._background

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

    def lie(self, heights: np.ndarray, rng: np.random.Generator, softness: float = 0.0
            ) -> np.ndarray:
        """How the fabric lies under this press: + undulation (a window of a smooth random
        field, ``drape_mm``) + the sensor's tilt (``tilt_deg``) + the cloth's millimetre-scale
        puckers (``pucker_mm`` x (1 - ``softness``)). (240, 320) [mm]."""
        s = self.sensor
        oy, ox = rng.integers(0, FRAME_H), rng.integers(0, FRAME_W)
        tx, ty = np.tan(np.deg2rad(rng.normal(0, s.tilt_deg, 2))).astype(np.float32)
        # each term in one pass (cv2.scaleAdd: a * x + y)
        out = cv2.scaleAdd(self._drape[oy:oy + FRAME_H, ox:ox + FRAME_W], s.drape_mm, heights)
        cv2.scaleAdd(self._xmm, float(tx), out, dst=out)
        cv2.scaleAdd(self._ymm, float(ty), out, dst=out)
        pucker = s.pucker_mm * (1.0 - float(np.clip(softness, 0.0, 1.0)))
        if pucker > 0:
            py, px = rng.integers(0, FRAME_H), rng.integers(0, FRAME_W)
            cv2.scaleAdd(self._pucker[py:py + FRAME_H, px:px + FRAME_W], pucker, out, dst=out)
        return out

    def indentation(self, heights: np.ndarray, depth_mm: float, softness: float = 0.0
                    ) -> np.ndarray:
        """(240, 320) heights [mm] pressed to ``depth_mm`` -> gel indentation [mm] on the
        shading grid, (240 / shade_step, 320 / shade_step)."""
        s, k = self.sensor, self.sensor.shade_step
        top = float(np.percentile(heights[::4, ::4], s.crush_percentile))
        h = heights
        if k > 1:
            h = cv2.resize(np.minimum(h, np.float32(top)), (self._ws, self._hs),
                           interpolation=cv2.INTER_AREA)
        px = s.mm_per_px * k
        soft = 1.0 - (1.0 - float(np.clip(softness, 0.0, 1.0))) * (1.0 - s.compression)
        # a soft fabric's relief is compressed around its top: T - (T - min(H, T)) * squeeze
        squeeze = 1.0 - soft * min(1.0, depth_mm / s.soft_depth_mm)
        # D = max(0, that - (T - d)) = clip(H * squeeze + d - T * squeeze, 0, d), one pass
        # for the affine map (cv2.addWeighted with a zero second term) and one for the clip
        d = cv2.addWeighted(h, squeeze, h, 0.0, depth_mm - top * squeeze)
        np.clip(d, 0.0, np.float32(depth_mm), out=d)
        if s.elastic_fill > 0:
            bridge = cv2.GaussianBlur(d, (0, 0), s.elastic_sigma_mm / px)
            bridge *= np.float32(s.elastic_fill)
            np.maximum(d, bridge, out=d)
        return cv2.GaussianBlur(d, (0, 0), max(0.3, s.gel_sigma_mm / px))

    def shading(self, indent: np.ndarray) -> np.ndarray:
        """Gel indentation on the shading grid [mm] (``indentation``) -> calibrated intensity
        change (240, 320, 3) float32 [grey levels] against the flat gel."""
        s, k = self.sensor, self.sensor.shade_step
        if indent.shape != (self._hs, self._ws):
            raise ValueError(f"indentation of shape {indent.shape}, expected "
                             f"{(self._hs, self._ws)}")
        step = np.float32(s.mm_per_px * k)
        # the negated gradient [mm/mm]: its angle is the calibration's direction atan2(row,
        # col) + pi, in [0, 2 pi)
        neg = -1.0 / (8.0 * float(step))
        mag, ang = cv2.cartToPolar(cv2.Sobel(indent, cv2.CV_32F, 1, 0, ksize=3, scale=neg),
                                   cv2.Sobel(indent, cv2.CV_32F, 0, 1, ksize=3, scale=neg))
        nb = self.calib.num_bins
        slope = cv2.phase(self._ones, mag)                # atan(|grad|) in [0, pi/2]
        if self._compiled_lookup is not None:
            out = np.empty((self._hs * self._ws, 3), np.float32)
            self._compiled_lookup(slope.reshape(-1), ang.reshape(-1), self._mag_scale,
                                  self._dir_scale, nb, self._table, self._feats6, out)
        else:
            out = self._lookup_numpy(slope, ang)
        out = out.reshape(self._hs, self._ws, 3)
        if k > 1:
            out = cv2.resize(out, (FRAME_W, FRAME_H), interpolation=cv2.INTER_LINEAR)
        return out

    def _lookup_numpy(self, slope: np.ndarray, ang: np.ndarray) -> np.ndarray:
        """The lookup of ``_lookup_rows_kernel`` in numpy (without numba): slope and direction
        [rad] on the shading grid -> (N, 3) float32 change against the flat gel."""
        nb = self.calib.num_bins
        bm = np.minimum(slope * self._mag_scale, nb - 1).astype(np.int32)
        bd = np.minimum(ang * self._dir_scale, nb - 1).astype(np.int32)
        idx = (bm * nb + bd).ravel()
        terms = self._table.take(idx, axis=0)              # (N, 18) coefficients per pixel
        terms *= self._feats                               # x features
        t = terms.reshape(-1, 6)                           # (N * 3, 6): pixel, channel
        out = t[:, 0] + t[:, 1]                            # sum over the 6 terms
        for j in range(2, 6):
            out += t[:, j]
        return out.reshape(-1, 3)

    def render(self, heights: np.ndarray, depth_mm: float, rng: np.random.Generator,
               softness: float = 0.0, background: np.ndarray | None = None) -> np.ndarray:
        """(240, 320) heights [mm] pressed to ``depth_mm`` -> uint8 RGB (240, 320, 3).

        ``softness`` in [0, 1]: share of the fabric's relief the press flattens;
        ``background``: the press's no-contact frame (float32 (240, 320, 3), from
        ``press_background``; default: the sensor's)."""
        s = self.sensor
        delta = self.shading(self.indentation(self.lie(heights, rng, softness), depth_mm,
                                              softness))
        gains = s.shading_gain * (1.0 + s.drift * rng.standard_normal(3))
        img = cv2.multiply(delta, (*gains.tolist(), 0.0))
        cv2.add(img, self._check_bg(background), dst=img)
        return self._finish(img, rng, drift=True)

    def no_contact(self, rng: np.random.Generator, drift: bool = False,
                   background: np.ndarray | None = None) -> np.ndarray:
        """The same sensor with nothing pressed on it (``drift``: with a per-touch
        brightness offset, as a contact frame has; ``background`` as for ``render``)."""
        return self._finish(self._check_bg(background).copy(), rng, drift=drift)

    def _check_bg(self, background: np.ndarray | None) -> np.ndarray:
        if background is None:
            return self._background
        if background.shape != self._background.shape or background.dtype != np.float32:
            raise ValueError(f"background of shape {background.shape} and type "
                             f"{background.dtype}, expected (240, 320, 3) float32")
        return background

    def session_background(self, rng: np.random.Generator) -> np.ndarray:
        """The no-contact frame of a new recording session: the sensor's, varied by the
        between-session spread (``session_*``). (240, 320, 3) float32 [grey levels]."""
        s = self.sensor
        return self._vary(self._background, rng, s.session_offset_rgb,
                          s.session_contrast_rgb, s.session_pattern)

    def press_background(self, session: np.ndarray, rng: np.random.Generator) -> np.ndarray:
        """The no-contact frame of one press in a session (``session_background``), varied by
        the within-session spread (``press_*``); the press's contact frame is rendered on it.
        (240, 320, 3) float32 [grey levels]."""
        s = self.sensor
        return self._vary(self._check_bg(session), rng, s.press_offset_rgb,
                          s.press_contrast_rgb, s.press_pattern)

    def _vary(self, base: np.ndarray, rng: np.random.Generator,
              offset: tuple[float, float, float], contrast: tuple[float, float, float],
              pattern: float) -> np.ndarray:
        """base (240, 320, 3) float32 -> base with one brightness factor z ~ N(0, 1) moving
        every channel's mean by ``offset`` * z and its spatial spread by ``contrast`` (std, a
        share ``contrast_brightness_corr`` of it following z), plus a large-scale pattern
        (a 6x8 grid of N(0, 1), cubic-interpolated, mean removed, x ``pattern`` x the channel's
        spread)."""
        z = float(rng.standard_normal())
        own = rng.standard_normal(3)
        grid = rng.standard_normal((6, 8, 3)).astype(np.float32)
        flat = base.reshape(-1, 3)
        mean, spread = flat.mean(axis=0), flat.std(axis=0)
        rho = np.asarray(self.sensor.contrast_brightness_corr)
        d_spread = np.asarray(contrast) * (rho * z + np.sqrt(1.0 - rho ** 2) * own)
        gain = 1.0 + d_spread / np.where(spread > 0, spread, 1.0)
        field = cv2.resize(grid, (FRAME_W, FRAME_H), interpolation=cv2.INTER_CUBIC)
        field -= field.reshape(-1, 3).mean(axis=0)     # the pattern leaves the means to z
        out = (base - mean) * gain.astype(np.float32) + (mean + np.asarray(offset) * z
                                                         ).astype(np.float32)
        out += field * (np.float32(pattern) * spread.astype(np.float32))
        return np.clip(out, 0, 255).astype(np.float32)

    def _finish(self, img: np.ndarray, rng: np.random.Generator, drift: bool) -> np.ndarray:
        """float32 image + noise (+ brightness drift) -> rounded, saturated uint8."""
        s = self.sensor
        oy, ox = rng.integers(0, FRAME_H), rng.integers(0, FRAME_W)
        offset = float(rng.normal(0, s.brightness_drift)) if drift else 0.0
        return cv2.addWeighted(img, 1.0, self._noise[oy:oy + FRAME_H, ox:ox + FRAME_W],
                               float(s.noise_std), offset, dtype=cv2.CV_8U)
