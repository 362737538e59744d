"""Touch sources: where the images of a trial come from (no ROS here).

``open_source(spec)`` accepts ``replay:DIR[:one-session]`` (recorded presses) and
``sim[:difficulty][:recorded]`` (procedural fabrics). Every source is a ``TouchSource`` (``base.py``): ``classes``,
``trial(platform_classes, seed)`` returning ``touch(platform) -> Touch`` (platform 0 = the
reference), its scene draw and its no-contact frame.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Literal, overload

import numpy as np

from ..core.errors import InputError
from .base import TouchSource

if TYPE_CHECKING:
    from .simulated import SimSource


@overload
def open_source(spec: Literal["sim", "sim:recorded"]) -> SimSource: ...
@overload
def open_source(spec: str) -> TouchSource: ...


def open_source(spec: str) -> TouchSource:
    """Open a touch source from its command-line spec."""
    kind, _, arg = spec.partition(":")
    if kind == "replay":
        one = arg.endswith(":one-session")
        folder = arg[:-len(":one-session")] if one else arg
        if not folder:
            raise InputError("source replay needs a folder: replay:DIR[:one-session]")
        from .replay import ReplaySource
        return ReplaySource(folder, one_session=one)
    if kind == "sim":
        from ..core.paths import config_dir
        from .simulated import SimSource
        parts = arg.split(":") if arg else []
        recorded = bool(parts) and parts[-1] == "recorded"
        if recorded:
            parts = parts[:-1]
        if len(parts) > 1:
            raise InputError(f"source {spec!r}: use sim[:difficulty][:recorded]")
        try:
            return SimSource(parts[0] if parts and parts[0] else "medium",
                             catalogue=config_dir() / "fabrics.yaml", recorded=recorded)
        except InputError as exc:
            raise InputError(f"source {spec!r}: {exc}") from None
    raise InputError(f"unknown source {spec!r}; use replay:DIR[:one-session] or "
                      "sim[:easy|medium|hard|<number>][:recorded]")


def assign_platforms(classes: list[str], comparisons: int, chosen: list[str] | None,
                     reference: str | None, seed: int) -> tuple[list[str], int]:
    """Classes of [reference, comparison 1..N] and the index (1..N) of the true match.

    ``chosen``: the comparison classes in platform order (None: ``comparisons`` drawn from
    ``classes``, seeded); ``reference``: its class (None: one of the comparisons, seeded)."""
    rng = np.random.default_rng([seed, 5])
    if chosen:
        unknown = [c for c in chosen if c not in classes]
        if unknown:
            raise InputError(f"--classes: unknown class(es) {unknown}; available: "
                             f"{', '.join(classes)}")
        comps = list(chosen)
    else:
        if len(classes) < comparisons:
            raise InputError(f"--comparisons {comparisons}: the source has only "
                             f"{len(classes)} classes")
        comps = [str(c) for c in rng.choice(classes, comparisons, replace=False)]
    if len(comps) < 2:
        raise InputError("--classes: a trial needs at least 2 comparison platforms")
    if reference is None:
        reference = comps[int(rng.integers(len(comps)))]
    if reference not in comps:
        raise InputError(f"--reference {reference!r} is not one of the comparison classes "
                         f"{comps}")
    return [reference] + comps, comps.index(reference) + 1


def trial_scene(src: TouchSource, comparisons: int, seed: int,
                chosen: list[str] | None = None, reference: str | None = None
                ) -> tuple[list[str], int]:
    """The scene of a trial on source ``src``: platform classes [reference, comparisons...] and
    the true match (1..N). Without ``chosen``, a source that draws its own scenes (the
    simulator at its difficulty) draws the comparisons from ``seed``; others draw classes."""
    if chosen is None:
        chosen = src.draw_scene(comparisons, seed)
    return assign_platforms(src.known_classes, comparisons, chosen, reference, seed)
