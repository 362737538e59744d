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

Session report: duration, settings, accuracy with its 95 % Wilson interval and n, touches and
time per trial (each linked to its report; each trial report links back), a confusion matrix
of the fabrics, accuracy against comparison touches with its Wilson band and n per point.
"""

from __future__ import annotations

import base64
import datetime as _dt
import html
import json
import math
import os
import shlex
from pathlib import Path
from typing import Any

from ..core.errors import InputError
from ..core.stats import wilson
from .record import not_sure, read_record, read_result, stop_text
from .record import read_config as _config

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
table.context td{text-align:left;vertical-align:top} table.context td:first-child{font-weight:600}
code{font-size:.9em;background:#f4f4f4;padding:1px 4px;border-radius:3px;word-break:break-all}
.platforms{display:flex;flex-wrap:wrap;gap:14px}
.platform{border:1px solid #ccc;border-radius:6px;padding:8px;width:250px}
.platform.chosen{border:3px solid #17803d} .platform.wrong{border:3px solid #b3261e}
.platform.truth{box-shadow:0 0 0 3px #1f77b4 inset}
.tag{display:inline-block;border-radius:3px;padding:0 5px;margin:2px 2px 2px 0;font-size:.85em;
color:#fff} .tag.chosen{background:#17803d} .tag.wrong{background:#b3261e}
.tag.truth{background:#1f77b4}
figure.touch{display:inline-block;margin:2px;cursor:zoom-in;outline:none}
figure.touch img{width:116px;height:87px} figure.touch .nc,figure.touch figcaption{display:none}
figure.touch:focus{position:fixed;left:20px;top:20px;z-index:10;background:#fff;padding:10px;
border:2px solid #444;box-shadow:0 4px 30px #0008;cursor:zoom-out}
figure.touch:focus img{width:auto;height:auto} figure.touch:focus .nc{display:inline-block;
width:320px;height:240px;background-size:contain;background-repeat:no-repeat;margin-left:8px}
figure.touch:focus figcaption{display:block}
.timeline{border-left:3px solid #999;margin-left:8px;padding-left:12px}
.timeline div{margin:3px 0} .timeline .bad{font-weight:600}
svg text{font-size:11px;font-family:system-ui,sans-serif}
"""


def _esc(x: Any) -> str:
    return html.escape("" if x is None else str(x))


def _png_data(path: Path) -> str | None:
    """A PNG file as a data URI, None when absent."""
    if not path.is_file():
        return None
    return "data:image/png;base64," + base64.b64encode(path.read_bytes()).decode()


def _page(title: str, body: str, extra_css: str = "") -> str:
    return (f"<!DOCTYPE html><html lang='en'><head><meta charset='utf-8'><title>"
            f"{_esc(title)}</title><style>{_CSS}{extra_css}</style></head><body>{body}"
            "</body></html>")


def _write(path: Path, text: str) -> Path:
    from ..core.outputs import write_bytes
    return write_bytes(path, text.encode("utf-8"))     # whole or not at all (WriteError)


