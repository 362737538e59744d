"""``tactex report FOLDER``: the reports written again (``regenerate``): a trial record gets its
report, a session folder every trial's and the session's, and any other folder holding records
(trial records and session folders, nested at any depth) each of theirs and ``index.html``
listing them (``index_html``): per session its date, trials done, accuracy and time; per trial
its date, session, scene, answer, verdict (correct, wrong, not sure, ...), touches, time and a
link to its report. A damaged record is listed with what is wrong and gets no link."""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path

from ...core.errors import InputError
from ..record import read_config, read_record
from .outcome import outcome
from .page import REPORT, duration, esc, fmt, page, table, when, write_page
from .session_page import write_session_report
from .timing import time_split
from .trial_page import write_trial_report

INDEX = "index.html"            # the report index of a folder of records
_DAMAGED = (KeyError, TypeError, AttributeError, IndexError, ValueError)


def regenerate(folder: str | Path) -> list[Path]:
    """``tactex report``: a trial record -> its report; a session folder -> every trial's
    report and the session report; a folder holding records -> each of their reports and the
    index (last). InputError when ``folder`` is none of these, or its one record or session
    is damaged."""
    d = Path(folder)
    try:
        return _regenerate(d)
    except InputError:
        raise
    except _DAMAGED as exc:
        # a file of the folder holds other types than a record's: refused, not a traceback
        raise InputError(f"{str(d)!r}: a file of the record or session is damaged "
                         f"({type(exc).__name__}: {exc})") from None


def _is_record(d: Path) -> bool:
    return (d / "config.json").is_file() or (d / "touches.jsonl").is_file()


def _is_session(d: Path) -> bool:
    from ..session import SESSION_FILE
    return (d / SESSION_FILE).is_file()


def session_records(d: Path) -> list[Path]:
    """The trial records of session folder ``d`` (a redone trial's superseded records left
    out), in name order."""
    return [p.parent for p in sorted(d.glob("trial_*/config.json"))
            if ".superseded." not in p.parent.name]


def _regenerate(d: Path) -> list[Path]:
    from .. import session as sess
    if _is_session(d):
        out = [write_trial_report(p.parent) for p in sorted(d.glob("trial_*/config.json"))]
        return out + [write_session_report(d)]
    if _is_record(d):
        return [write_trial_report(d)]
    sessions, trials = find_records(d)
    if not sessions and not trials:
        raise InputError(f"{str(d)!r} is neither a trial record (config.json, touches.jsonl) "
                         f"nor a session folder ({sess.SESSION_FILE}) and holds none")
    written: list[Path] = []
    problems: dict[Path, str] = {}
    for p in sessions + trials:
        try:
            written += _regenerate(p)
        except (InputError, *_DAMAGED) as exc:        # listed as damaged, the rest go on
            problems[p] = str(exc) if isinstance(exc, InputError) else \
                f"{type(exc).__name__}: {exc}"
    return written + [write_page(d / INDEX, index_html(d, problems))]


def find_records(root: Path) -> tuple[list[Path], list[Path]]:
    """(session folders, trial records outside a session) under ``root``, at any depth, in
    path order; hidden folders are skipped, nothing below a record or a session is looked at."""
    sessions, trials = [], []
    for here, dirs, _files in os.walk(root):
        p = Path(here)
        dirs[:] = sorted(n for n in dirs if not n.startswith("."))
        if p != root and _is_session(p):
            sessions.append(p)
            dirs[:] = []
        elif p != root and _is_record(p):
            trials.append(p)
            dirs[:] = []
    return sessions, trials


@dataclass
class _Row:
    start: float | None
    cells: list[str]


def _link(root: Path, report: Path, text: str) -> str:
    if not report.is_file():
        return esc(text)
    return f"<a href='{esc(Path(os.path.relpath(report, root)).as_posix())}'>{esc(text)}</a>"


