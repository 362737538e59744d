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

- **Degenerate scores**: handled where the choice is made (``strategies.break_ties``); the engine
  flags rounds whose scores are all equal (``RoundRecord.degenerate``).
- **Diverging training**: handled in the learner (gradient clipping, non-finite steps skipped,
  weights restored and learning rate halved when a round goes non-finite).
"""

from __future__ import annotations

import cv2
import numpy as np

from .contact import blur, contact_score


def flatness_score(frame: np.ndarray) -> float:
    """Texture between noise and vignetting scale, grey levels (low = flat frame)."""
    a = blur(frame)
    b = cv2.GaussianBlur(frame, (0, 0), 8).astype(np.float32)
    return float(np.abs(a - b).mean())


class ContactGuard:
    """Accept or reject a touch frame; ``check`` returns (ok, reason or '')."""

    def __init__(self, flat_min: float = 0.35, contact_min: float = 0.8) -> None:
        self.flat_min = float(flat_min)
        self.contact_min = float(contact_min)
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
