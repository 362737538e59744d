"""Perturbations of a touch: what goes wrong with a real sensor, each on a severity axis.

Every function takes a ``core.touch.Touch`` (uint8 RGB frames (240, 320, 3)) and returns a new
one; frames are computed in float32 and saturated to 0..255. Randomness comes only from the
``rng`` given (the caller seeds it per touch), so the same touch, severity and seed give the
same frames. Severity 0 returns the touch unchanged.

- ``lighting_drift``: the LED brightness and an ambient offset change over a trial. Touch number
  ``k`` (0 = the first touch of the trial) gets per-channel gain ``1 + k * pct / 100 * w_c`` and
  offset ``k * pct * w_c / 4`` grey levels (``w_c`` the trial's channel weights, e.g. drawn once
  in [0.5, 1.5] with a random sign: the drift's colour and direction); every frame of the touch
  drifts alike, its no-contact frame too (recorded seconds apart in the same press).
  Severity: ``pct`` percent gain change per touch.
- ``sensor_noise``: independent Gaussian noise of std ``sigma`` grey levels on every frame of the
  touch (each is a separate capture). Severity: ``sigma`` [grey levels].
- ``partial_contact``: a share ``fraction`` of the contact region shows no contact: the contact
  pixels (``|blur(frame) - blur(no contact)|`` summed over channels above ``CONTACT_LEVEL`` grey
  levels) beyond a line at a random angle are replaced by the no-contact frame, in every contact
  frame alike (the object covered only part of the gel). Severity: ``fraction`` of the contact
  area lost (0..1).
- ``low_force``: a lighter press: every contact frame becomes ``no_contact + scale * (frame -
  no_contact)``. Severity: ``1 - scale``, the share of the recorded contact difference lost.
- ``worn_gel``: a worn gel's coating renders texture blurred and weaker: the contact difference
  ``frame - no_contact`` is blurred (Gaussian, ``sigma_px``) and multiplied by
  ``1 / (1 + sigma_px / 8)``. Severity: ``sigma_px`` [px].

A touch without a no-contact frame (a single image file) cannot show less contact:
``partial_contact``, ``low_force`` and ``worn_gel`` return it unchanged.
"""

from __future__ import annotations

from dataclasses import replace

import cv2
import numpy as np

from ..core.errors import InputError
from ..core.touch import Touch

CONTACT_LEVEL = 6.0        # grey levels (sum over channels of the blurred difference): contact
KINDS = ("drift", "noise", "partial", "low_force", "worn")


def _frames(touch: Touch) -> list[np.ndarray]:
    """The contact frames of a touch: the strongest, then ``extra``."""
    return [touch.frame] + ([] if touch.extra is None else list(touch.extra))


def _rebuild(touch: Touch, frames: list[np.ndarray], no_contact: np.ndarray | None) -> Touch:
    """``touch`` with new contact frames (float, saturated to uint8) and no-contact frame."""
    u8 = [np.clip(np.rint(f), 0, 255).astype(np.uint8) for f in frames]
    nc = None if no_contact is None else np.clip(np.rint(no_contact), 0, 255).astype(np.uint8)
    return replace(touch, frame=u8[0], no_contact=nc,
                   extra=np.stack(u8[1:]) if len(u8) > 1 else None, descriptor=None)


def _check(name: str, value: float, lo: float, hi: float) -> float:
    v = float(value)
    if not lo <= v <= hi:
        raise InputError(f"{name} {value} outside [{lo:g}, {hi:g}]")
    return v


def lighting_drift(touch: Touch, k: int, pct: float, weights: np.ndarray) -> Touch:
    """Touch number ``k`` of a trial under a lighting drift of ``pct`` % gain per touch with
    channel weights ``weights`` (3,) (see module docstring)."""
    _check("lighting drift [% per touch]", pct, 0.0, 100.0)
    if pct == 0 or k == 0:
        return touch
    w = np.asarray(weights, np.float32).reshape(3)
    gain = 1.0 + k * pct / 100.0 * w
    offset = k * pct * w / 4.0

    def f(x: np.ndarray) -> np.ndarray:
        return x.astype(np.float32) * gain + offset

    return _rebuild(touch, [f(x) for x in _frames(touch)],
                    None if touch.no_contact is None else f(touch.no_contact))


def drift_weights(rng: np.random.Generator) -> np.ndarray:
    """A trial's drift colour and direction: (3,) weights in [0.5, 1.5], one random sign."""
    return rng.uniform(0.5, 1.5, 3) * rng.choice([-1.0, 1.0])


def noise_image(img: np.ndarray, sigma: float, rng: np.random.Generator) -> np.ndarray:
    """``img`` (any shape) plus Gaussian noise of std ``sigma`` grey levels, float32."""
    out = img.astype(np.float32)
    if sigma:
        out += rng.normal(0.0, sigma, out.shape).astype(np.float32)
    return out


