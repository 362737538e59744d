"""Reports a person reads: ``report.html`` per trial record and per study session.

Each is one self-contained HTML file (no network: touch images inlined as base64 PNG, charts
as inline SVG drawn here). Built from the record folder alone (``record.read_record``,
``config.json``, ``scene.yaml``), so ``tactex report FOLDER`` regenerates them at any time.

Trial report: the answer (or "not sure" when the trial stopped without reaching its stop
confidence), its belief and stop reason, correctness when the truth is known (a session trial);
every platform with its fabric (where known) and touch images; the belief after every decision
as a line chart; each round's chosen platform with its reason (the strategy's score); every
press with its time (request -> capture) [s], force [N] and depth [mm].

Session report: accuracy, touches and time per trial, a confusion matrix of the fabrics
(reference fabric x fabric on the chosen platform), accuracy against touches (the answer the
trial would have given had it stopped after t touches: the belief's argmax at the last decision
made with at most t touches).
"""

from __future__ import annotations

import base64
import html
import json
from pathlib import Path
from typing import Any

from ..core.errors import InputError
from .record import read_record, read_result

REPORT = "report.html"
COLOURS = ["#1f77b4", "#ff7f0e", "#2ca02c", "#d62728", "#9467bd", "#8c564b", "#e377c2",
           "#7f7f7f", "#bcbd22", "#17becf"]
_CSS = """
body{font-family:system-ui,sans-serif;margin:24px;color:#222;max-width:1100px}
h1{font-size:1.5em;margin-bottom:4px} h2{font-size:1.15em;margin-top:28px}
.answer{font-size:1.3em;padding:10px 14px;border-radius:6px;background:#eef4ff;display:inline-block}
.ok{color:#17803d} .bad{color:#b3261e} .muted{color:#666}
table{border-collapse:collapse;margin:6px 0} td,th{border:1px solid #ccc;padding:3px 8px;
text-align:right;font-size:.92em} th{background:#f4f4f4} td.l,th.l{text-align:left}
.platforms{display:flex;flex-wrap:wrap;gap:14px}
.platform{border:1px solid #ccc;border-radius:6px;padding:8px;width:250px}
.platform.chosen{border:3px solid #17803d}
.platform img{width:116px;height:87px;margin:2px;image-rendering:auto}
svg text{font-size:11px;font-family:system-ui,sans-serif}
"""


def _esc(x: Any) -> str:
    return html.escape("" if x is None else str(x))


def _png_data(path: Path) -> str | None:
    """A PNG file as a data URI, None when absent."""
    if not path.is_file():
        return None
    return "data:image/png;base64," + base64.b64encode(path.read_bytes()).decode()


def _page(title: str, body: str) -> str:
    return (f"<!DOCTYPE html><html lang='en'><head><meta charset='utf-8'><title>"
            f"{_esc(title)}</title><style>{_CSS}</style></head><body>{body}</body></html>")


def _write(path: Path, text: str) -> Path:
    from ..core.outputs import write_bytes
    return write_bytes(path, text.encode("utf-8"))     # whole or not at all (WriteError)


