"""What every touch source offers (``TouchSource``): the replay source (``replay.py``,
recorded presses) and the simulator source (``simulated.py``) implement it, and trials, the job
runner and the experiments use only this, never the type of a source.

Frames are RGB uint8 arrays of shape (240, 320, 3); platform 0 is the reference, platforms
1..C the comparisons; class names are the source's (folder names, or catalogue fabrics).
"""

from __future__ import annotations

from typing import Protocol, runtime_checkable
from collections.abc import Callable

import numpy as np

from ..core.touch import Touch


@runtime_checkable
class TouchSource(Protocol):
    """A source of touches for trials."""

    @property
    def classes(self) -> list[str]:
        """The classes a scene is drawn from (replay: the folder's classes with a press file;
        simulator: the catalogue's fabrics, in catalogue order)."""
        ...

    @property
    def known_classes(self) -> list[str]:
        """Every class a platform may hold: ``classes`` and, for the simulator, the fabrics
        its scenes drew (``draw_scene``)."""
        ...

    def by_number(self, number: int) -> str:
        """The class numbered ``number`` (1-based, the catalogue's order); InputError where
        classes have no numbers (recorded presses) or the number is out of range."""
        ...

    def draw_scene(self, comparisons: int, seed: int) -> list[str] | None:
        """The ``comparisons`` classes of a scene the source draws itself (the simulator at its
        difficulty), or None: the scene is drawn from ``classes``."""
        ...

    def no_contact(self, seed: int) -> np.ndarray | None:
        """The sensor's no-contact frame of the trial with ``seed`` (the one its touches carry),
        or None where every touch brings its own (recorded presses)."""
        ...

    def trial(self, platform_classes: list[str], seed: int,
              depth_spread_mm: float | None = None) -> Callable[[int], Touch]:
        """The touch function of one trial: ``touch(platform) -> Touch`` for platform classes
        [reference, comparison 1..C], drawn from ``seed``. ``depth_spread_mm``: press depth
        uniform in the sensor's nominal depth +- this [mm] (simulator only; InputError
        elsewhere)."""
        ...
