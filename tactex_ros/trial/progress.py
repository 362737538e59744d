"""Progress in the terminal while the graph runs: one line per press and per decision.

``Progress`` follows a trial record folder (``touches.jsonl``, ``decisions.jsonl``,
``events.jsonl``: the files the explorer fsyncs as it goes) and prints each new line once: a
press (platform, force [N], press time [s], failed attempts), a decision (round k of the
rounds cap N; the answer after the last capped round is "final", never "5/4"), belief per
platform, the next platform, the time since the trial's first press (the time it was
interrupted, from its last record line to the resume, left out: ``interrupted_s``; the
operator's pauses too, as the result's ``elapsed_s`` leaves them out) and an
estimate of the rest: the mean round so far times the rounds left, an upper bound as the
trial may stop earlier) and how a resume went (learner checkpoint restored, or re-training).
Touches and decisions a resumed trial had on disk before its interruption are marked
"replayed": they were pressed before, not now. A record folder replaced at the same path (a
redo) is followed afresh from its first line. Until the record folder exists (the nodes are
starting, 10-25 s) it says so once after ``STARTING_EVERY_S``, then every
``STARTING_AGAIN_S``, and no more once the nodes are up (``nodes_up``: a session's placement
prompt is not buried under it); while nothing new arrives (a thesis
CNN's decision takes 27-98 s) every ``WAITING_EVERY_S``. On a terminal it prints through
``rich`` (colour); in a log (not a terminal) plain lines.
"""

from __future__ import annotations

import json
import sys
import time
from pathlib import Path
from typing import Any
from collections.abc import Callable


#: [s] a decision still under way after this long (the thesis CNN: 27-98 s) is said so again
WAITING_EVERY_S = 30.0
#: [s] while the record folder does not exist yet (the nodes start), said first after this
STARTING_EVERY_S = 5.0
#: [s] ... and again every this often while it still does not exist (a slow start)
STARTING_AGAIN_S = 30.0


def press_line(t: dict[str, Any], replayed: bool = False) -> str:
    """One press as text (``replayed``: pressed before an interruption, replayed now)."""
    dt = (t["stamp"] - t["requested"]) if t.get("stamp") and t.get("requested") else None
    text = f"press {t.get('seq')}: {t.get('platform_id')}"
    if t.get("force_n") is not None:
        text += f" {t['force_n']:.1f} N"
    if dt is not None:
        text += f" {dt:.1f} s"
    att = int(t.get("attempts") or 0)
    failed = att - 1 if t.get("accepted") else att
    if failed > 0:
        text += f" ({failed} failed attempt{'s' if failed > 1 else ''})"
    if not t.get("accepted"):
        text += f" (not used: {t.get('reason')})"
    if replayed:
        text += " [replayed: pressed before the interruption]"
    return text


def clock_text(s: float) -> str:
    """``s`` [s] as m:ss (rounded to the second)."""
    s = int(round(max(0.0, s)))
    return f"{s // 60}:{s % 60:02d}"


def decision_line(dec: dict[str, Any], platform_ids: list[str], rounds: int | None = None,
                  elapsed_s: float | None = None, rest_s: float | None = None,
                  replayed: bool = False) -> str:
    """One decision as text: round k of ``rounds``, belief per comparison platform, the next
    platform; ``elapsed_s`` since the first press and ``rest_s`` (at most) where known."""
    b = dec.get("belief") or []
    # strict=False: a decision may lack its belief, and the ids may not be known yet (trial.json
    # not read); a progress line shows what it has rather than failing the follower
    belief = " ".join(f"{p} {v:.2f}" for p, v in zip(platform_ids, b, strict=False))
    nxt = dec.get("next") or ("done: " + str(dec.get("prediction")) if dec.get("done") else "-")
    r = dec.get("round")
    # the answer given after the last capped round is its own decision: never "5/4"
    k = (f"{r}/{rounds}" if rounds and isinstance(r, int) and r <= rounds else
         f"{r} (final, after the rounds cap {rounds})" if rounds else f"{r}")
    text = f"decision {k}: belief {belief} -> next {nxt}"
    if elapsed_s is not None:
        text += f" [{clock_text(elapsed_s)} elapsed"
        if rest_s is not None and not dec.get("done"):
            text += f", at most about {clock_text(rest_s)} left"
        text += "]"
    if replayed:
        text += " [replayed]"
    return text