def _trial_row(root: Path, d: Path, session: str) -> _Row:
    rec = read_record(d, images=False)
    cfg = read_config(d)
    out = outcome(d, rec, cfg)
    run = cfg.get("run") or {}
    starts = [t["requested"] for t in rec["touches"] if t.get("requested")]
    start = run.get("started") or (min(starts) if starts else None)
    ex = cfg.get("cli") or cfg.get("explorer") or {}
    scene = Path(ex.get("scene_file") or "").name or ex.get("source") or \
        ("scene.yaml" if (d / "scene.yaml").is_file() else "")
    answer = ""
    if out.finished and not out.skipped:
        answer = esc(out.prediction) + (f" ({esc(out.fabrics[out.prediction])})"
                                        if out.prediction in out.fabrics else "")
    cls = {"correct": "ok", "wrong": "bad"}.get(out.verdict, "muted")
    return _Row(start, [esc(when(start)), esc(session), _link(root, d / REPORT, d.name),
                        esc(scene), answer,
                        f"<span class='{cls} verdict'>{esc(out.verdict)}</span>",
                        esc(out.touches), fmt(time_split(rec)["total"], ".1f")])


def _session_row(root: Path, d: Path) -> _Row:
    from .. import session as sess
    summ = sess.summary(d)
    times = [e["time"] for e in sess.events(d) if e.get("time")]
    start = min(times) if times else None
    span = (max(times) - start) if times else None
    return _Row(start, [esc(when(start)), _link(root, d / REPORT, summ["name"]),
                        f"{summ['done']} of {summ['total']}", esc(sess.accuracy_text(summ)),
                        esc(summ.get("not_sure", 0)), esc(duration(span))])


def index_html(root: str | Path, problems: dict[Path, str] | None = None) -> str:
    """The report index of folder ``root``: its sessions, then every trial (those of the
    sessions too), newest first; ``problems``: record or session -> why it is damaged (listed
    apart, without a link)."""
    root = Path(root)
    problems = dict(problems or {})
    sessions, trials = find_records(root)
    srows, trows = [], []
    for sd in sessions:
        if sd in problems:
            continue
        try:
            srows.append(_session_row(root, sd))
            rows = [(p, sd.name) for p in session_records(sd)]
        except (InputError, *_DAMAGED) as exc:
            problems[sd] = str(exc)
            continue
        for p, name in rows:
            try:
                trows.append(_trial_row(root, p, name))
            except (InputError, *_DAMAGED) as exc:
                problems[p] = str(exc)
    for p in trials:
        if p in problems:
            continue
        try:
            trows.append(_trial_row(root, p, ""))
        except (InputError, *_DAMAGED) as exc:
            problems[p] = str(exc)

    def newest_first(rows: list[_Row]) -> list[list[str]]:
        return [r.cells for r in sorted(rows, key=lambda r: -(r.start or 0.0))]
    parts = [f"<h1>Reports in {esc(root.name or str(root))}</h1>",
             f"<p><span id='session-count'>{len(srows)}</span> session(s), <span "
             f"id='trial-count'>{len(trows)}</span> trial(s); newest first; a not-sure answer "
             "is never counted as correct</p>"]
    if srows:
        parts.append("<h2>Sessions</h2>" + table(
            ["date", "session", "trials done", "accuracy", "not sure", "time"],
            newest_first(srows), left=2, cls="sessions", tid="sessions"))
    parts.append("<h2>Trials</h2>" + table(
        ["date", "session", "trial", "scene", "answer", "verdict", "touches", "time [s]"],
        newest_first(trows), left=6, cls="trials", tid="trials"))
    if problems:
        parts.append("<h2>Damaged</h2>" + table(
            ["folder", "what is wrong"],
            [[esc(Path(os.path.relpath(p, root)).as_posix()), esc(why)]
             for p, why in sorted(problems.items())], left=2, cls="damaged", tid="damaged"))
    return page(f"tactex reports {root.name}", "".join(parts))
