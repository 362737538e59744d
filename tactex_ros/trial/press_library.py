"""A lab's own library pressed by its robot: N materials x K presses into the folder layout
``tactex prepare`` reads (``replay:DIR``: one folder per material, one video per press;
``sources/replay.py``), without ROS (``LibraryPressing``).

Each material is placed by the operator on one platform (the scene's reference unless
another is named) and confirmed as a session's placement is (``session_run.Operator``:
told, then waited for; the same prompt and confirmation events), then pressed until it has
K presses the trial's contact guard accepts (``core.guards.press_verdict``; a refused or
failed press is recorded and pressed again, ``MAX_FAILED`` in a row end the run). Every press
is a file the moment it arrives (written whole and atomically): a run cut off (Ctrl-C) keeps
every press made, and the next run on the folder presses only what is missing, asking for
the placement again (the platform may have been cleared meanwhile). The folder is never a
foreign one: a non-empty folder without ``library.json`` is refused.

Folder ``<out>/``::

    library.json            this is a tactex press library: its format, simulated or not
    library_events.jsonl    every run's start, prompts, confirmations, presses saved, refused
                            or failed (with the press's force, depth and pose), its end; in
                            a session's event names (``trial``: the material), so that the
                            session runner (``ros/devrun/session_runner.py``) follows it
    <material>/press_0001.mkv   one press: lossless FFV1 video, the sensor's no-contact frame
                            (3 times), the contact frame, then its further in-contact frames
    library_result.json     written (atomically) once every material of a run has its presses
    .superseded/<material>.<k>/   a material's presses set aside by the operator's redo
    .logs/<time>/           the nodes' logs (``tactex graph library``)

Hidden folders are no material: ``tactex prepare`` and every ``replay:`` reader skip them.
"""

from __future__ import annotations

import json
import logging
import os
import tempfile
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any
from collections.abc import Callable

import numpy as np

from ..core.errors import InputError, TrialError
from .record import append_line, name_problem
from .session import SessionTrial

LIBRARY_FILE = "library.json"
EVENTS_FILE = "library_events.jsonl"
RESULT_FILE = "library_result.json"
FORMAT = "tactex press library"
PRESS_SUFFIX = ".mkv"
NO_CONTACT_COPIES = 3         # the replay reader's no-contact frame: median of the first 3
MAX_FAILED = 5                # presses failed or refused in a row before the run ends
MAX_PRESSES = 1000            # presses per material a run may ask for


def parse_materials(text: str, allowed: list[str] | None = None) -> list[str]:
    """The materials ``text`` names (``a,b,c``; spaces around a name ignored), in order.
    InputError naming the problem: none, an empty or hidden name (leading '.'), one that is
    not a plain folder name (``record.name_problem``), a name given twice, or (``allowed``:
    a simulation's fabric catalogue) a name not among ``allowed``, which are listed."""
    names = [t.strip() for t in str(text or "").split(",")]
    if not any(names):
        raise InputError("--materials: give the materials' names, separated by commas "
                         "(e.g. --materials cork,felt,sandpaper)")
    for n in names:
        why = "empty (a ',' with nothing on one side)" if not n else name_problem(n)
        if why is None and n.startswith("."):
            why = "a hidden name (leading '.'): replay readers skip hidden folders"
        if why:
            raise InputError(f"--materials {text!r}: material {n!r}: {why}; a material is "
                             "a plain folder name (letters, digits, '_', '-', '.')")
    twice = sorted({n for n in names if names.count(n) > 1})
    if twice:
        raise InputError(f"--materials {text!r}: {', '.join(twice)} given twice")
    if allowed is not None:
        bad = [n for n in names if n not in allowed]
        if bad:
            raise InputError(f"--materials {text!r}: {', '.join(bad)} not in the simulator's "
                             f"fabric catalogue (config/fabrics.yaml; in simulation a material "
                             f"is one of: {', '.join(allowed)})")
    return names


def check_presses(presses: int) -> int:
    """``presses`` per material, 1..``MAX_PRESSES``; InputError naming the range otherwise."""
    if isinstance(presses, bool) or not isinstance(presses, int) or \
            not 1 <= presses <= MAX_PRESSES:
        raise InputError(f"--presses {presses!r}: a whole number of presses per material, "
                         f"1..{MAX_PRESSES}")
    return presses


