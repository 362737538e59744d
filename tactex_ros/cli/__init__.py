"""The ``tactex`` command: ``main.py`` (parser, trial, prepare, weights) and one module per
command group (``bench``, ``experiment``, ``graph``, ``sim``)."""

from .main import main

__all__ = ["main"]
