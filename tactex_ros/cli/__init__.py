"""The ``tactex`` command: ``main.py`` (parser, trial, prepare, the plug-in commands) and one
module per command group (``graph``, ``sim``); the lab adds its commands through entry points."""

from .main import main

__all__ = ["main"]
