"""The trial report (``trial_html``, ``write_trial_report``): the answer, the context, the
platforms and their touches, the belief charts, the timeline, the rounds and the presses."""

from __future__ import annotations

import shlex
from pathlib import Path

from ..record import read_config, read_record, stop_text
from .chart import line_chart
from .context import command_profiles, context_rows, failed_attempts, session_of
from .page import REPORT, duration, esc, fmt, page, png_data, table, when, write_page
from .outcome import outcome
from .timing import decision_seconds, time_split


def _timeline(d: Path, rec: dict) -> list[tuple[float, str, bool]]:
    """(epoch s, what happened, is an interruption) for the record and, in a session, the
    session's events about this trial."""
    out: list[tuple[float, str, bool]] = []
    cfg = read_config(d)
    run = cfg.get("run") or {}
    if run.get("started"):
        out.append((run["started"], "started" + (f": {run['command']}" if run.get("command")
                                                 else ""), False))
    for e in rec["events"]:
        kind, t = e.get("event"), e.get("time")
        if kind == "resumed":
            out.append((t or 0.0, f"resumed after touch {e.get('after_touch')} "
                                  f"({e.get('touches_replayed')} recorded touches replayed; "
                                  f"{e.get('how', '')})" + (f": {e['command']}" if
                                                           e.get("command") else ""), False))
        elif kind in ("trial_ended", "failed"):
            why = e.get("reason") or (e.get("result") or {}).get("error")
            out.append((t or 0.0, f"interrupted: {why}", True))
    sd = session_of(d)
    if sd is not None:
        from ..session import events as session_events
        tid = str((cfg.get("session") or {}).get("trial"))
        current = None                  # the trial running when an event came
        for e in session_events(sd):
            kind = e.get("event")
            if kind == "trial_started":
                current = str(e.get("trial"))
            if str(e.get("trial") or current) != tid or not e.get("time"):
                continue
            if kind == "awaiting_confirmation":
                out.append((e["time"], "placement prompted", False))
            elif kind == "confirmed":
                out.append((e["time"], f"placement confirmed by {e.get('by', '')}"
                            + (f" ({e['caller']})" if e.get("caller") else ""), False))
            elif kind in ("session_ended", "run_ended"):
                out.append((e["time"], f"interrupted: {e.get('reason')}", True))
            if kind in ("session_ended", "run_ended", "trial_done"):
                current = None
    res = rec.get("result") or {}
    if res and "error" not in res:
        end = max([x["time"] for x in rec["decisions"] if x.get("time")] or [0.0])
        out.append((end, f"finished: {res.get('prediction')} ({res.get('stop_reason')})",
                    False))
    return sorted(set(out), key=lambda x: x[0])


def _resume_command(d: Path, cfg: dict) -> str:
    """The command that continues the unfinished trial recorded in ``d``."""
    sd = session_of(d)
    words = command_profiles((cfg.get("run") or {}).get("command", ""))
    sim = " --sim" if words.get("mode", "").startswith("simulation") else ""
    if sd is not None:
        return f"tactex graph run{sim} --session-dir {shlex.quote(str(sd))}"
    if "cli" in cfg:
        return f"tactex trial --resume {shlex.quote(str(d))}"
    return f"tactex graph run{sim} --resume {shlex.quote(str(d))}"


def _why_unfinished(d: Path, rec: dict) -> str:
    ended = [e for e in rec["events"] if e.get("event") in ("trial_ended", "failed")]
    if ended:
        e = ended[-1]
        return str(e.get("reason") or (e.get("result") or {}).get("error"))
    sd = session_of(d)
    if sd is not None:
        from ..session import events as session_events
        ev = [e for e in session_events(sd) if e.get("event") in ("session_ended", "run_ended")]
        if ev:
            return str(ev[-1].get("reason"))
    return "no reason recorded (the process was stopped before it could say)"



def _belief_series(decisions: list[dict], comps: list[str], fabrics: dict[str, str],
                   x_of) -> dict[str, list[tuple[float, float]]]:
    series: dict[str, list[tuple[float, float]]] = {
        f"{c} ({fabrics[c]})" if c in fabrics else c: [] for c in comps}
    names = list(series)
    for dec in decisions:
        b = dec.get("belief") or []
        x = x_of(dec)
        if len(b) == len(comps) and x is not None:
            for name, v in zip(names, b, strict=True):
                series[name].append((float(x), float(v)))
    return series