def read_library_file(out: str | Path) -> dict[str, Any] | None:
    """``library.json`` of ``out`` checked to be a tactex press library's (None: absent);
    InputError naming the path when it is unreadable or another program's."""
    p = Path(out) / LIBRARY_FILE
    if not p.exists():
        return None
    try:
        doc = json.loads(p.read_text())
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise InputError(f"library {str(p)!r} is unreadable or torn ({exc}): choose another "
                         "--out folder") from None
    if not isinstance(doc, dict) or doc.get("format") != FORMAT or \
            not isinstance(doc.get("sim"), bool):
        raise InputError(f"{str(p)!r} is not a tactex press library's (format {FORMAT!r}): "
                         "choose another --out folder")
    return doc


def check_library_dir(out: str | Path, sim: bool) -> bool:
    """Before anything is written: ``out`` can be written and is new, empty or a press
    library made the same way (``sim``: simulated presses; the two never mix). True when a
    library is there to continue. InputError (exit status 2) naming the path otherwise: a
    non-empty folder that is no press library is never written into."""
    from ..core.outputs import check_dir
    d = Path(out)
    check_dir(d, "--out")
    if d.is_dir() and not os.access(d, os.W_OK | os.X_OK):
        raise InputError(f"--out {str(d)!r}: not writable")
    was = read_library_file(d)
    if was is None:
        if d.is_dir() and any(d.iterdir()):
            left = sorted(f.name for f in d.iterdir())
            raise InputError(f"--out {str(d)!r} is not empty ({', '.join(left[:3])}"
                             f"{' ...' if len(left) > 3 else ''}) and holds no "
                             f"{LIBRARY_FILE}: it is not a press library this can continue; "
                             "choose a new or empty folder")
        return False
    if was["sim"] != bool(sim):
        def kind(s: bool) -> str:
            return "simulated" if s else "robot"
        raise InputError(f"--out {str(d)!r} holds {kind(was['sim'])} presses; this run makes "
                         f"{kind(sim)} presses and the two never mix: choose another folder")
    return True


def open_library(out: str | Path, sim: bool) -> bool:
    """``check_library_dir``, then ``library.json`` written when the folder is new. True when
    an existing library is continued."""
    from ..core.outputs import dumps, write_bytes
    if check_library_dir(out, sim):
        return True
    write_bytes(Path(out) / LIBRARY_FILE, dumps({"format": FORMAT, "version": 1, "sim": sim,
                                                 "created": time.time()}).encode())
    return False


def press_files(out: str | Path, material: str) -> list[Path]:
    """The material's press files in ``out``, in press order."""
    d = Path(out) / material
    return sorted(d.glob("press_*" + PRESS_SUFFIX)) if d.is_dir() else []


def press_video(touch: Any) -> list[np.ndarray]:
    """The frames of a press file for ``touch`` (``core.touch.Touch``, RGB): its no-contact
    frame ``NO_CONTACT_COPIES`` times (the contact frame's own when it has none), the contact
    frame, its further in-contact frames; each RGB uint8 (240, 320, 3)."""
    nc = touch.no_contact if touch.no_contact is not None else touch.frame
    extra = [] if touch.extra is None else list(touch.extra)
    return [nc] * NO_CONTACT_COPIES + [touch.frame] + extra


def write_press(path: str | Path, touch: Any) -> Path:
    """One press file (``press_video``, lossless FFV1 at 25 fps), written whole and
    atomically (encoded in a temporary folder, then ``outputs.write_bytes``). WriteError
    names the path when it cannot be written; TrialError when this OpenCV cannot encode."""
    import cv2

    from ..core.outputs import write_bytes
    frames = press_video(touch)
    h, w = frames[0].shape[:2]
    with tempfile.TemporaryDirectory(prefix="tactex-press-") as tmp:
        f = Path(tmp) / ("press" + PRESS_SUFFIX)
        vw = cv2.VideoWriter(str(f), cv2.VideoWriter.fourcc(*"FFV1"), 25.0, (w, h))
        if not vw.isOpened():
            raise TrialError("this OpenCV cannot write FFV1 video (its FFmpeg backend is "
                             f"missing): press file {str(path)!r} not written")
        try:
            for fr in frames:
                vw.write(cv2.cvtColor(np.ascontiguousarray(fr), cv2.COLOR_RGB2BGR))
        finally:
            vw.release()
        return write_bytes(path, f.read_bytes())