def line_chart(series: dict[str, list[tuple[float, float]]], *, chart_id: str, x_label: str,
               y_label: str, y_max: float = 1.0, width: int = 640, height: int = 260,
               hline: tuple[float, str] | None = None,
               bands: dict[str, list[tuple[float, float, float]]] | None = None,
               notes: dict[str, list[tuple[float, str]]] | None = None) -> str:
    """An inline SVG line chart: ``series`` name -> [(x, y)], y in [0, y_max]. Each series is
    one ``polyline`` (class ``series``) with dots and a legend entry. ``hline``: (y, label) a
    dashed horizontal line (class ``stop-line``); ``bands``: name -> [(x, low, high)] a shaded
    band (class ``band``) behind that series; ``notes``: name -> [(x, text)] small labels above
    the series' points (e.g. n)."""
    ml, mr, mt, mb = 48, 170, 12, 38
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
    span = x1 - x0
    step = 10 ** math.floor(math.log10(span / 2)) if span > 2 else 1.0
    while span / step > 10:
        step *= 2
    t = math.ceil(x0 / step) * step
    while t <= x1 + 1e-9:
        out.append(f"<text x='{px(t):.1f}' y='{mt + ph + 16}' text-anchor='middle'>"
                   f"{t:g}</text>")
        t += step
    out.append(f"<text x='{ml + pw / 2}' y='{height - 4}' text-anchor='middle'>"
               f"{_esc(x_label)}</text><text x='12' y='{mt + ph / 2}' text-anchor='middle' "
               f"transform='rotate(-90 12 {mt + ph / 2})'>{_esc(y_label)}</text>")
    names = list(series)
    for name, band in (bands or {}).items():
        if not band:
            continue
        c = COLOURS[names.index(name) % len(COLOURS)] if name in names else "#999"
        up = " ".join(f"{px(x):.1f},{py(hi):.1f}" for x, _, hi in band)
        down = " ".join(f"{px(x):.1f},{py(lo):.1f}" for x, lo, _ in reversed(band))
        out.append(f"<polygon class='band' data-name='{_esc(name)}' points='{up} {down}' "
                   f"fill='{c}' fill-opacity='0.15' stroke='none'/>")
    if hline is not None:
        y, label = hline
        out.append(f"<line class='stop-line' x1='{ml}' x2='{ml + pw}' y1='{py(y):.1f}' "
                   f"y2='{py(y):.1f}' stroke='#b3261e' stroke-dasharray='6 4' "
                   f"stroke-width='1.5'/><text x='{ml + pw - 4}' y='{py(y) - 4:.1f}' "
                   f"text-anchor='end' fill='#b3261e'>{_esc(label)}</text>")
    for i, (name, pts) in enumerate(series.items()):
        c = COLOURS[i % len(COLOURS)]
        coords = " ".join(f"{px(x):.1f},{py(y):.1f}" for x, y in pts)
        out.append(f"<polyline class='series' data-name='{_esc(name)}' fill='none' "
                   f"stroke='{c}' stroke-width='2' points='{coords}'/>")
        out += [f"<circle cx='{px(x):.1f}' cy='{py(y):.1f}' r='2.5' fill='{c}'/>"
                for x, y in pts]
        out += [f"<text class='note' x='{px(x):.1f}' y='{py(y) - 6:.1f}' "
                f"text-anchor='middle' fill='#555'>{_esc(text)}</text>"
                for x, text in (notes or {}).get(name, [])]
        ly = mt + 14 + 16 * i
        out.append(f"<line x1='{ml + pw + 10}' x2='{ml + pw + 28}' y1='{ly - 4}' "
                   f"y2='{ly - 4}' stroke='{c}' stroke-width='3'/><text x='{ml + pw + 32}' "
                   f"y='{ly}' class='legend'>{_esc(name)}</text>")
    out.append("</svg>")
    return "".join(out)


def _table(head: list[str], rows: list[list[Any]], left: int = 1, cls: str = "",
           tid: str = "") -> str:
    th = "".join(f"<th class='{'l' if i < left else ''}'>{_esc(h)}</th>"
                 for i, h in enumerate(head))
    th = f"<tr>{th}</tr>" if head else ""
    body = "".join("<tr>" + "".join(f"<td class='{'l' if i < left else ''}'>{c}</td>"
                                     for i, c in enumerate(r)) + "</tr>" for r in rows)
    ident = f" id='{tid}'" if tid else ""
    return f"<table class='{cls}'{ident}>{th}{body}</table>"


def _fmt(x: Any, spec: str = ".2f") -> str:
    return "" if x is None else format(x, spec)


def _when(t: float | None) -> str:
    """Epoch seconds as ``YYYY-MM-DD HH:MM:SS UTC``."""
    if not t:
        return ""
    return _dt.datetime.fromtimestamp(t, _dt.UTC).strftime("%Y-%m-%d %H:%M:%S UTC")


def _duration(s: float | None) -> str:
    if s is None:
        return ""
    s = float(s)
    if s < 120:
        return f"{s:.1f} s"
    h, rest = divmod(int(round(s)), 3600)
    return (f"{h} h " if h else "") + f"{rest // 60} min {rest % 60} s"


# ------------------------------------------------------------------------------ run context

