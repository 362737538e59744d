"""The session report (``session_html``, ``write_session_report``): accuracy with its Wilson
interval, the context, each trial with its outcome, a confusion matrix of the fabrics and
accuracy against comparison touches."""

from __future__ import annotations

import json
import shlex
from pathlib import Path

from ...core.stats import wilson
from ..record import not_sure, read_config, read_record, read_result, stop_text
from .chart import line_chart
from .context import MISSING, run_context
from .page import REPORT, duration, esc, fmt, page, table, when, write_page
from .timing import time_split


def anytime_answers(rec: dict, comps: list[str]) -> list[tuple[int, str]]:
    """(comparison touches so far, argmax platform) after every recorded decision."""
    out = []
    for dec in rec["decisions"]:
        b = dec.get("belief") or []
        if len(b) == len(comps) and b:
            out.append((int(sum(dec.get("touches") or [0])),
                        comps[max(range(len(b)), key=b.__getitem__)]))
    return out


def run_rows(d: Path, trials: list[dict]) -> list[list[str]]:
    """The trial report's context rows (``run_context``: version and commit, command, preset,
    model, strategy, stop, rounds cap, settings changed from the preset, simulation or robot,
    profiles, host) over the session's started trials: each value once, with the trials it
    holds for where they differ (a resume with other options, another commit)."""
    cells: dict[str, dict[str, list[str]]] = {}
    for r in trials:
        rd = d / r["record"]
        if not (rd / "config.json").is_file():
            continue
        for k, v in run_context(read_config(rd), read_result(rd), command_id="").items():
            if k != "seed":                      # each trial's own (the session's seeds)
                cells.setdefault(k, {}).setdefault(v, []).append(str(r["id"]))
    if not cells:
        return [["how it ran", MISSING + " (no trial started)"]]
    rows = []
    for k, by_value in cells.items():
        if len(by_value) == 1:
            rows.append([k, next(iter(by_value))])
        else:
            rows.append([k, "<br>".join(f"{v} <span class='muted'>(trial{'s' * (len(ids) > 1)} "
                                        f"{esc(', '.join(ids))})</span>"
                                        for v, ids in by_value.items())])
    return rows


