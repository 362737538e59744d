"""Where a trial's time went: its runs (a resumed trial has several), the split into pressing,
deciding and waiting, and the time of each decision."""

from __future__ import annotations

from typing import Any


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



def decision_seconds(rec: dict, t0: float | None) -> list[float | None]:
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