def run_info(command: str | None = None) -> dict[str, Any]:
    """What a record keeps about how it was made (``config.json`` ``run``): the start (epoch
    seconds), tactex's version and git commit (``+dirty`` with uncommitted changes; '' outside
    a checkout), the host and the command (``TACTEX_COMMAND``, set by the ``tactex`` CLI)."""
    import socket
    import subprocess
    from importlib import metadata
    try:
        version = metadata.version("tactex")
    except metadata.PackageNotFoundError:
        version = ""
    repo = Path(__file__).resolve().parents[2]
    commit = ""
    if (repo / ".git").exists():
        try:
            commit = subprocess.run(["git", "-C", str(repo), "rev-parse", "--short=12", "HEAD"],
                                    capture_output=True, text=True, timeout=5).stdout.strip()
            dirty = subprocess.run(["git", "-C", str(repo), "status", "--porcelain",
                                    "--untracked-files=no"], capture_output=True, text=True,
                                   timeout=5).stdout.strip()
            commit += "+dirty" if commit and dirty else ""
        except (OSError, subprocess.SubprocessError):
            commit = ""
    cmd = command if command is not None else os.environ.get("TACTEX_COMMAND", "")
    return {"started": __import__("time").time(), "version": version, "commit": commit,
            "host": socket.gethostname(), "command": cmd}


def changed_settings(now: dict[str, Any], default: dict[str, Any], prefix: str = ""
                     ) -> dict[str, Any]:
    """Flattened ``section.key -> value`` of ``now`` where it differs from ``default``."""
    out: dict[str, Any] = {}
    for k, v in now.items():
        d = default.get(k) if isinstance(default, dict) else None
        if isinstance(v, dict):
            out.update(changed_settings(v, d or {}, f"{prefix}{k}."))
        elif v != d:
            out[f"{prefix}{k}"] = v
    return out


def _preset_changes(cfg: dict) -> dict[str, Any]:
    """Trial and learner settings of ``config.json`` that differ from their preset's."""
    from ..core.config import TRIAL_PRESETS, TrialConfig, learner_class, preset_learner
    preset = ((cfg.get("explorer") or cfg.get("cli") or {}).get("config")) or "default"
    learner = cfg.get("learner") or {}

    def defaults(cls: type) -> dict:
        return {n: f.get_default(call_default_factory=True) for n, f in cls.model_fields.items()}
    try:             # the preset's values (as TrialSettings makes them), not validated again
        given = preset_learner(preset, {"model": learner["model"]} if "model" in learner
                               else None)
        base = {"learner": {**defaults(learner_class(given["model"])), **given},
                "trial": {**defaults(TrialConfig), **TRIAL_PRESETS[preset]}}
    except Exception:  # noqa: BLE001 - an old or foreign record: every value is shown
        base = {}
    out = changed_settings(cfg.get("trial") or {}, base.get("trial") or {}, "trial.")
    out.update(changed_settings(learner, base.get("learner") or {}, "learner."))
    return out


def _command_profiles(command: str) -> dict[str, str]:
    """Simulation or robot, robot and sensor profiles read from a ``tactex graph run``
    command ('' where the command does not say)."""
    try:
        words = shlex.split(command)
    except ValueError:
        words = command.split()
    if not words:
        return {}

    def opt(name: str) -> str | None:
        for i, w in enumerate(words):
            if w == name and i + 1 < len(words):
                return words[i + 1]
            if w.startswith(name + "="):
                return w.split("=", 1)[1]
        return None
    sim = "--sim" in words or "sim:=true" in words
    return {"mode": "simulation (mock arm and camera)" if sim else "robot",
            "robot": opt("--robot") or ("sim" if sim else "fr3_crisp (default)"),
            "sensor": opt("--sensor") or ("mock camera" if sim else "gelsight_mini (default)")}


def _scene_fabrics(d: Path) -> tuple[list[str], dict[str, str]]:
    """Platform ids (scene order, reference first) and their fabric where the record says."""
    import yaml
    cfg = _config(d)
    placed = (cfg.get("session") or {}).get("placement") or {}
    ids, fabrics = [], {}
    p = d / "scene.yaml"
    cli = (cfg.get("cli") or {}).get("platforms")
    if not p.is_file() and isinstance(cli, dict):      # `tactex trial`: the source's classes
        return [str(k) for k in cli], {str(k): str(v) for k, v in cli.items()}
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


