"""The two kinds of error the product raises, told apart by the exit status.

``InputError``: bad input (configs, parameters, images, checkpoints, commands) with a message
that names the thing that was wrong; the command line exits 2, nodes refuse to configure.
``TrialError``: a trial could not go on at run time (baseline touches failed, the node is
stopping, an answer did not come); the message says what failed; the command line exits 1.
"""

from __future__ import annotations


class InputError(ValueError):
    """Bad input, with a message that names the thing that was wrong (exit status 2)."""


class TrialError(RuntimeError):
    """A run-time failure of a trial, with a message that says what failed (exit status 1)."""
