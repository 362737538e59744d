"""The two kinds of error the product raises, told apart by the exit status.

``InputError``: bad input (configs, parameters, images, checkpoints, commands) with a message
that names the thing that was wrong; the command line exits 2, nodes refuse to configure.
``TrialError``: a trial could not go on at run time (baseline touches failed, the node is
stopping, an answer did not come); the message says what failed; the command line exits 1.
``DeviceError`` (a ``TrialError``): a device named correctly is absent at run time (no camera
by that name, a camera that gives no frames, a robot whose state topic is silent): the same
command works once the device is there, so a node ends with exit status 1, not 2.
"""

from __future__ import annotations


class InputError(ValueError):
    """Bad input, with a message that names the thing that was wrong (exit status 2)."""


class TrialError(RuntimeError):
    """A run-time failure of a trial, with a message that says what failed (exit status 1)."""


class DeviceError(TrialError):
    """A device (camera, robot) is absent or silent at run time (exit status 1)."""