def scene_truth(folder: str | Path) -> list[str] | None:
    """The comparisons of record ``folder`` whose fabric is the reference's, when every
    platform of its scene names its fabric (``sim_fabric``, ``replay_class`` or a session's
    placement): a simulated or replayed trial's truth. None when a platform names none (a
    lab scene: the truth is not known) or no comparison matches."""
    ids, fabrics = _scene_fabrics(Path(folder))
    if len(ids) < 2 or any(i not in fabrics for i in ids):
        return None
    same = [i for i in ids[1:] if fabrics[i] == fabrics[ids[0]]]
    return same or None


def _session_of(d: Path) -> Path | None:
    """The session folder a trial record lies in (None: a single trial)."""
    from .session import SESSION_FILE
    return d.parent if (d.parent / SESSION_FILE).is_file() else None


def failed_attempts(touches: list[dict]) -> int:
    """Press attempts that failed, over the record's touch lines: an accepted touch's attempts
    beyond its first, every attempt of a failed press (the motion node retries a press up to
    ``retries`` times before it answers)."""
    return sum(max(0, int(t.get("attempts") or 1) - 1) if t.get("accepted")
               else int(t.get("attempts") or 0) for t in touches)


# ------------------------------------------------------------------------------ time

def _segments(rec: dict) -> list[dict[str, Any]]:
    """The trial's runs: each from its start (first request, or the resume) to its last
    recorded activity (capture, decision), in epoch seconds; the reason it ended where known."""
    touches, decisions, events = rec["touches"], rec["decisions"], rec["events"]
    starts = [e.get("time") for e in events if e.get("event") == "resumed" and e.get("time")]
    marks: list[float] = []
    for t in touches:
        marks += [x for x in (t.get("requested"), t.get("stamp")) if x]
    marks += [x["time"] for x in decisions if x.get("time")]
    first = min(marks) if marks else None
    bounds = [first] + starts if first is not None else starts
    segs = []
    for i, s in enumerate(bounds):
        nxt = bounds[i + 1] if i + 1 < len(bounds) else float("inf")
        inside = [m for m in marks if s is not None and s <= m < nxt]
        segs.append({"start": s, "end": max(inside) if inside else s})
    ended = [e for e in events if e.get("event") in ("trial_ended", "failed")]
    # an interrupted trial's last segment has no end yet
    for seg, e in zip(segs, ended, strict=False):
        seg["reason"] = e.get("reason") or (e.get("result") or {}).get("error")
    return segs


def time_split(rec: dict) -> dict[str, float | None]:
    """Where the trial's time went [s]: ``pressing`` (request -> capture, every press),
    ``deciding`` (every decision's training and scoring), ``total`` (all its runs: a resumed
    trial counts the time before the interruption too; the final run's ``elapsed_s`` when the
    result has it) and ``waiting`` (the rest: start-up, replays, waits)."""
    press = sum(t["stamp"] - t["requested"] for t in rec["touches"]
                if t.get("stamp") and t.get("requested"))
    decide = sum(float(x.get("decision_s") or 0.0) for x in rec["decisions"])
    segs = _segments(rec)
    res = rec.get("result") or {}
    earlier = sum((s["end"] - s["start"]) for s in segs[:-1] if s["start"] is not None)
    last = res.get("elapsed_s")
    if last is None and segs and segs[-1]["start"] is not None:
        last = segs[-1]["end"] - segs[-1]["start"]
    total = None if last is None else earlier + float(last)
    wait = None if total is None else max(0.0, total - press - decide)
    return {"pressing": press, "deciding": decide, "waiting": wait, "total": total,
            "runs": len(segs)}


def _timeline(d: Path, rec: dict) -> list[tuple[float, str, bool]]:
    """(epoch s, what happened, is an interruption) for the record and, in a session, the
    session's events about this trial."""
    out: list[tuple[float, str, bool]] = []
    cfg = _config(d)
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
    sd = _session_of(d)
    if sd is not None:
        from .session import events as session_events
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
    sd = _session_of(d)
    words = _command_profiles((cfg.get("run") or {}).get("command", ""))
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
    sd = _session_of(d)
    if sd is not None:
        from .session import events as session_events
        ev = [e for e in session_events(sd) if e.get("event") in ("session_ended", "run_ended")]
        if ev:
            return str(ev[-1].get("reason"))
    return "no reason recorded (the process was stopped before it could say)"


