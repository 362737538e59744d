"""The lab's ``tactex`` commands, each ``add_commands(subparsers)`` an entry point of group
``tactex.commands``: ``experiment``, ``bench``, ``weights``, ``sim compare``."""
