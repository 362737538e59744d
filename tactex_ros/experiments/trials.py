"""Trial files: fixed scenes of reference + comparison platforms (e.g. the thesis's human study).

Format (YAML)::

    name: human_study
    trials:
      - {id: 1, reference: 23, comparisons: [4, 8, 23, 7]}
      - {id: 2, reference: wool_jersey, comparisons: [wool_jersey, polar_fleece, ...]}

``id`` any scalar, unique (kept as a string); ``reference`` and every comparison are either an
integer, the fabric number of the simulator's catalogue (``config/fabrics.yaml``, resolved with
``SimSource.by_number``), or a class name of the source (a fabric name, or a class folder of a
replay source). The reference must be one of the comparisons: that platform is the true match.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any


from ..core.errors import TactexError
from ..sources.base import TouchSource
from ..trialfile import find_trial_file, load_trials  # noqa: F401  (the format lives in the product)


def class_name(source: TouchSource, item: Any) -> str:
    """A trial-file entry -> the source's class name (int = catalogue fabric number)."""
    if isinstance(item, bool):
        raise TactexError(f"trial entry {item!r}: expected a fabric number or a class name")
    if isinstance(item, int):
        try:
            return source.by_number(item)
        except TactexError as exc:
            raise TactexError(f"trial entry {item}: {exc}") from None
    name = str(item)
    known = source.known_classes
    if name not in known:
        raise TactexError(f"trial entry {name!r}: not a class of the source; available: "
                          f"{', '.join(known)}")
    return name


def platform_classes(source: TouchSource, trial: dict) -> list[str]:
    """[reference, comparison 1..C] class names of one trial."""
    return [class_name(source, trial["reference"])] + [class_name(source, c)
                                                       for c in trial["comparisons"]]
