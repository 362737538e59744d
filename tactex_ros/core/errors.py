"""The two kinds of error the product raises, told apart by the exit status.

``InputError``: bad input (configs, parameters, images, checkpoints, commands) with a message
that names the thing that was wrong; the command line exits 2, nodes refuse to configure.
``TrialError``: a trial could not go on at run time (baseline touches failed, the node is
stopping, an answer did not come); the message says what failed; the command line exits 1.
``DeviceError`` (a ``TrialError``): a device named correctly is absent at run time (no camera
by that name, a camera that gives no frames, a robot whose state topic is silent): the same
command works once the device is there, so a node ends with exit status 1, not 2.
``DeviceNotReady`` (a ``DeviceError``): the device is there but in a state that forbids the
work (a robot not in move mode: idle, reflex, user stop); the same command works once the
state is cleared: exit status 1.

Each class is caught where it is handled: a run-time state is never caught as bad input.
"""

from __future__ import annotations


class InputError(ValueError):
    """Bad input, with a message that names the thing that was wrong (exit status 2)."""


class TrialError(RuntimeError):
    """A run-time failure of a trial, with a message that says what failed (exit status 1)."""


class DeviceError(TrialError):
    """A device (camera, robot) is absent or silent at run time (exit status 1)."""


class DeviceNotReady(DeviceError):
    """A device is there but in a state that forbids the work, e.g. a robot not in move mode
    (exit status 1)."""
