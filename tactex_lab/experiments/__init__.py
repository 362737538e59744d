"""Experiments: one command each (``tactex experiment <name>``), no ROS.

Every experiment writes a results folder (``--out``, default ``results/<name>``) holding
``config.json`` (arguments, versions, seeds), JSON results and PNG figures, and shows progress
for anything longer than a few seconds. Each command module imports only the shared helpers,
never another command: ``runner`` (the one job runner: joblib, or Ray with ``--backend ray``),
``trials`` (trial files), ``common`` (results folder, ``--set`` parser, progress display,
accuracy-at-budget reader), ``curves`` (belief curves of real-press scenes) and ``protocol``
(the class-disjoint protocol of ``real`` and ``unseen``); statistics and figures come from ``analysis`` (``stats``,
``charts``). Benchmarks that print figures: ``bench/``.
"""