def session_html(folder: str | Path) -> str:
    """The session report of session folder ``folder`` as HTML text."""
    from .. import session as sess
    d = Path(folder)
    summ = sess.summary(d)
    started = sess.load_started(d)
    evs = sess.events(d)
    done = [r for r in summ["trials"] if r["done"] and not r.get("skipped")]
    acc = summ["accuracy"]
    k = sum(r["correct"] is True for r in done)
    unsure_n = summ.get("not_sure", 0)
    lo, hi = wilson(k, len(done))
    times = [e["time"] for e in evs if e.get("time")]
    span = (max(times) - min(times)) if times else None
    parts = [f"<h1>Session {esc(summ['name'])}</h1>",
             f"<p class='answer' id='accuracy'>accuracy <b>{fmt(acc, '.3f')}</b> "
             f"({k} of {len(done)} trials correct, <span id='not-sure-count'>{unsure_n}"
             f"</span> not sure; 95 % interval (Wilson) "
             f"<span id='accuracy-ci'>{lo:.2f}&ndash;{hi:.2f}</span>, n = "
             f"<span id='n'>{len(done)}</span>; {summ['done']} of {summ['total']} trials "
             "done)</p>"]
    set_ = started.get("settings") or {}
    starts = [e for e in evs if e.get("event") in ("started", "resumed")]
    ends = [e for e in evs if e.get("event") in ("session_ended", "run_ended")]
    info = [["trial file", f"<code>{esc(started.get('path'))}</code>"],
            ["first event", esc(when(min(times) if times else None))],
            ["last event", esc(when(max(times) if times else None))],
            ["duration", f"<span id='duration'>{duration(span)}</span> (first to last "
                         f"event; {len(starts)} start(s), {len(ends)} interruption(s))"],
            ["settings", ", ".join(f"<code>{esc(k_)}={esc(json.dumps(v))}</code>"
                                   for k_, v in sorted(set_.items())) or "not recorded"]]
    info += run_rows(d, summ["trials"])
    for e in ends:
        info.append(["interrupted", f"{esc(when(e.get('time')))}: {esc(e.get('reason'))}"])
    if summ["done"] < summ["total"]:
        # the last run's --trials while one of them is not done: its interrupted trial first
        asked = (starts[-1].get("trials_asked") if starts else None) or []
        left = {r["id"] for r in summ["trials"] if not r["done"]}
        words = ["tactex", "graph", "run", "--session-dir", str(d.resolve())]
        if left & set(asked):
            words += ["--trials", ",".join(asked)]
        info.append(["continue with", f"<code id='resume-command'>"
                                      f"{esc(shlex.join(words))}</code>"])
    parts.append(table([], info, left=2, cls="context", tid="context"))
    ops = [e for e in evs if e.get("event") == "operator"]
    parts.append(f"<h2>Operator actions</h2><p class='muted'>pause, resume, abort, skip and "
                 f"redo, each as asked (key: the terminal; service: a ROS service call, the "
                 f"layout's buttons); <span id='operator-count'>{len(ops)}</span> in all</p>")
    parts.append(table(["time", "action", "trial", "by"], [
        [esc(when(e.get("time"))), f"<span class='operator'>{esc(e.get('action'))}</span>",
         esc(e.get("trial")),
         esc(e.get("by")) + (f", {esc(e['caller'])}" if e.get("caller") else "")]
        for e in ops], left=4, cls="operator-actions", tid="operator-actions") if ops else
        "<p class='muted' id='operator-actions-none'>none</p>")
    rows = []
    curves: list[list[tuple[int, bool]]] = []
    fabrics: list[str] = []
    conf: dict[tuple[str, str], int] = {}
    # a cut session: started trials past the summarised ones are left out
    for r, t in zip(summ["trials"], started["trials"], strict=False):
        # a link only to a report on disk (a trial never started has none)
        link = (f"<a href='{esc(r['record'])}/{REPORT}'>{esc(r['id'])}</a>"
                if (d / r["record"] / REPORT).is_file() else esc(r["id"]))
        if not r["done"]:
            state = "not started" if not (d / r["record"]).is_dir() else "unfinished"
            rows.append([link, esc(list(t["placement"].values())[0]), "", "", "", "", "",
                         f"<span class='muted'>{state}</span>"])
            continue
        if r.get("skipped"):
            rows.append([link, esc(list(t["placement"].values())[0]), "",
                         esc(r["touches"]), "", "", "skipped by the operator",
                         "<span class='muted skipped'>skipped</span>"])
            continue
        placement = t["placement"]
        ref_fab = list(placement.values())[0]
        got = placement.get(r["prediction"], "?")
        for f in (ref_fab, got):
            if f not in fabrics:
                fabrics.append(f)
        conf[(ref_fab, got)] = conf.get((ref_fab, got), 0) + 1
        res = read_result(d / r["record"]) or {}
        mark = ("<span class='muted'>not sure</span>" if r.get("not_sure") else
                "<span class='ok'>yes</span>" if r["correct"] else "<span class='bad'>no</span>")
        stop_conf = (read_config(d / r["record"]).get("trial") or {}).get("stop_confidence")
        rec = read_record(d / r["record"], images=False)
        dec = rec["decisions"]
        comps_ = list(placement)[1:]
        b = (dec[-1].get("belief") or []) if dec else []
        p_b = b[comps_.index(r["prediction"])] if r["prediction"] in comps_ and \
            len(b) == len(comps_) else None
        unsure = bool(r.get("not_sure")) or not_sure(res, stop_conf, p_b)
        n_cmp = sum(bool(x.get("accepted")) and x.get("platform_id") in comps_
                    for x in rec["touches"])
        split = time_split(rec)
        rows.append([link, esc(ref_fab), f"{esc(r['prediction'])} ({esc(got)})"
                     + (" <span class='muted'>not sure</span>" if unsure else ""),
                     esc(r["touches"]), esc(n_cmp), fmt(split["total"], ".1f"),
                     esc(stop_text(res, unsure)), mark])
        curves.append([(n, a in t["truth"]) for n, a in anytime_answers(rec, comps_)])
    parts.append("<h2>Trials</h2>" + table(
        ["trial", "reference fabric", "answer", "touches (all)", "touches (comparisons)",
         "time [s]", "stop", "correct"], rows, left=3, cls="trials"))
    if done:
        touches = [r["touches"] for r in done]
        parts.append(f"<p>touches per trial (all, reference included): mean "
                     f"{sum(touches) / len(touches):.1f}, min {min(touches)}, max "
                     f"{max(touches)}; time per trial counts every run of a resumed trial</p>")
    parts.append("<h2>Confusion matrix of the fabrics</h2><p class='muted'>rows: the "
                 "reference's fabric; columns: the fabric on the platform the trial chose</p>")
    head = ["reference \\ chosen"] + fabrics
    refs = [f for f in fabrics if any(a == f for a, _ in conf)]
    mrows = [[esc(a)] + [(f"<b>{conf.get((a, b), 0)}</b>" if a == b else
                           str(conf.get((a, b), 0) or "")) for b in fabrics] for a in refs]
    parts.append(table(head, mrows, left=1, cls="confusion"))
    parts.append("<h2>Accuracy against comparison touches</h2><p class='muted'>the answer "
                 "each trial would have given had it stopped after t touches of the "
                 "comparison platforms (trials that ended earlier keep their answer); shaded: "
                 "the 95 % Wilson interval; above each point: n, the trials with a decision "
                 "by then</p>")
    if curves and any(curves):
        t_max = max(n for c in curves for n, _ in c)
        t_min = min(n for c in curves for n, _ in c if c)
        pts, band, notes = [], [], []
        for t_ in range(t_min, t_max + 1):
            hits = []
            for c in curves:
                seen = [ok for n, ok in c if n <= t_]
                if seen:
                    hits.append(seen[-1])
            if hits:
                a, b_ = wilson(sum(hits), len(hits))
                pts.append((float(t_), sum(hits) / len(hits)))
                band.append((float(t_), a, b_))
                notes.append((float(t_), f"n={len(hits)}"))
        parts.append(line_chart({"accuracy": pts}, chart_id="accuracy-chart",
                                x_label="touches of the comparison platforms",
                                y_label="accuracy", bands={"accuracy": band},
                                notes={"accuracy": notes}))
    return page(f"tactex session {summ['name']}", "".join(parts))


def write_session_report(folder: str | Path) -> Path:
    """Write ``<folder>/report.html`` for a session folder (atomically)."""
    d = Path(folder)
    return write_page(d / REPORT, session_html(d))
