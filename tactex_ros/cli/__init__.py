"""The ``tactex`` command: ``main.py`` (parser, trial, prepare, weights, bench latency) and one
module per command group (``experiment``, ``graph``, ``sim``)."""

from .main import main

__all__ = ["main"]
