"""A rotation-invariant texture descriptor of one touch, computed on the contact difference.

A GelSight frame is mostly the gel's own background (vignetting, tint); contact changes it by a
few grey levels. The descriptor therefore works on the *contact difference*
d = blur(contact) - blur(no contact) (per-channel mean removed, so a lighting offset between the
two frames does not count), cropped by ``BORDER`` px against the sensor's dark rim. Without a
no-contact frame the difference is taken against a heavy blur of the contact frame itself (a
high-pass proxy that keeps texture but loses the contact's overall shape).

Parts (all invariant to in-plane rotation of the texture, up to sampling):

- ``intensity`` (6): log of the 50/75/90/99th percentiles, mean and std of |d| (RGB norm)
  [log grey levels]: how strongly and how widely the surface pressed into the gel.
- ``spectrum`` (3 x 10): log radial power spectrum of each channel of d in 10 log-spaced bands
  from 1/80 to 0.5 cycles/px: the texture's scales, whatever its orientation.
- ``lbp`` (10 + 18 + 18 + 18): rotation-invariant uniform local binary patterns (scikit-image,
  ``method='uniform'``) of the grey difference at (P, R) = (8, 1), (16, 2), (16, 4) and (16, 2)
  at half resolution, as square-rooted histograms (Hellinger geometry).
- ``structure`` (3 x 2): structure-tensor energy (log) and coherence (0 = isotropic,
  1 = one orientation) at integration scales 1, 3 and 8 px: how directional the texture is.

- ``height_map`` (23, appended when asked: ``learner.descriptor_height_map``, on by default):
  statistics of the contact's height map by photometric stereo without a calibration ball
  (``height_map``, below): log radial power spectrum of the height in the 10 bands (10),
  roughness of the height with the contact's shape removed (4), log std of the shape (1), log
  percentiles of the gradient magnitude (3), circular harmonics 1-4 of the gradient
  orientations (4), log std of the Laplacian (1). Taken on the same contact difference as the
  other parts (so without a no-contact frame, on the high-pass proxy), over the whole frame
  also for a partial contact (an integrated height has no meaning over a region).

``describe`` returns a (DIM,) float64 vector (``DIM_HEIGHT_MAP`` with the height map);
``describe_touch`` averages it over a touch's contact frames (the strongest one plus
``Touch.extra``).
"""

from __future__ import annotations

import hashlib
from collections import OrderedDict
from collections.abc import Sequence

import cv2
import numpy as np
from scipy import linalg
from skimage.feature import local_binary_pattern

from .errors import InputError
from .touch import validate_frame
from .touch import Touch, as_touch

BORDER = 16                                   # px cropped from every side (dark rim)
N_BANDS = 10
BAND_EDGES = np.geomspace(1.0 / 80.0, 0.5, N_BANDS + 1)   # cycles/px
LBP_SCALES = ((8, 1, 1), (16, 2, 1), (16, 4, 1), (16, 2, 2))  # (points, radius, downscale)
STRUCTURE_SCALES = (1.0, 3.0, 8.0)           # px
PARTS = {"intensity": 6, "spectrum": 3 * N_BANDS,
         "lbp": sum(p + 2 for p, _, _ in LBP_SCALES), "structure": 2 * len(STRUCTURE_SCALES)}
DIM = sum(PARTS.values())
HM_DIM = N_BANDS + 4 + 1 + 3 + 4 + 1          # the height map's statistics
HM_SHAPE_SIGMA = 16.0                          # px, the contact's shape (removed for roughness)
DIM_HEIGHT_MAP = DIM + HM_DIM


def descriptor_dim(height_map: bool) -> int:
    """Size of the descriptor with or without the height map (``describe``)."""
    return DIM_HEIGHT_MAP if height_map else DIM


def part_slices() -> dict[str, slice]:
    """Where each part lies in the descriptor vector."""
    out, i = {}, 0
    for name, n in PARTS.items():
        out[name] = slice(i, i + n)
        i += n
    return out


def contact_difference(frame: np.ndarray, no_contact: np.ndarray | None) -> np.ndarray:
    """(240, 320, 3) uint8 frames -> (240 - 2B, 320 - 2B, 3) float32 difference, mean removed."""
    return contact_differences([frame], no_contact)[0]


