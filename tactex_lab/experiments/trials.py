"""Trial files in the offline experiments: entries -> a source's class names.

The format and its loader live in the product (``tactex_ros/trial/trialfile.py``: ``load_trials``,
``find_trial_file``, re-exported here); ``class_name`` / ``platform_classes`` resolve an entry
(a catalogue fabric number or a class name) against a touch source.
"""

from __future__ import annotations

from typing import Any


from tactex_ros.core.errors import InputError
from tactex_ros.sources.base import TouchSource
from tactex_ros.trial.trialfile import find_trial_file, load_trials  # noqa: F401  (the format lives in the product)


def class_name(source: TouchSource, item: Any) -> str:
    """A trial-file entry -> the source's class name (int = catalogue fabric number)."""
    if isinstance(item, bool):
        raise InputError(f"trial entry {item!r}: expected a fabric number or a class name")
    if isinstance(item, int):
        try:
            return source.by_number(item)
        except InputError as exc:
            raise InputError(f"trial entry {item}: {exc}") from None
    name = str(item)
    known = source.known_classes
    if name not in known:
        raise InputError(f"trial entry {name!r}: not a class of the source; available: "
                         f"{', '.join(known)}")
    return name


def platform_classes(source: TouchSource, trial: dict) -> list[str]:
    """[reference, comparison 1..C] class names of one trial."""
    return [class_name(source, trial["reference"])] + [class_name(source, c)
                                                       for c in trial["comparisons"]]
