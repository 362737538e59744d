"""The ``tactex`` command: ``main.py`` (parser, trial, prepare, the plug-in commands), one
module per command group (``graph_commands``, ``sim_commands``, ``report``, ``robot``) and the
option helpers they share (``options``); the lab adds its commands through entry points.
Imports point one way: ``main`` -> command modules -> ``options`` (no module imports ``main``
but ``reference``, which documents its parser)."""
