"""Error type for bad input: configs, parameters, images, checkpoints, commands."""

from __future__ import annotations


class TactexError(ValueError):
    """Bad input, with a message that names the thing that was wrong.

    The command line turns it into exit status 2; nodes refuse to configure with it.
    """