def line_chart(series: dict[str, list[tuple[float, float]]], *, chart_id: str, x_label: str,
               y_label: str, y_max: float = 1.0, width: int = 640, height: int = 260) -> str:
    """An inline SVG line chart: ``series`` name -> [(x, y)], y in [0, y_max]. Each series is
    one ``polyline`` (class ``series``) with dots and a legend entry."""
    ml, mr, mt, mb = 48, 130, 12, 38
    pw, ph = width - ml - mr, height - mt - mb
    xs = [x for pts in series.values() for x, _ in pts] or [0.0, 1.0]
    x0, x1 = min(xs), max(xs)
    if x1 == x0:
        x1 = x0 + 1.0

    def px(x: float) -> float:
        return ml + (x - x0) / (x1 - x0) * pw

    def py(y: float) -> float:
        return mt + ph - max(0.0, min(y, y_max)) / y_max * ph

    out = [f"<svg id='{_esc(chart_id)}' xmlns='http://www.w3.org/2000/svg' width='{width}' "
           f"height='{height}' viewBox='0 0 {width} {height}' role='img'>",
           f"<rect x='{ml}' y='{mt}' width='{pw}' height='{ph}' fill='#fafafa' "
           "stroke='#999'/>"]
    for k in range(5):
        y = y_max * k / 4
        out.append(f"<line x1='{ml}' x2='{ml + pw}' y1='{py(y):.1f}' y2='{py(y):.1f}' "
                   f"stroke='#e2e2e2'/><text x='{ml - 6}' y='{py(y) + 4:.1f}' "
                   f"text-anchor='end'>{y:.2g}</text>")
    ticks = sorted({round(x) for x in xs})
    step = max(1, len(ticks) // 10)
    for x in ticks[::step]:
        out.append(f"<text x='{px(x):.1f}' y='{mt + ph + 16}' text-anchor='middle'>{x:g}</text>")
    out.append(f"<text x='{ml + pw / 2}' y='{height - 4}' text-anchor='middle'>"
               f"{_esc(x_label)}</text><text x='12' y='{mt + ph / 2}' text-anchor='middle' "
               f"transform='rotate(-90 12 {mt + ph / 2})'>{_esc(y_label)}</text>")
    for i, (name, pts) in enumerate(series.items()):
        c = COLOURS[i % len(COLOURS)]
        coords = " ".join(f"{px(x):.1f},{py(y):.1f}" for x, y in pts)
        out.append(f"<polyline class='series' data-name='{_esc(name)}' fill='none' "
                   f"stroke='{c}' stroke-width='2' points='{coords}'/>")
        out += [f"<circle cx='{px(x):.1f}' cy='{py(y):.1f}' r='2.5' fill='{c}'/>"
                for x, y in pts]
        ly = mt + 14 + 16 * i
        out.append(f"<line x1='{ml + pw + 10}' x2='{ml + pw + 28}' y1='{ly - 4}' "
                   f"y2='{ly - 4}' stroke='{c}' stroke-width='3'/><text x='{ml + pw + 32}' "
                   f"y='{ly}'>{_esc(name)}</text>")
    out.append("</svg>")
    return "".join(out)


def _table(head: list[str], rows: list[list[Any]], left: int = 1, cls: str = "") -> str:
    th = "".join(f"<th class='{'l' if i < left else ''}'>{_esc(h)}</th>"
                 for i, h in enumerate(head))
    th = f"<tr>{th}</tr>" if head else ""
    body = "".join("<tr>" + "".join(f"<td class='{'l' if i < left else ''}'>{c}</td>"
                                     for i, c in enumerate(r)) + "</tr>" for r in rows)
    return f"<table class='{cls}'>{th}{body}</table>"


def _fmt(x: Any, spec: str = ".2f") -> str:
    return "" if x is None else format(x, spec)


def _scene_fabrics(d: Path) -> tuple[list[str], dict[str, str]]:
    """Platform ids (scene order, reference first) and their fabric where the record says."""
    import yaml
    cfg = _config(d)
    placed = (cfg.get("session") or {}).get("placement") or {}
    ids, fabrics = [], {}
    p = d / "scene.yaml"
    if p.is_file():
        doc = yaml.safe_load(p.read_text()) or {}
        plats = doc.get("platforms") or []
        ref = [q for q in plats if q.get("role") == "reference"]
        for q in ref + [q for q in plats if q.get("role") != "reference"]:
            ids.append(str(q.get("id")))
            f = placed.get(str(q.get("id"))) or q.get("sim_fabric") or q.get("replay_class")
            if f:
                fabrics[str(q.get("id"))] = str(f)
    return ids, fabrics


def _config(d: Path) -> dict:
    """``config.json`` of a record ({} when absent or unreadable); InputError naming the file
    and the field when it is not an object or a section is not one."""
    p = d / "config.json"
    try:
        cfg = json.loads(p.read_text())
    except (OSError, UnicodeDecodeError, json.JSONDecodeError):
        return {}
    from .record import check_fields
    return check_fields(cfg, {k: (dict, None) for k in ("trial", "session", "explorer",
                                                        "learner")}, repr(str(p)))


def not_sure(result: dict, stop_confidence: float | None, belief: float | None) -> bool:
    """A trial that ran out of rounds or touches with its answer's belief below the stop
    confidence it was given (no stop confidence: 0 or unknown -> never 'not sure'). A result
    that carries the engine's own ``sure`` (``TrialOutcome.sure``) is read from it."""
    if result.get("sure") is not None:
        return not result["sure"]
    if result.get("stop_reason") in (None, "", "confident") or not stop_confidence:
        return False
    return belief is None or belief < stop_confidence


def trial_html(folder: str | Path) -> str:
    """The trial report of record ``folder`` as HTML text."""
    d = Path(folder)
    rec = read_record(d, images=False)
    res, cfg = rec["result"] or {}, _config(d)
    ids, fabrics = _scene_fabrics(d)
    touches, decisions = rec["touches"], rec["decisions"]
    comps = ids[1:] if ids else sorted({t.get("platform_id") for t in touches} - {None})
    strategy = res.get("strategy") or (cfg.get("trial") or {}).get("strategy", "")
    pred = res.get("prediction")
    n_touch = len([t for t in touches if t.get("accepted")])
    final_belief = (decisions[-1].get("belief") if decisions else None) or []
    p_belief = (final_belief[comps.index(pred)] if pred in comps and
                len(final_belief) == len(comps) else None)
    parts = [f"<h1>Trial {_esc(d.name)}</h1>"]
    if not res:
        parts.append("<p class='answer bad' id='answer'>no result: the trial did not finish "
                     "(resumable)</p>")
    elif "error" in res:
        parts.append(f"<p class='answer bad' id='answer'>no answer: {_esc(res['error'])}</p>")
    else:
        conf = (cfg.get("trial") or {}).get("stop_confidence")
        sure = "<span id='not-sure'>not sure</span>; best guess " \
            if not_sure(res, conf, p_belief) else ""
        fab = f" ({_esc(fabrics[pred])})" if pred in fabrics else ""
        verdict = ""
        if isinstance(res.get("correct"), bool):
            verdict = (" <span class='ok'>correct</span>" if res["correct"] else
                       " <span class='bad'>wrong</span>")
        parts.append(f"<p class='answer' id='answer'>The reference matches <b "
                     f"id='prediction'>{_esc(pred)}</b>{fab}: {sure}belief "
                     f"{_fmt(p_belief, '.2f')}, stopped: <span id='stop-reason'>"
                     f"{_esc(res.get('stop_reason'))}</span>{verdict}</p>")
    truth = res.get("truth_platforms")
    facts = [("touches", f"<span id='touches'>{n_touch}</span>"
              f" accepted of {len(touches)} presses"),
             ("strategy", _esc(strategy)), ("seed", _esc((cfg.get("explorer") or {}).get("seed"))),
             ("time", _fmt(res.get("elapsed_s"), ".1f") + " s" if res.get("elapsed_s") else "")]
    if truth is not None:
        facts.append(("true match", _esc(", ".join(truth))))
    parts.append(_table([], [[k, v] for k, v in facts], left=2))

    parts.append("<h2>Platforms and their touches</h2><div class='platforms'>")
    for pid in ids or sorted({t.get("platform_id") for t in touches}):
        imgs = [t for t in touches if t.get("platform_id") == pid and t.get("image")]
        tags = []
        for t in imgs:
            uri = _png_data(d / t["image"])
            if uri:
                tags.append(f"<img class='touch' alt='touch {t['seq']} of {_esc(pid)}' "
                            f"title='touch {t['seq']}: {_fmt(t.get('force_n'), '.1f')} N' "
                            f"src='{uri}'>")
        chosen = " chosen" if pid == pred else ""
        role = "reference" if ids and pid == ids[0] else "comparison"
        parts.append(f"<div class='platform{chosen}' data-platform='{_esc(pid)}'><b>"
                     f"{_esc(pid)}</b> <span class='muted'>{role}"
                     f"{' &middot; ' + _esc(fabrics[pid]) if pid in fabrics else ''}</span><br>"
                     f"{len(imgs)} touch(es)<br>{''.join(tags)}</div>")
    parts.append("</div>")

    parts.append("<h2>Belief after every decision</h2>")
    series: dict[str, list[tuple[float, float]]] = {c: [] for c in comps}
    for i, dec in enumerate(decisions, 1):
        b = dec.get("belief") or []
        if len(b) == len(comps):
            for c, v in zip(comps, b):
                series[c].append((float(i), float(v)))
    if any(series.values()):
        parts.append(line_chart(series, chart_id="belief-chart",
                                x_label="decision (one after every touch of a round)",
                                y_label="belief"))
    else:
        parts.append("<p class='muted' id='belief-chart-missing'>no decision recorded</p>")

    parts.append("<h2>Rounds: the chosen platform and why</h2>")
    rows = []
    for dec in decisions:
        b, u = dec.get("belief") or [], dec.get("uncertainty") or []
        nxt = dec.get("next") or ""
        why = "done" if dec.get("done") else ""
        if nxt and nxt in comps and len(u) == len(comps):
            k = comps.index(nxt)
            rank = sorted(u, reverse=True).index(u[k]) + 1
            why = (f"{_esc(strategy)} score {u[k]:.3g}"
                   + (" (highest)" if rank == 1 else f" (rank {rank})"))
        elif nxt:
            why = "reference (re-touch)" if ids and nxt == ids[0] else "as scheduled"
        rows.append([_esc(dec.get("round")), _esc(nxt or "-"), why,
                     " ".join(f"{_esc(c)} {v:.2f}" for c, v in zip(comps, b)),
                     _fmt(dec.get("decision_s"), ".2f")])
    parts.append(_table(["round", "next", "reason", "belief", "decision [s]"], rows, left=4))

    parts.append("<h2>Presses</h2>")
    rows = []
    for t in touches:
        dt = (t["stamp"] - t["requested"]) if t.get("stamp") and t.get("requested") else None
        ok = "yes" if t.get("accepted") else f"no: {_esc(t.get('reason'))}"
        depth = t.get("depth_m")
        rows.append([_esc(t.get("seq")), _esc(t.get("platform_id")), _fmt(dt, ".2f"),
                     _fmt(t.get("force_n"), ".2f"),
                     _fmt(None if depth is None else depth * 1e3, ".2f"), ok])
    parts.append(_table(["touch", "platform", "press [s]", "force [N]", "depth [mm]",
                         "accepted"], rows, left=2, cls="presses"))
    return _page(f"tactex trial {d.name}", "".join(parts))


def write_trial_report(folder: str | Path) -> Path:
    """Write ``<folder>/report.html`` (atomically); returns its path."""
    d = Path(folder)
    return _write(d / REPORT, trial_html(d))


def anytime_answers(rec: dict, comps: list[str]) -> list[tuple[int, str]]:
    """(touches so far, argmax platform) after every recorded decision."""
    out = []
    for dec in rec["decisions"]:
        b = dec.get("belief") or []
        if len(b) == len(comps) and b:
            out.append((int(sum(dec.get("touches") or [0])),
                        comps[max(range(len(b)), key=b.__getitem__)]))
    return out


def session_html(folder: str | Path) -> str:
    """The session report of session folder ``folder`` as HTML text."""
    from . import session as sess
    d = Path(folder)
    summ = sess.summary(d)
    started = sess.load_started(d)
    done = [r for r in summ["trials"] if r["done"]]
    acc = summ["accuracy"]
    parts = [f"<h1>Session {_esc(summ['name'])}</h1>",
             f"<p class='answer' id='accuracy'>accuracy <b>{_fmt(acc, '.3f')}</b> "
             f"({sum(r['correct'] for r in done)} of {len(done)} trials correct; "
             f"{summ['done']} of {summ['total']} trials done)</p>"]
    rows = []
    curves: list[list[tuple[int, bool]]] = []
    fabrics: list[str] = []
    conf: dict[tuple[str, str], int] = {}
    for r, t in zip(summ["trials"], started["trials"]):
        link = f"<a href='{_esc(r['record'])}/{REPORT}'>{_esc(r['id'])}</a>"
        if not r["done"]:
            rows.append([link, "", "", "", "", "", "<span class='muted'>not done</span>"])
            continue
        placement = t["placement"]
        ref_fab = list(placement.values())[0]
        got = placement.get(r["prediction"], "?")
        for f in (ref_fab, got):
            if f not in fabrics:
                fabrics.append(f)
        conf[(ref_fab, got)] = conf.get((ref_fab, got), 0) + 1
        res = read_result(d / r["record"]) or {}
        mark = "<span class='ok'>yes</span>" if r["correct"] else "<span class='bad'>no</span>"
        stop_conf = (_config(d / r["record"]).get("trial") or {}).get("stop_confidence")
        dec = read_record(d / r["record"], images=False)["decisions"]
        comps_ = list(placement)[1:]
        b = (dec[-1].get("belief") or []) if dec else []
        p_b = b[comps_.index(r["prediction"])] if r["prediction"] in comps_ and \
            len(b) == len(comps_) else None
        rows.append([link, _esc(ref_fab), f"{_esc(r['prediction'])} ({_esc(got)})"
                     + (" <span class='muted'>not sure</span>" if not_sure(res, stop_conf, p_b)
                        else ""),
                     _esc(r["touches"]), _fmt(r.get("elapsed_s"), ".1f"),
                     _esc(r["stop_reason"]), mark])
        comps = list(placement)[1:]
        rec = read_record(d / r["record"], images=False)
        curves.append([(n, a in t["truth"]) for n, a in anytime_answers(rec, comps)])
    parts.append("<h2>Trials</h2>" + _table(
        ["trial", "reference fabric", "answer", "touches", "time [s]", "stop", "correct"],
        rows, left=3, cls="trials"))
    if done:
        touches = [r["touches"] for r in done]
        times = [r["elapsed_s"] for r in done if r.get("elapsed_s") is not None]
        parts.append(f"<p>touches per trial: mean {sum(touches) / len(touches):.1f}, "
                     f"min {min(touches)}, max {max(touches)}"
                     + (f"; time per trial: mean {sum(times) / len(times):.1f} s"
                        if times else "") + "</p>")
    parts.append("<h2>Confusion matrix of the fabrics</h2><p class='muted'>rows: the "
                 "reference's fabric; columns: the fabric on the platform the trial chose</p>")
    head = ["reference \\ chosen"] + fabrics
    refs = [f for f in fabrics if any(a == f for a, _ in conf)]
    mrows = [[_esc(a)] + [(f"<b>{conf.get((a, b), 0)}</b>" if a == b else
                           str(conf.get((a, b), 0) or "")) for b in fabrics] for a in refs]
    parts.append(_table(head, mrows, left=1, cls="confusion"))
    parts.append("<h2>Accuracy against touches</h2><p class='muted'>the answer each trial "
                 "would have given had it stopped after t touches (trials that ended earlier "
                 "keep their answer)</p>")
    if curves and any(curves):
        t_max = max(n for c in curves for n, _ in c)
        t_min = min(n for c in curves for n, _ in c if c)
        pts = []
        for t_ in range(t_min, t_max + 1):
            hits = []
            for c in curves:
                seen = [ok for n, ok in c if n <= t_]
                if seen:
                    hits.append(seen[-1])
            if hits:
                pts.append((float(t_), sum(hits) / len(hits)))
        parts.append(line_chart({"accuracy": pts}, chart_id="accuracy-chart",
                                x_label="touches of the comparisons", y_label="accuracy"))
    return _page(f"tactex session {summ['name']}", "".join(parts))


def write_session_report(folder: str | Path) -> Path:
    """Write ``<folder>/report.html`` for a session folder (atomically)."""
    d = Path(folder)
    return _write(d / REPORT, session_html(d))


def regenerate(folder: str | Path) -> list[Path]:
    """``tactex report``: a trial record -> its report; a session folder -> every trial's
    report and the session report. InputError when ``folder`` is neither."""
    d = Path(folder)
    try:
        return _regenerate(d)
    except InputError:
        raise
    except (KeyError, TypeError, AttributeError, IndexError, ValueError) as exc:
        # a file of the folder holds other types than a record's: refused, not a traceback
        raise InputError(f"{str(d)!r}: a file of the record or session is damaged "
                         f"({type(exc).__name__}: {exc})") from None


def _regenerate(d: Path) -> list[Path]:
    from . import session as sess
    if (d / sess.SESSION_FILE).is_file():
        out = [write_trial_report(p.parent) for p in sorted(d.glob("trial_*/config.json"))]
        return out + [write_session_report(d)]
    if (d / "config.json").is_file() or (d / "touches.jsonl").is_file():
        return [write_trial_report(d)]
    raise InputError(f"{str(d)!r} is neither a trial record (config.json, touches.jsonl) nor "
                      f"a session folder ({sess.SESSION_FILE})")