def tail_jsonl(path: Path, offset: int) -> tuple[list[dict], int]:
    """The whole JSON lines of ``path`` after byte ``offset`` and the offset after them (a line
    still being written waits for its end; a torn line is skipped)."""
    try:
        with open(path, "rb") as f:
            f.seek(offset)
            data = f.read()
    except OSError:
        return [], offset
    end = data.rfind(b"\n") + 1
    out = []
    for line in data[:end].splitlines():
        try:
            out.append(json.loads(line))
        except json.JSONDecodeError:
            continue
    return out, offset + end


class Progress:
    """Prints what is new in the followed record folder each time ``poll()`` is called."""

    def __init__(self, out: Callable[[str, str], None] | None = None,
                 clock: Callable[[], float] = time.monotonic,
                 every_s: float = WAITING_EVERY_S) -> None:
        self.out = out or console_printer()
        self.clock = clock
        self.every_s = every_s
        self.folder: Path | None = None
        self._offsets: dict[str, int] = {}
        self._ids: list[str] = []
        self._deciding: int | None = None    # the decision the explorer is making (round)
        self._since = 0.0                    # clock of the last line printed
        self._waited = 0.0                   # [s] since the last touch or decision
        self._started = clock()              # for the start-up line
        self._start_said: float | None = None   # clock of the last start-up line
        self._up = False                     # the nodes are up: no more start-up lines
        self._rounds: int | None = None      # the rounds cap (config.json)
        self._replayed_touches = 0           # touches on disk before the last resume
        self._replayed_decisions = 0
        self._seen_decisions = 0
        self._first: float | None = None     # epoch s of the first press request
        self._times: list[float] = []        # epoch s of every press and decision seen
        self._resumes: list[float] = []      # epoch s of each resume of the record
        self._pauses: list[list[float | None]] = []    # [pause, resume] epoch s (operator)
        self._inode: int | None = None       # the followed folder's (a redo replaces it)

    def follow(self, folder: str | Path | None) -> None:
        """Follow another record folder (the next trial of a session)."""
        folder = Path(folder) if folder else None
        if folder != self.folder:
            self.folder = folder
            self._afresh()

    def _afresh(self) -> None:
        """Nothing of the followed folder seen yet."""
        self._offsets, self._ids, self._inode = {}, [], None
        self._deciding, self._rounds, self._first = None, None, None
        self._times, self._resumes, self._pauses = [], [], []
        self._replayed_touches = self._replayed_decisions = self._seen_decisions = 0

    def nodes_up(self) -> None:
        """Every node is up (e.g. a session's placement prompt is out): the start-up line is
        not printed again."""
        self._up = True

    def _interrupted(self, until: float) -> float:
        """[s] the trial was interrupted (stopped, then resumed) or held by the operator's
        pause before ``until``: not part of its elapsed time (nor of the result's
        ``elapsed_s``) nor of the estimate of the rest."""
        first = self._first if self._first is not None else -float("inf")
        held = sum(max(0.0, min(r if r is not None else until, until) - max(p, first))
                   for p, r in self._pauses if p is not None)
        return interrupted_s(self._times, self._resumes, until) + held

    def _new_lines(self, name: str) -> list[dict]:
        lines, self._offsets[name] = tail_jsonl(self.folder / name, self._offsets.get(name, 0))
        return lines

    def poll(self) -> None:
        now = self.clock()
        if self.folder is None or not self.folder.is_dir():
            due = (now - self._started >= STARTING_EVERY_S if self._start_said is None
                   else now - self._start_said >= STARTING_AGAIN_S)
            if due and not self._up:
                self._start_said = now
                self.out(f"starting the nodes: {now - self._started:.0f} s (the first press "
                         "follows once every node is up)", "info")
            return
        try:
            inode = self.folder.stat().st_ino
        except OSError:
            return
        if self._inode is not None and inode != self._inode:
            self._afresh()         # a redo moved the record away: a new one at the same path
        self._inode = inode
        if not self._ids:
            self._ids = _comparison_ids(self.folder)
        if self._rounds is None:
            self._rounds = _rounds_cap(self.folder)
        printed = False
        for e in self._new_lines("events.jsonl"):
            if e.get("event") == "resumed":
                if isinstance(e.get("time"), (int, float)):
                    self._resumes.append(float(e["time"]))
                self._replayed_touches = int(e.get("after_touch") or 0)
                self._replayed_decisions = int(e.get("decisions_on_disk") or 0)
                if e.get("how"):
                    self.out(f"resume: {e['how']}", "info")
                    printed = True
            elif e.get("event") == "operator" and isinstance(e.get("time"), (int, float)):
                at = float(e["time"])
                if e.get("action") == "pause":
                    self._pauses.append([at, None])
                elif self._pauses and self._pauses[-1][1] is None:    # resume, skip, ...
                    self._pauses[-1][1] = at
        for t in self._new_lines("touches.jsonl"):
            if self._first is None and t.get("requested"):
                self._first = float(t["requested"])
            self._times += [float(t[k]) for k in ("requested", "stamp")
                            if isinstance(t.get(k), (int, float))]
            self.out(press_line(t, int(t.get("seq") or 0) <= self._replayed_touches), "press")
            printed = True
        decisions = self._new_lines("decisions.jsonl")
        for d in decisions:
            self._seen_decisions += 1
            replayed = self._seen_decisions <= self._replayed_decisions
            elapsed = rest = None
            if d.get("time"):
                self._times.append(float(d["time"]))
            if self._first is not None and d.get("time"):
                elapsed = float(d["time"]) - self._first - self._interrupted(float(d["time"]))
                r = int(d.get("round") or 0)
                if self._rounds and r > 0:
                    rest = elapsed / (r + 1) * max(0, self._rounds - r)
            self.out(decision_line(d, self._ids, self._rounds, elapsed, rest, replayed),
                     "decision")
        if decisions:
            last = decisions[-1]
            self._deciding = None if last.get("done") else int(last.get("round") or 0) + 1
        elif printed and not self._offsets.get("decisions.jsonl"):
            self._deciding = 1
        if printed or decisions:
            self._since, self._waited = now, 0.0
        elif self._deciding is not None and now - self._since >= self.every_s:
            self._waited += now - self._since
            self.out(f"working: {self._waited:.0f} s without a new touch or decision "
                     f"(decisions on disk: {self._deciding - 1})", "info")
            self._since = now


