"""Reports a person reads: ``report.html`` per trial record and per study session.

Each is one self-contained HTML file (no network, no script: touch images inlined as base64
PNG, charts as inline SVG drawn here, the full-size view by CSS ``:focus``). Built from the
record folder alone (``record.read_record``, ``config.json``, ``scene.yaml``, ``events.jsonl``
and, for a session trial, the session's ``session.json`` / ``session_events.jsonl``), so
``tactex report FOLDER`` regenerates them at any time.

Trial report: the answer (or "not sure" when the trial stopped without reaching its stop
confidence) and its verdict where the truth is known; the context a person needs to trust and
reproduce it (date, version and commit, the command, preset, model, every setting that differs
from the preset's, stop threshold, rounds cap, simulation or robot, robot and sensor profiles,
scene); every platform with its fabric, marked chosen / true match / chosen but wrong, and its
touch images (click: full size beside the sensor's no-contact frame); the belief per comparison
against touches and against seconds, with the stop threshold and the fabric names; where the
time went (pressing, deciding, waiting); what happened (start, interruptions, resumes) on a
timeline; each round's chosen platform with its reason; every press with its time, force,
depth and failed attempts; for an unfinished trial, why and the command that continues it.

Session report: duration, settings, the trial report's context over the session's trials,
accuracy with its 95 % Wilson interval and n, every operator action, touches and time per trial
(each linked to its report where one is on disk; each trial report links back), a confusion
matrix of the fabrics, accuracy against comparison touches with its Wilson band and n per point.

Report index: ``tactex report DIR`` over a folder holding records and sessions writes
``index.html`` listing them (``index``).

The package, by what it draws: ``page`` (the skeleton and CSS from ``page.html``, formats,
tables), ``chart`` (``line_chart``), ``context`` (how a record was made, its scene and the
context table), ``timing`` (where a trial's time went), ``trial_page``, ``session_page`` and
``outcome`` (what a trial came to, for every page that shows it) and ``index``
(``regenerate``, ``index_html``: ``tactex report``).
"""

from __future__ import annotations

from ..record import not_sure
from .chart import COLOURS, line_chart
from .context import changed_settings, failed_attempts, run_info, scene_truth
from .index import index_html, regenerate
from .page import REPORT
from .session_page import anytime_answers, session_html, write_session_report
from .timing import time_split
from .trial_page import trial_html, write_trial_report

__all__ = ["COLOURS", "REPORT", "anytime_answers", "changed_settings", "failed_attempts",
           "index_html", "line_chart", "not_sure", "regenerate", "run_info", "scene_truth", "session_html",
           "time_split", "trial_html", "write_session_report", "write_trial_report"]
