"""Experiments: one command each (``tactex experiment <name>``), no ROS.

Every experiment writes a results folder (``--out``, default ``results/<name>``) holding
``config.json`` (arguments, versions, seeds), JSON results and PNG figures, and shows progress
for anything longer than a few seconds. Shared helpers live in ``common``.
"""