def add_event(out: str | Path, event: dict[str, Any]) -> None:
    """Append one line to ``library_events.jsonl`` (fsync'ed)."""
    from ..core.outputs import dumps
    p = Path(out) / EVENTS_FILE
    append_line(p, (dumps(event, indent=None) + "\n").encode(), p)


def events(out: str | Path) -> list[dict]:
    """The library's events (a torn last line is skipped)."""
    from .record import _read_jsonl
    return _read_jsonl(Path(out) / EVENTS_FILE)


def counts(out: str | Path, materials: list[str]) -> dict[str, int]:
    """Press files on disk per material."""
    return {m: len(press_files(out, m)) for m in materials}


@dataclass
class LibraryPressing:
    """A run that presses ``materials`` ``presses`` times each on platform ``platform`` into
    the library ``out`` (opened, or continued: ``open_library``); ``sim``: the presses are
    simulated. ``log(level, text)``: where its lines go."""

    out: Path
    materials: list[str]
    presses: int
    platform: str
    sim: bool = False
    log: Callable[[int, str], None] = field(
        default=lambda level, text: logging.getLogger("tactex.library").log(level, text))
    resumed: bool = False
    made: int = 0                     # presses saved in this run

    def __post_init__(self) -> None:
        self.out = Path(self.out).resolve()
        check_presses(self.presses)
        parse_materials(",".join(self.materials))
        open_library(self.out, self.sim)    # ``tactex graph library`` opens it first
        self.resumed = any(e.get("event") in ("started", "resumed") for e in events(self.out))
        add_event(self.out, {"event": "resumed" if self.resumed else "started",
                             "materials": self.materials, "presses": self.presses,
                             "platform": self.platform, "have": self.counts(),
                             "time": time.time()})

    def counts(self) -> dict[str, int]:
        """Press files on disk per material of this run."""
        return counts(self.out, self.materials)

    def done(self) -> int:
        """Presses of this run's materials on disk, at most ``presses`` each."""
        return sum(min(n, self.presses) for n in self.counts().values())

    def _end(self, why: str, code: int, **more: Any) -> int:
        self.log(logging.ERROR if code else logging.INFO, f"library run ended: {why}")
        add_event(self.out, {"event": "session_ended", "reason": why, **more,
                             "time": time.time()})
        return code

    def _prompt(self, operator: Any, trial: SessionTrial, k: int, n: int, have: int) -> bool:
        """Tell the operator what to place and wait for the confirmation (events as a
        session's: ``awaiting_confirmation``, ``confirmed``); False when not confirmed in
        time."""
        pid, material = next(iter(trial.placement.items()))
        text = (f"library {self.out.name}, material {material} ({k}/{n}): place {material} "
                f"on platform {pid} ({self.presses - have} presses to make) -- then confirm")
        operator.expect(trial.id)
        self.log(logging.INFO, text)
        add_event(self.out, {"event": "awaiting_confirmation", "trial": trial.id,
                             "what": "material", "number": k, "of": n,
                             "placement": trial.placement, "text": text, "time": time.time()})
        operator.tell(text)
        got = operator.wait()
        if got is None:
            return False
        by, caller = got
        add_event(self.out, {"event": "confirmed", "trial": trial.id, "what": "material",
                             "by": by,
                             "caller": caller or None, "time": time.time()})
        return True

    def supersede(self, material: str, by: dict[str, Any]) -> Path:
        """The operator's redo: the material's presses so far go to
        ``.superseded/<material>.<k>`` (kept, named in the events); it is pressed afresh."""
        root = self.out / ".superseded"
        root.mkdir(exist_ok=True)
        k = 1 + sum(1 for _ in root.glob(material + ".*"))
        old = root / f"{material}.{k}"
        os.replace(self.out / material, old)
        add_event(self.out, {"event": "superseded", "trial": material,
                             "record": str(old.relative_to(self.out)), **by,
                             "time": time.time()})
        return old

    def run(self, operator: Any, press: Callable[[dict], Any],
            stopping: Callable[[], bool],
            accept: Callable[[Any], tuple[bool, str]] = lambda touch: (True, ""),
            control: Any = None) -> int:
        """Every material not yet complete, in order: the placement confirmed
        (``operator``: ``session_run.Operator``), then ``press(meta)`` until it has
        ``presses`` accepted presses (``accept(touch)``: (ok, why); ``meta``: the press's
        fields, filled by ``press``). ``control`` (``trial.control.OperatorControl``, or
        None): the operator's pause, abort, skip and redo hold each material as a trial.
        Returns the exit status: 0 (done, or stopped / aborted: resumable), 1 (a placement
        not confirmed, ``MAX_FAILED`` presses in a row failed, a press not written)."""
        from ..core.engine import TouchFailed
        from .control import OperatorStop
        mats, K = self.materials, self.presses
        try:
            for k, m in enumerate(mats, 1):
                have = len(press_files(self.out, m))
                if have >= K:
                    continue
                trial = SessionTrial(id=m, position=k - 1, seed=0,
                                     placement={self.platform: m}, truth=[])
                if not self._prompt(operator, trial, k, len(mats), have):
                    return self._end(f"placement of material {m} not confirmed in time", 1,
                                     trial=m)
                operator.place(trial)
                if control is not None:
                    control.start(m)
                failed = 0
                try:
                    while have < K:
                        if stopping():
                            return 0
                        meta: dict[str, Any] = {}
                        try:
                            touch = press(meta)
                            ok, why = accept(touch)
                        except TouchFailed as exc:
                            ok, why = False, str(exc)
                        except OperatorStop as stop:
                            said = {"by": stop.by, "caller": stop.caller or None}
                            if stop.action == "abort":
                                return self._end(f"material {m} aborted by the operator "
                                                 f"({stop.by})", 0, trial=m, aborted=True,
                                                 **said)
                            if stop.action == "skip":
                                add_event(self.out, {"event": "material_skipped",
                                                     "trial": m, "have": have, **said,
                                                     "time": time.time()})
                                break
                            if have:               # redo: pressed afresh
                                self.supersede(m, said)
                            have = 0
                            continue
                        if not ok:
                            failed += 1
                            add_event(self.out, {"event": "press_refused", "trial": m,
                                                 "reason": why, "in_a_row": failed,
                                                 "meta": meta, "time": time.time()})
                            self.log(logging.WARNING, f"material {m}: press not kept: {why}")
                            if failed >= MAX_FAILED:
                                return self._end(f"material {m}: {failed} presses in a row "
                                                 f"failed or were refused (the last: {why})",
                                                 1, trial=m)
                            continue
                        failed = 0
                        have += 1
                        path = self.out / m / f"press_{have:04d}{PRESS_SUFFIX}"
                        write_press(path, touch)
                        self.made += 1
                        add_event(self.out, {"event": "press_saved", "trial": m,
                                             "press": have, "of": K,
                                             "file": str(path.relative_to(self.out)),
                                             "meta": meta, "time": time.time()})
                finally:
                    if control is not None:
                        control.end()
                if have >= K:
                    add_event(self.out, {"event": "material_done", "trial": m,
                                         "presses": have, "time": time.time()})
            out = {"folder": str(self.out), "materials": self.counts(), "presses": K,
                   "platform": self.platform, "sim": self.sim, "made": self.made,
                   "complete": all(n >= K for n in self.counts().values())}
            from ..core.outputs import dumps, write_bytes
            write_bytes(self.out / RESULT_FILE, dumps(out).encode())
            add_event(self.out, {"event": "session_done", "time": time.time(), **out})
            self.log(logging.INFO, f"library {self.out}: {self.done()} presses of "
                                   f"{len(mats)} materials ({self.made} in this run)")
            return 0
        except Exception as exc:  # the run must end in an explicit, recorded state
            if stopping():
                return 0
            try:
                return self._end(f"{type(exc).__name__}: {exc}", 1)
            except TrialError as why:        # a full disk may refuse the event too
                self.log(logging.ERROR, f"library run end not recorded: {why}")
                return 1