def sensor_noise(touch: Touch, sigma: float, rng: np.random.Generator) -> Touch:
    """Every frame of ``touch`` with independent Gaussian noise of std ``sigma`` grey levels:
    the contact frames in order, then the no-contact frame."""
    _check("sensor noise [grey levels]", sigma, 0.0, 255.0)
    if sigma == 0:
        return touch
    frames = [noise_image(x, sigma, rng) for x in _frames(touch)]
    nc = None if touch.no_contact is None else noise_image(touch.no_contact, sigma, rng)
    return _rebuild(touch, frames, nc)


def contact_mask(frame: np.ndarray, no_contact: np.ndarray) -> np.ndarray:
    """(240, 320) bool: pixels in contact (blurred difference summed over channels >
    ``CONTACT_LEVEL`` grey levels)."""
    d = (cv2.GaussianBlur(frame, (5, 5), 0).astype(np.float32) -
         cv2.GaussianBlur(no_contact, (5, 5), 0).astype(np.float32))
    return np.abs(d).sum(axis=2) > CONTACT_LEVEL


def partial_contact(touch: Touch, fraction: float, angle: float) -> Touch:
    """``touch`` with the share ``fraction`` of its contact region (of the strongest frame)
    beyond a line at ``angle`` [rad] replaced by the no-contact frame in every contact frame."""
    _check("partial contact [share of the contact area lost]", fraction, 0.0, 1.0)
    if fraction == 0 or touch.no_contact is None:
        return touch
    inside = contact_mask(touch.frame, touch.no_contact)
    h, w = inside.shape
    yy, xx = np.mgrid[0:h, 0:w].astype(np.float32)
    proj = np.cos(angle) * xx + np.sin(angle) * yy
    vals = proj[inside] if inside.any() else proj.ravel()
    cut = np.quantile(vals, 1.0 - fraction) if fraction < 1 else -np.inf
    lost = proj >= cut if fraction < 1 else np.ones_like(inside)
    nc = touch.no_contact.astype(np.float32)
    frames = [np.where(lost[..., None], nc, x.astype(np.float32)) for x in _frames(touch)]
    return _rebuild(touch, frames, nc)


def low_force(touch: Touch, lost: float) -> Touch:
    """A lighter press: the share ``lost`` of the contact difference removed from every
    contact frame (``no_contact + (1 - lost) * (frame - no_contact)``)."""
    _check("low force [share of the contact difference lost]", lost, 0.0, 1.0)
    if lost == 0 or touch.no_contact is None:
        return touch
    nc = touch.no_contact.astype(np.float32)
    frames = [nc + (1.0 - lost) * (x.astype(np.float32) - nc) for x in _frames(touch)]
    return _rebuild(touch, frames, nc)


def worn_gel(touch: Touch, sigma_px: float) -> Touch:
    """A worn gel: the contact difference blurred by ``sigma_px`` px and weakened by
    ``1 / (1 + sigma_px / 8)`` in every contact frame."""
    _check("worn gel [blur px]", sigma_px, 0.0, 50.0)
    if sigma_px == 0 or touch.no_contact is None:
        return touch
    nc = touch.no_contact.astype(np.float32)
    c = 1.0 / (1.0 + sigma_px / 8.0)
    frames = [nc + c * cv2.GaussianBlur(x.astype(np.float32) - nc, (0, 0), sigma_px)
              for x in _frames(touch)]
    return _rebuild(touch, frames, nc)


class Perturbation:
    """One perturbation at one severity over one trial: ``__call__(touch)`` perturbs the trial's
    touches in order (touch k = the k-th call), seeded by ``seed`` per touch, so the k-th touch
    of a trial gets the same random draws at every severity.

    ``kind``: one of ``KINDS``; ``severity`` in that kind's unit (module docstring)."""

    def __init__(self, kind: str, severity: float, seed: int) -> None:
        if kind not in KINDS:
            raise InputError(f"perturbation {kind!r}: choose one of {', '.join(KINDS)}")
        self.kind = kind
        self.severity = float(severity)
        self.seed = int(seed)
        self.k = 0
        self.weights = drift_weights(np.random.default_rng([self.seed, 53]))

    def __call__(self, touch: Touch) -> Touch:
        rng = np.random.default_rng([self.seed, 59, self.k])
        k, s = self.k, self.severity
        self.k += 1
        if self.kind == "drift":
            return lighting_drift(touch, k, s, self.weights)
        if self.kind == "noise":
            return sensor_noise(touch, s, rng)
        if self.kind == "partial":
            return partial_contact(touch, s, float(rng.uniform(0.0, 2.0 * np.pi)))
        if self.kind == "low_force":
            return low_force(touch, s)
        return worn_gel(touch, s)