def interrupted_s(times: list[float], resumes: list[float], until: float) -> float:
    """[s] of a record's interruptions before ``until`` (epoch s): for each resume before it,
    from the last press or decision recorded before the resume (``times``) to the resume."""
    gap = 0.0
    for r in resumes:
        before = [t for t in times if t < r]
        if r < until and before:
            gap += r - max(before)
    return gap


def _rounds_cap(folder: Path) -> int | None:
    """The trial's rounds cap (``config.json`` ``trial.rounds``), None when unknown."""
    try:
        r = (json.loads((folder / "config.json").read_text()).get("trial") or {}).get("rounds")
    except (OSError, json.JSONDecodeError):
        return None
    return int(r) if r else None


def _comparison_ids(folder: Path) -> list[str]:
    """Comparison platform ids of a record (scene.yaml order, reference left out)."""
    import yaml
    try:
        doc = yaml.safe_load((folder / "scene.yaml").read_text()) or {}
    except (OSError, yaml.YAMLError):
        return []
    return [str(p.get("id")) for p in doc.get("platforms") or [] if p.get("role") != "reference"]


def console_printer(stream=None) -> Callable[[str, str], None]:
    """``out(text, kind)``: rich on a terminal, plain lines otherwise (logs, pipes)."""
    stream = stream or sys.stdout
    if stream.isatty():
        from rich.console import Console
        console = Console(file=stream, highlight=False)
        style = {"press": "cyan", "decision": "green", "prompt": "bold yellow",
                 "info": "bold"}

        def out(text: str, kind: str = "info") -> None:
            console.print(text, style=style.get(kind), markup=False)
        return out

    def plain(text: str, kind: str = "info") -> None:
        print(text, file=stream, flush=True)
    return plain
