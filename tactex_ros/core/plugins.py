"""Plug-ins found by name through Python entry points, without importing them until used.

The product names no plug-in package: a distribution declares entry points in a group (the
repository's ``setup.cfg`` declares the lab's), ``importlib.metadata`` lists them from the
installed metadata (nothing is imported), and ``load`` imports the one asked for.

Groups: ``tactex.learners`` (name = ``learner.model``, a ``CnnSettings``
tag, object = a factory ``(num_classes, cfg, seed) -> learner``, see ``core/learners.py``) and ``tactex.commands``
(object = ``add_commands(subparsers)`` adding ``tactex`` sub-commands, see ``cli/main.py``).
"""

from __future__ import annotations

from functools import cache
from importlib.metadata import EntryPoint, entry_points
from typing import Any

from .errors import InputError

LEARNERS = "tactex.learners"
COMMANDS = "tactex.commands"


@cache
def available(group: str) -> dict[str, EntryPoint]:
    """{name: entry point} of ``group``, first declaration of a name wins (a name declared by
    two installed distributions is one plug-in)."""
    out: dict[str, EntryPoint] = {}
    for ep in entry_points(group=group):
        out.setdefault(ep.name, ep)
    return out


def load(group: str, name: str) -> Any:
    """The object of plug-in ``name`` in ``group``, imported now. InputError when no installed
    distribution declares it or it cannot be imported (the reason named)."""
    ep = available(group).get(name)
    if ep is None:
        raise InputError(f"{name!r} needs a plug-in of group {group!r} that is not installed "
                         f"(installed: {', '.join(sorted(available(group))) or 'none'})")
    try:
        return ep.load()
    except ImportError as exc:
        raise InputError(f"plug-in {name!r} ({ep.value}) cannot be imported: {exc}") from None