def contact_differences(frames: Sequence[np.ndarray], no_contact: np.ndarray | None
                        ) -> np.ndarray:
    """(F, 240 - 2B, 320 - 2B, 3) float32: ``contact_difference`` of each of F frames of one
    press against its no-contact frame (blurred once); None: each against its own blur."""
    ref = None if no_contact is None else \
        cv2.GaussianBlur(no_contact.astype(np.float32), (0, 0), 0.8)
    out = []
    for frame in frames:
        c = cv2.GaussianBlur(frame.astype(np.float32), (0, 0), 0.8)
        r = cv2.GaussianBlur(frame.astype(np.float32), (0, 0), 12.0) if ref is None else ref
        d = (c - r)[BORDER:-BORDER, BORDER:-BORDER]
        out.append(d - d.reshape(-1, 3).mean(axis=0))
    return np.stack(out)


_BANDS: dict[tuple[int, int], list[np.ndarray]] = {}


def _band_index(radius: np.ndarray) -> list[np.ndarray]:
    """Flat indices of the FFT bins of each radial band (row-major, as a boolean mask picks
    them), cached per shape."""
    if radius.shape not in _BANDS:
        _BANDS[radius.shape] = [np.flatnonzero((radius >= BAND_EDGES[k])
                                               & (radius < BAND_EDGES[k + 1]))
                                for k in range(N_BANDS)]
    return _BANDS[radius.shape]


def radial_bands(img: np.ndarray, radius: np.ndarray, window: np.ndarray) -> np.ndarray:
    """(H, W) float -> (N_BANDS,) log mean power per radial frequency band."""
    p = (np.abs(np.fft.fft2((img - img.mean()) * window)) ** 2).ravel()
    out = np.empty(N_BANDS)
    for k, idx in enumerate(_band_index(radius)):
        out[k] = np.log(p[idx].mean() + 1e-6)
    return out


def _lbp_hist(grey_u8: np.ndarray, points: int, radius: int,
              keep: np.ndarray | None = None) -> np.ndarray:
    codes = local_binary_pattern(grey_u8, points, radius, method="uniform").astype(np.int64)
    codes = codes.ravel() if keep is None else codes[keep]
    h = np.bincount(codes, minlength=points + 2).astype(np.float64)
    return np.sqrt(h / h.sum())


def _structure(grey: np.ndarray, sigma: float,
               keep: np.ndarray | None = None) -> tuple[float, float]:
    gx = cv2.Sobel(grey, cv2.CV_32F, 1, 0, ksize=3)
    gy = cv2.Sobel(grey, cv2.CV_32F, 0, 1, ksize=3)
    jxx = cv2.GaussianBlur(gx * gx, (0, 0), sigma)
    jyy = cv2.GaussianBlur(gy * gy, (0, 0), sigma)
    jxy = cv2.GaussianBlur(gx * gy, (0, 0), sigma)
    tr = jxx + jyy
    aniso = np.sqrt((jxx - jyy) ** 2 + 4.0 * jxy ** 2)
    if keep is not None:
        tr, aniso = tr[keep], aniso[keep]
    return float(np.log(tr.mean() + 1e-6)), float(aniso.sum() / (tr.sum() + 1e-6))


_GEOMETRY: dict[tuple[int, int], tuple[np.ndarray, np.ndarray]] = {}


def fft_geometry(h: int, w: int) -> tuple[np.ndarray, np.ndarray]:
    """Radial frequency [cycles/px] of every FFT bin and the Hann window, cached per shape."""
    if (h, w) not in _GEOMETRY:
        fy = np.fft.fftfreq(h)[:, None]
        fx = np.fft.fftfreq(w)[None, :]
        _GEOMETRY[(h, w)] = (np.sqrt(fx ** 2 + fy ** 2), np.outer(np.hanning(h), np.hanning(w)))
    return _GEOMETRY[(h, w)]


def gradient_map(d: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Surface gradient of a contact difference ``d`` (H, W, 3) float32 without a calibration:
    (gx, gy) (H, W) float32 up to one scale and the colour->gradient map M (2, 3).

    The gradient is taken as a linear map of the colour difference (g = M d). A true gradient
    field has zero curl, so M is the one whose field is most nearly curl-free on this very
    press: the smallest generalized eigenvector of (K^T K, blockdiag(V^T V, V^T V)), K the curl
    as a linear function of M's 6 entries, V the colours (the field's energy). Scaled so that
    the field's root mean square is 1."""
    dy = np.gradient(d, axis=0).reshape(-1, 3)
    dx = np.gradient(d, axis=1).reshape(-1, 3)
    k = np.hstack([dy, -dx]).astype(np.float64)               # curl = K m
    v = d.reshape(-1, 3).astype(np.float64)
    a = k.T @ k
    b = np.zeros((6, 6))
    b[:3, :3] = b[3:, 3:] = v.T @ v
    _, vec = linalg.eigh(a, b + 1e-9 * np.trace(b) * np.eye(6))
    m = vec[:, 0].reshape(2, 3)
    g = d @ m.T.astype(np.float32)
    scale = np.sqrt((g ** 2).sum(-1).mean()) + 1e-12
    return g[..., 0] / scale, g[..., 1] / scale, m / scale


