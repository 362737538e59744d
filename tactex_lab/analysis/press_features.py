"""Candidate per-press features beyond the shipped descriptor (issue 33), screened with
``tactex experiment unseen --screen-features`` (docs/research/unseen_materials.md).

All numpy (FFT) on the contact difference d (``texture.contact_difference``: (H, W, 3) float32,
the blurred contact frame minus the blurred no-contact frame, per-channel mean removed, dark rim
cropped), so any of them could run in the product (no torch, nothing trained):

- ``filter_bank`` (scattering-like): a bank of oriented Gabor filters built in the frequency
  domain (``FB_FREQS`` centre frequencies [cycles/px], ``FB_ORIENT`` orientations over 180 deg).
  First order: log mean modulus of the grey difference per scale, averaged over orientations
  (rotation invariant); the outputs of coarse scales are computed subsampled (their spectrum
  cropped); orientation profile: the 2nd and 4th circular harmonics of the
  per-orientation energies relative to their mean (their moduli are rotation invariant: one
  direction, a square weave). Second order: the orientation-averaged modulus map of scale j1
  filtered again at every coarser scale j2, log mean modulus minus the first order of j1
  (how the texture's fine-scale energy is modulated at coarser scales).
- ``height_map`` (now ``tactex_ros.core.texture.height_map``, the shipped descriptor's last
  part): photometric stereo without a calibration ball. The gradient is a linear map of
  the colour difference (g = M d, M 2 x 3); M is the one whose gradient field is most nearly
  curl-free on this very press (a generalized 6 x 6 eigenproblem: a true gradient field of
  any surface has zero curl, and for a colour response linear in the gradient only M = lambda
  x the inverse response makes it so), scale fixed by the field's energy, sign so that the
  height rises where the gel is most deformed. Integrated by the FFT Poisson solution
  (Frankot-Chellappa). Features: log radial power spectrum of the height in ``texture``'s 10
  bands, roughness of the height with the contact's shape removed (log std, log mean |h|,
  skewness, kurtosis), log std of the shape itself (indentation), log percentiles of the
  gradient magnitude, 2nd / 4th circular harmonics of the gradient orientations weighted by
  magnitude, log std of the Laplacian (curvature).
- ``growth``: how the contact spreads over the press video: at the frames where the contact
  score first reaches 25 / 50 / 75 / 100 % of its peak, the log share of pixels deformed by more
  than ``GROWTH_LEVEL`` grey levels and the log 90th percentile of |d| (a soft material spreads
  before it presses deep).
"""

from __future__ import annotations

import cv2
import numpy as np
from scipy import fft as sfft

from tactex_ros.core import texture

FB_FREQS = (0.35, 0.22, 0.14, 0.088, 0.055, 0.035)    # cycles/px, ratio 1.6
FB_ORIENT = 8                                          # orientations over [0, 180) deg
FB_BANDWIDTH = 0.45                                    # Gaussian sigma / centre frequency
GROWTH_SHARES = (0.25, 0.5, 0.75, 1.0)
GROWTH_LEVEL = 4.0                                     # grey levels


_BANKS: dict[tuple[int, int, int], tuple[np.ndarray, np.ndarray]] = {}


