"""Guards against the failure modes found by ``tactex experiment stability``.

- **No-contact and blank touches** (``ContactGuard``): a touch that shows no contact carries no
  texture; trained on, it teaches the network a "blank" look for whichever platform it was filed
  under, and as the reference it makes every answer a guess. Two checks:

  1. *flatness*, needs nothing else: mean |blur5(frame) - blur_sigma8(frame)| in grey levels, the
     band between sensor noise and vignetting. A real or simulated no-contact frame scores about
     0.5-1.2 (noise and gel structure), a flat frame (dead camera, lost stream, the stability
     experiment's ``blank`` perturbation) about 0.2. Rejected below ``flat_min`` (0.35).
  2. *contact against a no-contact reference* of the same sensor session, when one was given
     (``set_reference``): mean |blur5(frame) - blur5(reference)| after removing the per-channel
     mean difference (so lighting drift does not count as contact). Measured: no contact 0.35-0.6,
     real octopi-dev contact frames 1.26-4.5, simulated presses at nominal depth 0.92-5.0, at
     0.02-0.1 mm 0.5-0.7. Rejected below ``contact_min`` (0.8).

- **Partial contact** (``ContactGuard.inspect``, ``LearnerConfig.contact_region_min``): a touch
  whose object covered only part of the gel (tilted platform, a fold, the edge of a sample)
  describes less texture and more flat gel, and the descriptor's every part shifts with the
  covered share (``tactex experiment stability-real``: the shipped method's first break on
  replayed real presses). Detected from the touch itself: the *contact region*
  (``contact_region``: |blur(frame) - blur(its no-contact frame)| summed over channels, smoothed
  at ``REGION_SIGMA`` px, above ``REGION_LEVEL`` grey levels, inside the descriptor's border)
  covers less than ``contact_region_min`` of the frame. Measured on 50 octopi-dev presses: the
  region covers 0.66-1.0 of the frame (median 0.89); with half the contact masked, 0.3-0.6. Such
  a touch is kept, flagged, and described over its contact region only
  (``texture.describe_difference(d, region)``), as if the contact filled the frame.

- **A recorded press** (``press_verdict``): the guard's check of one press against its own
  no-contact frame, for recordings of separate sensor sessions: presses that reach a
  descriptor without a trial (``tactex prepare``'s library, the lab's cached replays) and the
  touches of a replayed trial (``engine.refusing_no_contact``), so they keep only what a trial
  on the robot would keep.

- **Degenerate scores**: handled where the choice is made (``strategies.break_ties``); the engine
  flags rounds whose scores are all equal (``RoundRecord.degenerate``).
- **Diverging training**: handled in the learner (gradient clipping, non-finite steps skipped,
  weights restored and learning rate halved when a round goes non-finite).
"""

from __future__ import annotations

from dataclasses import replace

import cv2
import numpy as np

from .contact import blur, contact_score
from .texture import BORDER, contact_difference, describe_difference
from .errors import InputError
from .touch import Touch, validate_frame

REGION_SIGMA = 6.0          # px: smoothing of the contact difference before the region test
REGION_LEVEL = 3.0          # grey levels (sum over channels): the region's threshold


def flatness_score(frame: np.ndarray) -> float:
    """Texture between noise and vignetting scale, grey levels (low = flat frame)."""
    a = blur(frame)
    b = cv2.GaussianBlur(frame, (0, 0), 8).astype(np.float32)
    return float(np.abs(a - b).mean())


def contact_region(frame: np.ndarray, no_contact: np.ndarray) -> np.ndarray:
    """(240 - 2 BORDER, 320 - 2 BORDER) bool: where a contact frame differs from its no-contact
    frame (uint8 RGB (240, 320, 3) both) by more than ``REGION_LEVEL`` grey levels summed over
    channels, after smoothing the difference at ``REGION_SIGMA`` px."""
    d = (cv2.GaussianBlur(frame.astype(np.float32), (0, 0), 0.8) -
         cv2.GaussianBlur(no_contact.astype(np.float32), (0, 0), 0.8))
    m = np.abs(d).sum(axis=2)[BORDER:-BORDER, BORDER:-BORDER]
    return cv2.GaussianBlur(m, (0, 0), REGION_SIGMA) > REGION_LEVEL


class ContactGuard:
    """Accept or reject a touch; ``check(frame)`` returns (ok, reason or ''), ``inspect(touch)``
    also finds a partial contact (``region_min`` > 0) and returns the touch to store."""

    def __init__(self, flat_min: float = 0.35, contact_min: float = 0.8,
                 region_min: float = 0.0, with_height_map: bool = False) -> None:
        self.flat_min = float(flat_min)
        self.with_height_map = bool(with_height_map)   # the region descriptor's height map
        self.contact_min = float(contact_min)
        self.region_min = float(region_min)
        self._ref: np.ndarray | None = None

    def set_reference(self, frame: np.ndarray | None) -> None:
        """No-contact frame of the same sensor session (None = flatness check only)."""
        self._ref = None if frame is None else blur(frame)

    @property
    def has_reference(self) -> bool:
        return self._ref is not None

    def check(self, frame: np.ndarray) -> tuple[bool, str]:
        if self.flat_min > 0:
            f = flatness_score(frame)
            if f < self.flat_min:
                return False, f"blank frame: texture {f:.2f} < {self.flat_min:g} grey levels"
        if self._ref is not None and self.contact_min > 0:
            c = contact_score(frame, self._ref, drift_robust=True)
            if c < self.contact_min:
                return False, (f"no contact: {c:.2f} < {self.contact_min:g} grey levels "
                               "against the no-contact reference")
        return True, ""

    def inspect(self, touch: Touch) -> tuple[bool, str, Touch]:
        """``check`` on the touch's frame, then the partial-contact test: (ok, reason or '',
        the touch to store). A touch whose contact region (against its own no-contact frame)
        covers less than ``region_min`` of the frame comes back with its ``descriptor`` taken
        over that region and the reason ``partial contact: ...`` (ok stays True); a touch that
        already has a descriptor or no no-contact frame is not tested."""
        ok, reason = self.check(touch.frame)
        if not ok or self.region_min <= 0 or touch.no_contact is None \
                or touch.descriptor is not None:
            return ok, reason, touch
        region = contact_region(touch.frame, touch.no_contact)
        share = float(region.mean())
        if share >= self.region_min or not region.any():
            return True, "", touch
        x = describe_difference(contact_difference(touch.frame, touch.no_contact), region,
                                self.with_height_map)
        return True, (f"partial contact: region {share:.2f} < {self.region_min:g} of the "
                      "frame, described over the region"), replace(touch, descriptor=x)


def press_verdict(touch: Touch, flat_min: float = 0.35, contact_min: float = 0.8
                  ) -> tuple[bool, str]:
    """``ContactGuard.check`` of a recorded press's frame with the press's own no-contact frame
    as the reference (the flatness check only when it has none, or an unusable one): (ok,
    reason or ''). A frame that is not a sensor frame (``validate_frame``) is refused with
    the validation's reason."""
    try:
        frame = validate_frame(touch.frame, "touch frame")
    except InputError as exc:
        return False, str(exc)
    try:
        reference = (None if touch.no_contact is None
                     else validate_frame(touch.no_contact, "no-contact frame"))
    except InputError:
        reference = None
    guard = ContactGuard(flat_min, contact_min)
    guard.set_reference(reference)
    return guard.check(frame)