def integrate(gx: np.ndarray, gy: np.ndarray) -> np.ndarray:
    """Height (H, W) float64 whose gradient is nearest (least squares, periodic) to (gx, gy)
    [height per px]: the FFT Poisson solution (Frankot-Chellappa), mean zero."""
    h, w = gx.shape
    fy = np.fft.fftfreq(h)[:, None]
    fx = np.fft.fftfreq(w)[None, :]
    den = (2 * np.pi) ** 2 * (fx ** 2 + fy ** 2)
    den[0, 0] = 1.0
    num = -2j * np.pi * (fx * np.fft.fft2(gx) + fy * np.fft.fft2(gy))
    z = num / den
    z[0, 0] = 0.0
    return np.real(np.fft.ifft2(z))


def height_map(d: np.ndarray) -> np.ndarray:
    """(HM_DIM,) float64 statistics of the height map of a contact difference ``d`` (H, W, 3)
    float32 (``contact_difference``); see the module docstring. The height's sign is chosen so
    that it rises where the gel is most deformed (its shape correlates with |d|)."""
    gx, gy, _ = gradient_map(d)
    hgt = integrate(gx, gy).astype(np.float32)
    mag = np.sqrt((d ** 2).sum(-1))
    shape = cv2.GaussianBlur(hgt, (0, 0), HM_SHAPE_SIGMA)
    ms = cv2.GaussianBlur(mag, (0, 0), HM_SHAPE_SIGMA)
    if np.corrcoef(shape.ravel(), ms.ravel())[0, 1] < 0:
        hgt, shape, gx, gy = -hgt, -shape, -gx, -gy
    radius, window = fft_geometry(*hgt.shape)
    feats = [radial_bands(hgt, radius, window)]
    t = (hgt - shape).ravel()
    sd = t.std() + 1e-9
    z = (t - t.mean()) / sd
    feats.append([np.log(sd), np.log(np.abs(t).mean() + 1e-9), (z ** 3).mean(),
                  np.log((z ** 4).mean())])
    feats.append([np.log(shape.std() + 1e-9)])
    gm = np.sqrt(gx ** 2 + gy ** 2)
    feats.append(np.log(np.percentile(gm, [50, 90, 99]) + 1e-6))
    th = np.arctan2(gy, gx)
    wsum = gm.sum() + 1e-9
    feats.append([np.abs((gm * np.exp(1j * k * th)).sum()) / wsum for k in (1, 2, 3, 4)])
    feats.append([np.log(cv2.Laplacian(hgt, cv2.CV_32F).std() + 1e-9)])
    return np.concatenate([np.asarray(f, np.float64).ravel() for f in feats])


def describe(frame: np.ndarray, no_contact: np.ndarray | None = None,
             with_height_map: bool = False) -> np.ndarray:
    """(DIM,) float64 descriptor of one contact frame (see the module docstring);
    ``with_height_map``: (DIM_HEIGHT_MAP,), the height map's statistics appended."""
    frame = validate_frame(frame, "touch frame")
    if no_contact is not None:
        no_contact = validate_frame(no_contact, "no-contact frame")
    return describe_difference(contact_difference(frame, no_contact),
                               with_height_map=with_height_map)