def _crop_index(n: int, k: int) -> np.ndarray:
    """FFT bins of an ``n``-point axis below the Nyquist frequency of a ``k``-fold subsampling,
    in the FFT order of an n // k grid."""
    m = n // k
    return np.concatenate([np.arange(0, (m + 1) // 2), np.arange(n - m // 2, n)])


def _factor(f: float) -> int:
    """Subsampling of scale ``f``'s output: the largest power of 2 whose Nyquist frequency
    still holds the filter (centre + 3 sigma)."""
    k = 1
    while (1 + 3 * FB_BANDWIDTH) * f * 2 * k <= 0.5 + 1e-9:
        k *= 2
    return k


def _bank(h: int, w: int, j: int) -> tuple[np.ndarray, np.ndarray]:
    """Scale ``j``'s (L, h', w') complex64 frequency responses (zero at DC) on its subsampled
    grid, and the (rows, cols) FFT bins of the full grid they cover; cached per shape."""
    if (h, w, j) not in _BANKS:
        k = _factor(FB_FREQS[j])
        ri, ci = _crop_index(h, k), _crop_index(w, k)
        fy = np.fft.fftfreq(h)[ri][:, None]
        fx = np.fft.fftfreq(w)[ci][None, :]
        f = FB_FREQS[j]
        s = FB_BANDWIDTH * f
        out = np.empty((FB_ORIENT, len(ri), len(ci)), np.complex64)
        for l in range(FB_ORIENT):
            th = np.pi * l / FB_ORIENT
            g = np.exp(-((fx - f * np.cos(th)) ** 2 + (fy - f * np.sin(th)) ** 2) / (2 * s * s))
            g -= np.exp(-(f * f) / (2 * s * s)) * np.exp(-(fx ** 2 + fy ** 2) / (2 * s * s))
            # ifft on the n' grid divides by n', the full one by n: rescale to the full grid's
            out[l] = g * (len(ri) * len(ci)) / (h * w)
        _BANKS[(h, w, j)] = (out, np.ix_(ri, ci))
    return _BANKS[(h, w, j)]


def _moduli(img: np.ndarray, scales: range | list[int]) -> list[np.ndarray]:
    """Per scale j: (L, H / k_j, W / k_j) |img * psi_jl| (complex Gabor responses, subsampled
    by the scale's ``_factor``)."""
    f = sfft.fft2((img - img.mean()).astype(np.float32), workers=1)
    out = []
    for j in scales:
        bank, idx = _bank(img.shape[0], img.shape[1], j)
        out.append(np.abs(sfft.ifft2(f[idx][None] * bank, axes=(-2, -1), workers=1)))
    return out


FB_DIM = 3 * len(FB_FREQS) + len(FB_FREQS) * (len(FB_FREQS) - 1) // 2


def filter_bank(d: np.ndarray, second_order: bool = True) -> np.ndarray:
    """(FB_DIM,) (without the second order: 3 x len(FB_FREQS)) Gabor filter-bank statistics of
    the grey contact difference of ``d`` (H, W, 3), see the module docstring."""
    grey = d.mean(axis=-1)
    J = len(FB_FREQS)
    m = _moduli(grey, range(J))                              # J x (L, h_j, w_j)
    energy = np.array([mj.mean(axis=(-2, -1)) for mj in m])  # (J, L)
    s1 = np.log(energy.mean(1) + 1e-6)
    harm = np.abs(np.fft.fft(energy, axis=1))
    feats = [s1, harm[:, 1] / (harm[:, 0] + 1e-9), harm[:, 2] / (harm[:, 0] + 1e-9)]
    if second_order:
        for j1 in range(J - 1):
            u1 = m[j1].mean(axis=0)
            if u1.shape != grey.shape:
                u1 = cv2.resize(u1, (grey.shape[1], grey.shape[0]), interpolation=cv2.INTER_LINEAR)
            m2 = _moduli(u1, range(j1 + 1, J))
            feats.append(np.log([x.mean() + 1e-6 for x in m2]) - s1[j1])
    return np.concatenate([np.asarray(f, np.float64).ravel() for f in feats])


#: The height map is the product's since it became part of the shipped descriptor (issue 33).
gradient_map, integrate, height_map = texture.gradient_map, texture.integrate, texture.height_map
HM_DIM = texture.HM_DIM


GROWTH_DIM = 2 * len(GROWTH_SHARES)


def growth(frames_rgb: np.ndarray, no_contact: np.ndarray, scores: np.ndarray,
           peak: int) -> np.ndarray:
    """(GROWTH_DIM,) the contact's spread over a press video (F, H, W, 3) uint8 RGB with its
    contact ``scores`` (F,) and the strongest frame ``peak``."""
    out = []
    for share in GROWTH_SHARES:
        rise = np.flatnonzero(scores[:peak + 1] >= share * scores[peak])
        i = int(rise[0]) if len(rise) else peak
        mag = np.sqrt((texture.contact_difference(frames_rgb[i], no_contact) ** 2).sum(-1))
        out += [np.log((mag > GROWTH_LEVEL).mean() + 1e-3),
                np.log(np.percentile(mag, 90) + 1e-3)]
    return np.asarray(out)


def _touch_jobs(t, rgb: np.ndarray, idx, scores, emb, burst: int) -> dict:
    """The timed jobs of :func:`touch_costs` for one press (touch ``t``, its BGR->RGB frames
    ``rgb`` and strongest-contact ``idx``/``scores``), bound to this press."""
    from tactex_ros.core import embedding
    return {
        "descriptor": lambda: texture.describe(t.frame, t.no_contact),
        "descriptor_height_map": lambda: texture.describe(t.frame, t.no_contact, True),
        "filter_bank_1st": lambda: filter_bank(
            texture.contact_difference(t.frame, t.no_contact), second_order=False),
        "filter_bank": lambda: filter_bank(texture.contact_difference(t.frame, t.no_contact)),
        "height_map": lambda: height_map(texture.contact_difference(t.frame, t.no_contact)),
        "growth": lambda: growth(rgb, t.no_contact, scores, idx),
        # the shipped network (core/embedding.py) on the strongest frame, and the whole
        # touch as learner.descriptor_embedding=sim describes it
        "embedding": lambda: embedding.embed_touch(t, 1, emb),
        "embedding_burst": lambda: embedding.embed_touch(t, 4, emb),
        "descriptor_embedding": lambda: (texture.describe(t.frame, t.no_contact, True),
                                         embedding.embed_touch(t, burst, emb)),
    }


def touch_costs(root: str, presses: int = 12, repeats: int = 2) -> dict[str, dict]:
    """Per-touch cost [ms] of the descriptor without and with the height map (the shipped
    default since issue 33) and of each candidate, timed side by side
    (interleaved, the same presses) on the first ``presses`` presses of the replay folder
    ``root``: median and quartiles over presses x ``repeats``. ``growth`` includes the contact
    differences of its 4 frames; ``embedding`` is the shipped network's numpy pass on the
    strongest frame (``core/embedding.py``), ``embedding_burst`` its mean over the press's 4
    frames, ``descriptor_embedding`` the height-map descriptor and the embedding as the
    shipped default takes it (``learner.descriptor_embedding=sim``, over
    ``learner.descriptor_embedding_frames`` frames)."""
    import time
    from tactex_ros.core.contact import strongest_contact
    from tactex_ros.sources.replay import ReplaySource, read_video
    src = ReplaySource(root)
    paths = [p for c in src.classes for p in src.presses(c)][:presses]
    times: dict[str, list[float]] = {k: [] for k in ("descriptor", "descriptor_height_map",
                                                     "filter_bank_1st",
                                                     "filter_bank", "height_map", "growth",
                                                     "embedding", "embedding_burst",
                                                     "descriptor_embedding")}
    from tactex_ros.core import embedding
    from tactex_ros.core.config import DescriptorSettings
    emb = embedding.load(embedding.SHIPPED)
    burst = DescriptorSettings().descriptor_embedding_frames
    for path in paths:
        arr = read_video(path)
        rgb = np.ascontiguousarray(arr[..., ::-1])
        t = src.touch(path)
        idx, scores = strongest_contact(arr)
        jobs = _touch_jobs(t, rgb, idx, scores, emb, burst)
        for _ in range(repeats):
            for k, f in jobs.items():
                t0 = time.perf_counter()
                f()
                times[k].append((time.perf_counter() - t0) * 1e3)
    return {k: {"median_ms": float(np.median(v)), "q25_ms": float(np.percentile(v, 25)),
                "q75_ms": float(np.percentile(v, 75)), "n": len(v),
                "ratio_to_descriptor": float(np.median(v) / np.median(times["descriptor"]))}
            for k, v in times.items()}
