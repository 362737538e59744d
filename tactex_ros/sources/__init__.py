"""Touch sources: where the images of a trial come from (no ROS here).

``open_source(spec)`` accepts ``replay:DIR`` (recorded presses) and ``sim[:difficulty]``
(procedural fabrics). Every source has ``classes`` and ``trial(platform_classes, seed)``, which
returns a touch function ``touch(platform) -> RGB uint8 (240, 320, 3)``, platform 0 = reference.
"""

from __future__ import annotations

from ..core.errors import TactexError


def open_source(spec: str):
    """Open a touch source from its command-line spec."""
    kind, _, arg = spec.partition(":")
    if kind == "replay":
        if not arg:
            raise TactexError("source replay needs a folder: replay:DIR")
        from .replay import ReplaySource
        return ReplaySource(arg)
    if kind == "sim":
        from ..sim.source import SimSource
        return SimSource(arg or "medium")
    raise TactexError(f"unknown source {spec!r}; use replay:DIR or sim[:easy|medium|hard|<number>]")