# ------------------------------------------------------------------------------ trial report

def _context_rows(d: Path, cfg: dict, res: dict, rec: dict) -> list[list[str]]:
    run = cfg.get("run") or {}
    ex, tr, le = cfg.get("explorer") or {}, cfg.get("trial") or {}, cfg.get("learner") or {}
    prof = _command_profiles(run.get("command", ""))
    cli = cfg.get("cli") or {}
    if cli:          # `tactex trial`: touches from a source, no robot
        ex = cli
        prof = {"mode": f"no robot: touches from source {cli.get('source')}",
                "robot": "none", "sensor": "the source's recorded or simulated frames"}
    first = min([t.get("requested") or 1e18 for t in rec["touches"]] or [1e18])
    started = run.get("started") or (first if first < 1e18 else None)
    changes = dict(run.get("non_default") or {})
    changes.update(_preset_changes(cfg))
    nd = ", ".join(f"<code>{_esc(k)}={_esc(json.dumps(v))}</code>"
                   for k, v in sorted(changes.items())) or "none"
    ids, fabrics = _scene_fabrics(d)
    scene = ", ".join(f"{_esc(p)}: {_esc(fabrics.get(p, '?'))}" for p in ids)
    missing = "<span class='muted'>not recorded</span>"
    sess = cfg.get("session") or {}
    rows = [["date", _esc(_when(started)) or missing],
            ["tactex", (_esc(run.get("version")) or missing) + " &middot; commit "
             + (f"<code>{_esc(run['commit'])}</code>" if run.get("commit") else missing)],
            ["command", f"<code id='command'>{_esc(run['command'])}</code>"
             if run.get("command") else missing],
            ["preset", _esc(ex.get("config") or "default")],
            ["model", _esc(res.get("model") or le.get("model"))],
            ["strategy", _esc(res.get("strategy") or tr.get("strategy"))],
            ["stop threshold", f"belief &ge; {_esc(tr.get('stop_confidence'))}"],
            ["rounds cap", _esc(tr.get("rounds"))],
            ["settings changed from the preset", nd],
            ["seed", _esc(ex.get("seed"))],
            ["simulation or robot", _esc(prof.get("mode")) or missing],
            ["robot profile", _esc(prof.get("robot")) or missing],
            ["sensor", _esc(prof.get("sensor")) or missing],
            ["scene", f"{_esc(Path(ex.get('scene_file') or '').name or ex.get('source'))} "
                      f"&middot; {scene}"],
            ["host", _esc(run.get("host")) or missing]]
    if sess:
        rows.insert(0, ["session trial", f"{_esc(sess.get('name'))}, trial "
                                          f"{_esc(sess.get('trial'))}"])
    return rows


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


def _decision_seconds(rec: dict, t0: float | None) -> list[float | None]:
    """Seconds since the trial's first request at which each decision was made: its recorded
    time, or (older records) the capture time of the touch it followed plus its decision time."""
    out: list[float | None] = []
    accepted = [t for t in rec["touches"] if t.get("accepted")]
    for i, dec in enumerate(rec["decisions"]):
        if t0 is None:
            out.append(None)
        elif dec.get("time"):
            out.append(dec["time"] - t0)
        else:
            n = int(sum(dec.get("touches") or [])) + int(dec.get("reference_touches") or 0)
            k = min(max(n, i + 1), len(accepted)) - 1
            stamp = accepted[k].get("stamp") if accepted and k >= 0 else None
            out.append(None if stamp is None else stamp - t0
                       + float(dec.get("decision_s") or 0.0))
    return out