def describe_difference(d: np.ndarray, region: np.ndarray | None = None,
                        with_height_map: bool = False) -> np.ndarray:
    """(DIM,) descriptor of a contact difference (H, W, 3) float32 (``contact_difference``, or
    a region of one at least 80 px on a side).

    ``region``: (H, W) bool, the pixels in contact (a partial contact, ``core/guards.py``);
    every part is then taken over the region only, as if the contact filled the frame: the
    intensity percentiles, the local binary patterns and the structure energy over its pixels,
    the spectrum of the difference zeroed outside it, divided by the region's share of the
    (squared) window. None: the whole frame (the default descriptor).
    ``with_height_map``: the height map's statistics of the whole ``d`` appended."""
    if region is not None and region.shape != d.shape[:2]:
        raise InputError(f"texture descriptor: region {region.shape} is not the difference's "
                         f"{d.shape[:2]}")
    if region is not None and not region.any():
        raise InputError("texture descriptor: empty contact region")
    inside = np.ones(d.shape[:2], bool) if region is None else region
    mag = np.sqrt((d ** 2).sum(axis=-1))
    grey = d.mean(axis=-1)
    q = np.percentile(mag[inside], [50, 75, 90, 99])
    feats = [np.log(q + 1e-3), np.log([mag[inside].mean() + 1e-3, mag[inside].std() + 1e-3])]
    radius, window = fft_geometry(*grey.shape)
    if region is None:
        feats += [radial_bands(d[..., ch], radius, window) for ch in range(3)]
    else:
        share = float((window ** 2 * region).sum() / (window ** 2).sum())
        dz = np.where(region[..., None], d - d[region].mean(axis=0), 0.0)
        feats += [radial_bands(dz[..., ch], radius, window) - np.log(share) for ch in range(3)]
    smooth = cv2.GaussianBlur(grey, (0, 0), 1.0)
    u8 = np.clip(smooth * 4.0 + 128.0, 0, 255).astype(np.uint8)
    for points, rad, down in LBP_SCALES:
        img, keep = u8, inside
        if down != 1:
            img = cv2.resize(u8, None, fx=1.0 / down, fy=1.0 / down, interpolation=cv2.INTER_AREA)
            keep = cv2.resize(inside.astype(np.uint8), (img.shape[1], img.shape[0]),
                              interpolation=cv2.INTER_NEAREST).astype(bool)
        feats.append(_lbp_hist(img, points, rad, None if region is None else keep))
    feats.append(np.array([v for s in STRUCTURE_SCALES
                           for v in _structure(grey, s, None if region is None else inside)]))
    if with_height_map:
        feats.append(height_map(d))
    out = np.concatenate([np.asarray(f, dtype=np.float64).ravel() for f in feats])
    if out.shape != (descriptor_dim(with_height_map),) or not np.all(np.isfinite(out)):
        raise InputError("texture descriptor: non-finite or mis-sized result")
    return out


_CACHE: OrderedDict[bytes, np.ndarray] = OrderedDict()
CACHE_SIZE = 4096


def _key(frame: np.ndarray, no_contact: np.ndarray | None, with_height_map: bool) -> bytes:
    h = hashlib.blake2b(np.ascontiguousarray(frame).data, digest_size=16,
                        person=b"hm" if with_height_map else b"")
    if no_contact is not None:
        h.update(np.ascontiguousarray(no_contact).data)
    return h.digest()


def clear_cache() -> None:
    """Forget every cached descriptor (benchmarks time the description itself)."""
    _CACHE.clear()


def describe_cached(frame: np.ndarray, no_contact: np.ndarray | None = None,
                    with_height_map: bool = False) -> np.ndarray:
    """``describe`` with a process-wide LRU cache keyed by the frames' bytes (a replayed press
    met again, e.g. in an evaluation over many scenes, is described once)."""
    k = _key(frame, no_contact, with_height_map)
    if k in _CACHE:
        _CACHE.move_to_end(k)
        return _CACHE[k]
    out = describe(frame, no_contact, with_height_map)
    _CACHE[k] = out
    if len(_CACHE) > CACHE_SIZE:
        _CACHE.popitem(last=False)
    return out


def describe_touch(touch: Touch | np.ndarray, max_frames: int = 1,
                   with_height_map: bool = False) -> np.ndarray:
    """(DIM,) mean descriptor over up to ``max_frames`` contact frames of one touch;
    ``with_height_map``: (``DIM_HEIGHT_MAP``,), the height map's statistics of the strongest
    frame appended (the lab's ``frames4_hm``: its texture is the deepest there, and one
    height map per touch keeps the cost of one)."""
    t = as_touch(touch)
    first = describe_cached(t.frame, t.no_contact, with_height_map)
    if t.extra is None or max_frames <= 1:
        return first
    rest = [describe_cached(f, t.no_contact, False) for f in t.extra[:max_frames - 1]]
    base = np.mean([first[:DIM]] + rest, axis=0)
    return np.concatenate([base, first[DIM:]])