def trial_html(folder: str | Path) -> str:
    """The trial report of record ``folder`` as HTML text."""
    d = Path(folder)
    rec = read_record(d, images=False)
    res, cfg = rec["result"] or {}, read_config(d)
    out = outcome(d, rec, cfg)
    ids, fabrics, comps = out.ids, out.fabrics, out.comps
    touches, decisions = rec["touches"], rec["decisions"]
    strategy = res.get("strategy") or (cfg.get("trial") or {}).get("strategy", "")
    conf = (cfg.get("trial") or {}).get("stop_confidence")
    pred, truth, p_belief, n_touch = out.prediction, out.truth, out.belief, out.touches
    sd = session_of(d)
    parts = [f"<h1>Trial {esc(d.name)}</h1>"]
    if sd is not None:
        parts.append(f"<p><a id='session-link' href='../{REPORT}'>&larr; session "
                     f"{esc((cfg.get('session') or {}).get('name') or sd.name)}</a></p>")
    if not res or "error" in res:
        why = res["error"] if "error" in res else _why_unfinished(d, rec)
        parts.append(f"<p class='answer bad' id='answer'>no answer: the trial did not finish "
                     f"&mdash; <span id='unfinished-reason'>{esc(why)}</span></p>"
                     f"<p>{len(touches)} touch(es) are on disk. Continue it with <code "
                     f"id='resume-command'>{esc(_resume_command(d, cfg))}</code> (the "
                     "recorded touches are replayed, none is pressed twice).</p>")
    else:
        unsure = out.unsure
        sure = "<span id='not-sure'>not sure</span>; best guess " if unsure else ""
        fab = f" ({esc(fabrics[pred])})" if pred in fabrics else ""
        verdict = "<span id='verdict' class='muted'>truth unknown</span>"
        if out.correct is not None:
            right = out.correct
            tfab = ", ".join(f"{esc(p)}" + (f" ({esc(fabrics[p])})" if p in fabrics else "")
                             for p in truth or [])
            # a not-sure answer is never called correct (its best guess may be right)
            verdict = ("<span id='verdict' class='muted'>not sure</span> (the best guess is "
                       "the true match)" if right and unsure else
                       "<span id='verdict' class='ok'>correct</span>" if right else
                       f"<span id='verdict' class='bad'>wrong</span>: the true match is "
                       f"<b id='truth'>{tfab}</b>")
        parts.append(f"<p class='answer' id='answer'>The reference matches <b "
                     f"id='prediction'>{esc(pred)}</b>{fab}: {sure}belief "
                     f"{fmt(p_belief, '.2f')}, stopped: <span id='stop-reason'>"
                     f"{esc(stop_text(res, unsure))}</span> &mdash; {verdict}</p>")
        bound = res.get("bound") or {}
        if bound.get("rule") == "evalue" and bound.get("evalues"):
            parts.append(f"<p id='stop-bound'>Stop rule: e-value (likelihood-ratio "
                         f"martingale); the largest e-value is {max(bound['evalues']):.3g}, the "
                         f"stop needs {bound['threshold']:g} = 1 / alpha: P(ever stopping wrong)"
                         f" &le; alpha = {bound['alpha']:g} under the evidence model "
                         "(independent touches, the null fitted on another library).</p>")
    split = time_split(rec)
    n_failed = failed_attempts(touches)
    facts = [("touches", f"<span id='touches'>{n_touch}</span> accepted of {len(touches)} "
                         f"presses; <span id='failed-attempts'>{n_failed}</span> failed "
                         "attempt(s) in all"),
             ("time", f"<span id='time-total'>{duration(split['total'])}</span> in "
                      f"{split['runs']} run(s): pressing {duration(split['pressing'])}, "
                      f"deciding {duration(split['deciding'])}, waiting "
                      f"{duration(split['waiting'])}")]
    if truth is not None:
        facts.append(("true match", esc(", ".join(truth))))
    parts.append(table([], [[k, v] for k, v in facts], left=2, cls="context",
                        tid="facts"))
    parts.append("<h2>Context</h2>" + table([], context_rows(d, cfg, res, rec), left=2,
                                              cls="context", tid="context"))

    parts.append("<h2>Platforms and their touches</h2><p class='muted'>click a touch for the "
                 "full-size image beside the sensor's no-contact frame; click elsewhere to "
                 "close</p><div class='platforms'>")
    nc_css: dict[str, str] = {}
    for pid in ids or sorted({t.get("platform_id") for t in touches}):
        imgs = [t for t in touches if t.get("platform_id") == pid and t.get("image")]
        tags = []
        for t in imgs:
            uri = png_data(d / t["image"])
            if not uri:
                continue
            nc = t.get("no_contact")
            if nc and nc not in nc_css:
                nuri = png_data(d / nc)
                if nuri:
                    nc_css[nc] = f".nc-{len(nc_css)}{{background-image:url({nuri})}}"
            ncls = ""
            if nc in nc_css:
                ncls = nc_css[nc].split("{")[0][1:]
            cap = (f"touch {t['seq']} of {esc(pid)}: {fmt(t.get('force_n'), '.1f')} N"
                   + ("; right: no-contact frame" if ncls else "; no no-contact frame "
                      "recorded"))
            tags.append(f"<figure class='touch' tabindex='0'><img class='touch' alt='touch "
                        f"{t['seq']} of {esc(pid)}' title='touch {t['seq']}: "
                        f"{fmt(t.get('force_n'), '.1f')} N' src='{uri}'>"
                        + (f"<span class='nc {ncls}' role='img' aria-label='no-contact "
                           "frame'></span>" if ncls else "")
                        + f"<figcaption>{cap}</figcaption></figure>")
        role = "reference" if ids and pid == ids[0] else "comparison"
        cls, marks = [], []
        if pid == pred and res and "error" not in res:
            wrong = truth is not None and pid not in truth
            cls.append("wrong" if wrong else "chosen")
            marks.append("<span class='tag wrong'>chosen, wrong</span>" if wrong else
                         "<span class='tag chosen'>chosen</span>")
        if truth is not None and pid in truth:
            cls.append("truth")
            marks.append("<span class='tag truth'>true match</span>")
        parts.append(f"<div class='platform {' '.join(cls)}' data-platform='{esc(pid)}'>"
                     f"<b>{esc(pid)}</b> <span class='muted'>{role}"
                     f"{' &middot; ' + esc(fabrics[pid]) if pid in fabrics else ''}</span> "
                     f"{''.join(marks)}<br>{len(imgs)} touch(es)<br>{''.join(tags)}</div>")
    parts.append("</div>")

    stop = (float(conf), f"stop at {conf:g}") if conf else None
    parts.append("<h2>Belief against touches</h2>")
    by_touch = _belief_series(decisions, comps, fabrics,
                              lambda dec: sum(dec.get("touches") or []))
    if any(by_touch.values()):
        parts.append(line_chart(by_touch, chart_id="belief-chart",
                                x_label="touches of the comparison platforms so far",
                                y_label="belief", hline=stop))
    else:
        parts.append("<p class='muted' id='belief-chart-missing'>no decision recorded</p>")
    parts.append("<h2>Belief against time</h2>")
    t0s = [t["requested"] for t in touches if t.get("requested")]
    secs = decision_seconds(rec, min(t0s) if t0s else None)
    it = iter(secs)
    by_time = _belief_series(decisions, comps, fabrics, lambda _dec: next(it))
    if any(by_time.values()):
        parts.append(line_chart(by_time, chart_id="belief-time-chart",
                                x_label="seconds since the first press request",
                                y_label="belief", hline=stop))
    else:
        parts.append("<p class='muted' id='belief-time-chart-missing'>no decision with a "
                     "time recorded</p>")

    parts.append("<h2>What happened</h2><div class='timeline' id='timeline'>")
    for t, text, bad in _timeline(d, rec):
        parts.append(f"<div class='{'bad' if bad else ''}'>{esc(when(t))} &mdash; "
                     f"{esc(text)}</div>")
    parts.append("</div>")

    parts.append("<h2>Rounds: the chosen platform and why</h2>")
    rows = []
    for dec in decisions:
        b, u = dec.get("belief") or [], dec.get("uncertainty") or []
        nxt = dec.get("next") or ""
        why = "done" if dec.get("done") else ""
        if nxt and nxt in comps and len(u) == len(comps):
            k = comps.index(nxt)
            rank = sorted(u, reverse=True).index(u[k]) + 1
            why = (f"{esc(strategy)} score {u[k]:.3g}"
                   + (" (highest)" if rank == 1 else f" (rank {rank})"))
        elif nxt:
            why = "reference (re-touch)" if ids and nxt == ids[0] else "as scheduled"
        rows.append([esc(dec.get("round")), esc(nxt or "-"), why,
                     " ".join(f"{esc(c)} {v:.2f}" for c, v in zip(comps, b, strict=False)),  # b: [] without belief
                     fmt(dec.get("decision_s"), ".2f")])
    parts.append(table(["round", "next", "reason", "belief", "decision [s]"], rows, left=4))

    parts.append("<h2>Presses</h2>")
    rows = []
    for t in touches:
        dt = (t["stamp"] - t["requested"]) if t.get("stamp") and t.get("requested") else None
        ok = "yes" if t.get("accepted") else f"no: {esc(t.get('reason'))}"
        depth = t.get("depth_m")
        att = int(t.get("attempts") or (1 if t.get("accepted") else 0))
        failed = att - 1 if t.get("accepted") else att
        why = t.get("attempt_failures") or ""
        rows.append([esc(t.get("seq")), esc(t.get("platform_id")), fmt(dt, ".2f"),
                     fmt(t.get("force_n"), ".2f"),
                     fmt(None if depth is None else depth * 1e3, ".2f"),
                     f"{att}" + (f" <span class='bad'>({failed} failed"
                                 + (f": {esc(why)}" if why else "") + ")</span>"
                                 if failed else ""), ok])
    parts.append(table(["touch", "platform", "press [s]", "force [N]", "depth [mm]",
                         "attempts", "accepted"], rows, left=2, cls="presses"))
    return page(f"tactex trial {d.name}", "".join(parts), "".join(nc_css.values()))


def write_trial_report(folder: str | Path) -> Path:
    """Write ``<folder>/report.html`` (atomically); returns its path."""
    d = Path(folder)
    return write_page(d / REPORT, trial_html(d))