def trial_html(folder: str | Path) -> str:
    """The trial report of record ``folder`` as HTML text."""
    d = Path(folder)
    rec = read_record(d, images=False)
    res, cfg = rec["result"] or {}, _config(d)
    ids, fabrics = _scene_fabrics(d)
    touches, decisions = rec["touches"], rec["decisions"]
    comps = ids[1:] if ids else sorted({t.get("platform_id") for t in touches} - {None})
    strategy = res.get("strategy") or (cfg.get("trial") or {}).get("strategy", "")
    conf = (cfg.get("trial") or {}).get("stop_confidence")
    pred = res.get("prediction")
    truth = res.get("truth_platforms")
    if truth is None and (cfg.get("session") or {}).get("truth") is not None:
        truth = cfg["session"]["truth"]
    if truth is None and res and "error" not in res:
        truth = scene_truth(d)             # a record written before result.json kept it
    n_touch = len([t for t in touches if t.get("accepted")])
    final_belief = (decisions[-1].get("belief") if decisions else None) or []
    p_belief = (final_belief[comps.index(pred)] if pred in comps and
                len(final_belief) == len(comps) else None)
    sd = _session_of(d)
    parts = [f"<h1>Trial {_esc(d.name)}</h1>"]
    if sd is not None:
        parts.append(f"<p><a id='session-link' href='../{REPORT}'>&larr; session "
                     f"{_esc((cfg.get('session') or {}).get('name') or sd.name)}</a></p>")
    if not res or "error" in res:
        why = res["error"] if "error" in res else _why_unfinished(d, rec)
        parts.append(f"<p class='answer bad' id='answer'>no answer: the trial did not finish "
                     f"&mdash; <span id='unfinished-reason'>{_esc(why)}</span></p>"
                     f"<p>{len(touches)} touch(es) are on disk. Continue it with <code "
                     f"id='resume-command'>{_esc(_resume_command(d, cfg))}</code> (the "
                     "recorded touches are replayed, none is pressed twice).</p>")
    else:
        unsure = not_sure(res, conf, p_belief)
        sure = "<span id='not-sure'>not sure</span>; best guess " if unsure else ""
        fab = f" ({_esc(fabrics[pred])})" if pred in fabrics else ""
        verdict = "<span id='verdict' class='muted'>truth unknown</span>"
        if isinstance(res.get("correct"), bool) or truth is not None:
            ok = res.get("correct") if isinstance(res.get("correct"), bool) else pred in truth
            tfab = ", ".join(f"{_esc(p)}" + (f" ({_esc(fabrics[p])})" if p in fabrics else "")
                             for p in truth or [])
            # a not-sure answer is never called correct (its best guess may be right)
            verdict = ("<span id='verdict' class='muted'>not sure</span> (the best guess is "
                       "the true match)" if ok and unsure else
                       "<span id='verdict' class='ok'>correct</span>" if ok else
                       f"<span id='verdict' class='bad'>wrong</span>: the true match is "
                       f"<b id='truth'>{tfab}</b>")
        parts.append(f"<p class='answer' id='answer'>The reference matches <b "
                     f"id='prediction'>{_esc(pred)}</b>{fab}: {sure}belief "
                     f"{_fmt(p_belief, '.2f')}, stopped: <span id='stop-reason'>"
                     f"{_esc(stop_text(res, unsure))}</span> &mdash; {verdict}</p>")
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
             ("time", f"<span id='time-total'>{_duration(split['total'])}</span> in "
                      f"{split['runs']} run(s): pressing {_duration(split['pressing'])}, "
                      f"deciding {_duration(split['deciding'])}, waiting "
                      f"{_duration(split['waiting'])}")]
    if truth is not None:
        facts.append(("true match", _esc(", ".join(truth))))
    parts.append(_table([], [[k, v] for k, v in facts], left=2, cls="context",
                        tid="facts"))
    parts.append("<h2>Context</h2>" + _table([], _context_rows(d, cfg, res, rec), left=2,
                                              cls="context", tid="context"))

    parts.append("<h2>Platforms and their touches</h2><p class='muted'>click a touch for the "
                 "full-size image beside the sensor's no-contact frame; click elsewhere to "
                 "close</p><div class='platforms'>")
    nc_css: dict[str, str] = {}
    for pid in ids or sorted({t.get("platform_id") for t in touches}):
        imgs = [t for t in touches if t.get("platform_id") == pid and t.get("image")]
        tags = []
        for t in imgs:
            uri = _png_data(d / t["image"])
            if not uri:
                continue
            nc = t.get("no_contact")
            if nc and nc not in nc_css:
                nuri = _png_data(d / nc)
                if nuri:
                    nc_css[nc] = f".nc-{len(nc_css)}{{background-image:url({nuri})}}"
            ncls = ""
            if nc in nc_css:
                ncls = nc_css[nc].split("{")[0][1:]
            cap = (f"touch {t['seq']} of {_esc(pid)}: {_fmt(t.get('force_n'), '.1f')} N"
                   + ("; right: no-contact frame" if ncls else "; no no-contact frame "
                      "recorded"))
            tags.append(f"<figure class='touch' tabindex='0'><img class='touch' alt='touch "
                        f"{t['seq']} of {_esc(pid)}' title='touch {t['seq']}: "
                        f"{_fmt(t.get('force_n'), '.1f')} N' src='{uri}'>"
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
        parts.append(f"<div class='platform {' '.join(cls)}' data-platform='{_esc(pid)}'>"
                     f"<b>{_esc(pid)}</b> <span class='muted'>{role}"
                     f"{' &middot; ' + _esc(fabrics[pid]) if pid in fabrics else ''}</span> "
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
    secs = _decision_seconds(rec, min(t0s) if t0s else None)
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
        parts.append(f"<div class='{'bad' if bad else ''}'>{_esc(_when(t))} &mdash; "
                     f"{_esc(text)}</div>")
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
            why = (f"{_esc(strategy)} score {u[k]:.3g}"
                   + (" (highest)" if rank == 1 else f" (rank {rank})"))
        elif nxt:
            why = "reference (re-touch)" if ids and nxt == ids[0] else "as scheduled"
        rows.append([_esc(dec.get("round")), _esc(nxt or "-"), why,
                     " ".join(f"{_esc(c)} {v:.2f}" for c, v in zip(comps, b, strict=False)),  # b: [] without belief
                     _fmt(dec.get("decision_s"), ".2f")])
    parts.append(_table(["round", "next", "reason", "belief", "decision [s]"], rows, left=4))

    parts.append("<h2>Presses</h2>")
    rows = []
    for t in touches:
        dt = (t["stamp"] - t["requested"]) if t.get("stamp") and t.get("requested") else None
        ok = "yes" if t.get("accepted") else f"no: {_esc(t.get('reason'))}"
        depth = t.get("depth_m")
        att = int(t.get("attempts") or (1 if t.get("accepted") else 0))
        failed = att - 1 if t.get("accepted") else att
        why = t.get("attempt_failures") or ""
        rows.append([_esc(t.get("seq")), _esc(t.get("platform_id")), _fmt(dt, ".2f"),
                     _fmt(t.get("force_n"), ".2f"),
                     _fmt(None if depth is None else depth * 1e3, ".2f"),
                     f"{att}" + (f" <span class='bad'>({failed} failed"
                                 + (f": {_esc(why)}" if why else "") + ")</span>"
                                 if failed else ""), ok])
    parts.append(_table(["touch", "platform", "press [s]", "force [N]", "depth [mm]",
                         "attempts", "accepted"], rows, left=2, cls="presses"))
    return _page(f"tactex trial {d.name}", "".join(parts), "".join(nc_css.values()))


def write_trial_report(folder: str | Path) -> Path:
    """Write ``<folder>/report.html`` (atomically); returns its path."""
    d = Path(folder)
    return _write(d / REPORT, trial_html(d))


def anytime_answers(rec: dict, comps: list[str]) -> list[tuple[int, str]]:
    """(comparison touches so far, argmax platform) after every recorded decision."""
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
    evs = sess.events(d)
    done = [r for r in summ["trials"] if r["done"] and not r.get("skipped")]
    acc = summ["accuracy"]
    k = sum(r["correct"] is True for r in done)
    unsure_n = summ.get("not_sure", 0)
    lo, hi = wilson(k, len(done))
    times = [e["time"] for e in evs if e.get("time")]
    span = (max(times) - min(times)) if times else None
    parts = [f"<h1>Session {_esc(summ['name'])}</h1>",
             f"<p class='answer' id='accuracy'>accuracy <b>{_fmt(acc, '.3f')}</b> "
             f"({k} of {len(done)} trials correct, <span id='not-sure-count'>{unsure_n}"
             f"</span> not sure; 95 % interval (Wilson) "
             f"<span id='accuracy-ci'>{lo:.2f}&ndash;{hi:.2f}</span>, n = "
             f"<span id='n'>{len(done)}</span>; {summ['done']} of {summ['total']} trials "
             "done)</p>"]
    set_ = started.get("settings") or {}
    starts = [e for e in evs if e.get("event") in ("started", "resumed")]
    ends = [e for e in evs if e.get("event") in ("session_ended", "run_ended")]
    info = [["trial file", f"<code>{_esc(started.get('path'))}</code>"],
            ["first event", _esc(_when(min(times) if times else None))],
            ["last event", _esc(_when(max(times) if times else None))],
            ["duration", f"<span id='duration'>{_duration(span)}</span> (first to last "
                         f"event; {len(starts)} start(s), {len(ends)} interruption(s))"],
            ["settings", ", ".join(f"<code>{_esc(k_)}={_esc(json.dumps(v))}</code>"
                                   for k_, v in sorted(set_.items())) or "not recorded"]]
    for e in ends:
        info.append(["interrupted", f"{_esc(_when(e.get('time')))}: {_esc(e.get('reason'))}"])
    for e in evs:                    # the operator's pause / resume / abort / skip / redo
        if e.get("event") == "operator":
            who = _esc(e.get("by")) + (f", {_esc(e['caller'])}" if e.get("caller") else "")
            info.append(["operator", f"<span class='operator'>{_esc(_when(e.get('time')))}: "
                                     f"{_esc(e.get('action'))} trial {_esc(e.get('trial'))} "
                                     f"(by {who})</span>"])
    if summ["done"] < summ["total"]:
        # the last run's --trials while one of them is not done: its interrupted trial first
        asked = (starts[-1].get("trials_asked") if starts else None) or []
        left = {r["id"] for r in summ["trials"] if not r["done"]}
        words = ["tactex", "graph", "run", "--session-dir", str(d.resolve())]
        if left & set(asked):
            words += ["--trials", ",".join(asked)]
        info.append(["continue with", f"<code id='resume-command'>"
                                      f"{_esc(shlex.join(words))}</code>"])
    parts.append(_table([], info, left=2, cls="context", tid="context"))
    rows = []
    curves: list[list[tuple[int, bool]]] = []
    fabrics: list[str] = []
    conf: dict[tuple[str, str], int] = {}
    # a cut session: started trials past the summarised ones are left out
    for r, t in zip(summ["trials"], started["trials"], strict=False):
        link = f"<a href='{_esc(r['record'])}/{REPORT}'>{_esc(r['id'])}</a>"
        if not r["done"]:
            state = "not started" if not (d / r["record"]).is_dir() else "unfinished"
            rows.append([link, _esc(list(t["placement"].values())[0]), "", "", "", "", "",
                         f"<span class='muted'>{state}</span>"])
            continue
        if r.get("skipped"):
            rows.append([_esc(r["id"]), _esc(list(t["placement"].values())[0]), "",
                         _esc(r["touches"]), "", "", "skipped by the operator",
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
        stop_conf = (_config(d / r["record"]).get("trial") or {}).get("stop_confidence")
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
        rows.append([link, _esc(ref_fab), f"{_esc(r['prediction'])} ({_esc(got)})"
                     + (" <span class='muted'>not sure</span>" if unsure else ""),
                     _esc(r["touches"]), _esc(n_cmp), _fmt(split["total"], ".1f"),
                     _esc(stop_text(res, unsure)), mark])
        curves.append([(n, a in t["truth"]) for n, a in anytime_answers(rec, comps_)])
    parts.append("<h2>Trials</h2>" + _table(
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
    mrows = [[_esc(a)] + [(f"<b>{conf.get((a, b), 0)}</b>" if a == b else
                           str(conf.get((a, b), 0) or "")) for b in fabrics] for a in refs]
    parts.append(_table(head, mrows, left=1, cls="confusion"))
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
