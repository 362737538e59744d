"""Trial record on disk: every touch is written (and fsync'ed) the moment it arrives.

Layout of ``<root>/<trial_id>/``::

    touches.jsonl        one JSON line per touch, in arrival order (also rejected ones)
    rejections.jsonl     touches refused after they were written (the core's guard)
    touch_0001_c1.png    the touch image (lossless RGB), name = sequence number + platform id
    extra_0001_c1_1.png  the touch's further in-contact frames (``Touch.extra``, the capture's
                         burst), lossless RGB, in their order; the touch line lists them
                         (``extra``); a record made before they were kept has none
    no_contact_0001.png  the sensor's no-contact frame that came with touch 1 (written again
                         only when it changes; each touch line names its file)
    decisions.jsonl      one JSON line per decision (the exploration state)
    events.jsonl         what happened to the trial: how it ended without a result (node exit,
                         signal, deadline), where it was resumed, each MCAP file of its topics
                         when it was started (``mcap_started``, ``ros/bag.py``)
    result.json          the trial's result (written last, atomically)
    scene.yaml, config.json   what the trial ran with

Line-per-event files with ``fsync`` after every write lose nothing already recorded when the
process dies; a reader (``read_record``) skips a torn last line, and one ended before the next
line was appended (noted as a ``torn_line`` event: ``append_line``); any other line that does
not parse, or a field of another type than ``FIELDS`` says, refuses the record with the file,
the line and the field named (InputError). This folder is the ground
truth (a resume is rebuilt from it, ``tactex_ros.trial.resume``); an MCAP file of the trial's topics
(``ros/bag.py``) is written beside it for ROS tools.
"""

from __future__ import annotations

import hashlib
import json
import math
import os
import threading
import time
from pathlib import Path
from typing import Any

import cv2
import numpy as np

from ..core.errors import InputError, TrialError
from ..core.outputs import check_dir, check_free, dumps, fsync_write, write_bytes

_fsync_write = fsync_write     # every record file is written whole or not at all (WriteError)

MIN_FREE_MB = 50.0    # [MB] default free-space margin checked before a trial and each touch


def append_event(folder: str | Path, event: dict[str, Any]) -> None:
    """Append one line to ``<folder>/events.jsonl`` (fsync'ed)."""
    p = Path(folder) / "events.jsonl"
    append_line(p, _line(event), p)


#: the event noted when a torn last line (a crashed writer's, without its newline) is ended
#: before the next line is appended (``line``: its number in ``file``); readers skip that line
TORN_LINE = "torn_line"
#: the files where ``TORN_LINE`` notes are kept: a record's events, a session's
NOTE_FILES = ("events.jsonl", "session_events.jsonl")


def _close_torn(path: Path, notes: Path) -> None:
    """End a last line that has no newline (a writer that crashed mid-line) and note its
    number in ``notes`` (``TORN_LINE``), so that no later line is joined to it."""
    try:
        with open(path, "rb") as f:
            if f.seek(0, os.SEEK_END) == 0:
                return
            f.seek(-1, os.SEEK_END)
            if f.read(1) == b"\n":
                return
            f.seek(0)
            n = f.read().count(b"\n") + 1
    except FileNotFoundError:
        return
    _fsync_write(path, b"\n", True)
    if notes != path:
        _close_torn(notes, notes)
    _fsync_write(notes, _line({"event": TORN_LINE, "file": path.name, "line": n}), True)


def append_line(path: Path, data: bytes, notes: Path) -> None:
    """Append the JSON line ``data`` to ``path`` whole and fsync'ed (``fsync_write``), after
    ending a torn last line (``_close_torn``, noted in ``notes``)."""
    _close_torn(path, notes)
    _fsync_write(path, data, True)


def _line(obj: dict[str, Any]) -> bytes:
    """One strict JSON line (NaN -> null)."""
    return (dumps(obj, indent=None) + "\n").encode()


def _last_seq(d: Path) -> int:
    """Highest touch number on disk: metadata lines and image files (an image written just
    before a crash, without its line, is never overwritten)."""
    seqs = [int(t.get("seq", 0)) for t in _read_jsonl(d / "touches.jsonl")]
    seqs += [_seq_of(f) for f in d.glob("touch_*.png")]
    return max(seqs, default=0)


RECORD_FILES = ("touches.jsonl", "config.json", "result.json", "decisions.jsonl")


def name_problem(name: str, folder: bool = True) -> str | None:
    r"""Why ``name`` is not a plain name for a trial (None: it is): empty or only spaces,
    spaces around it, a control character (a newline, a tab); a ``folder`` name also '/' or
    '\', '.' or '..' (a trial file's id is not: its record folder is ``session.record_name``)."""
    import unicodedata
    if not name.strip():
        return "empty or only spaces"
    if name != name.strip():
        return "spaces around it"
    bad = next((c for c in name if unicodedata.category(c).startswith("C")), None)
    if bad is not None:
        return f"a control character ({bad!r})"
    if not folder:
        return None
    if "/" in name or "\\" in name:
        return "a '/' or '\\'"
    if name in (".", ".."):
        return "'.' or '..'"
    return None


def check_trial_id(trial_id: str) -> None:
    """A trial id is a plain folder name (``name_problem``); InputError naming it otherwise."""
    why = name_problem(trial_id)
    if why:
        raise InputError(f"trial_id {trial_id!r}: {why}; a trial id is a plain name (letters, "
                          "digits, spaces inside, punctuation other than '/' and '\\')")


def free_trial_id(root: str | Path) -> str:
    """A new record's name in ``root`` when none is given: ``trial_<date>_<time>``, with
    ``_2``, ``_3``, ... when a record of that name is there already (two trials started in
    the same second)."""
    stem = time.strftime("trial_%Y%m%d_%H%M%S")
    name, k = stem, 1
    while (Path(root) / name).exists():
        k += 1
        name = f"{stem}_{k}"
    return name


def check_new_record(root: str | Path, trial_id: str) -> Path:
    """The folder of a new trial record ``<root>/<trial_id>``: refused (named) when the id is
    not a plain name, a record is already there (records are never overwritten) or ``root``
    cannot be written. Nothing is created."""
    check_trial_id(trial_id)
    d = Path(root) / trial_id
    if any((d / f).exists() for f in RECORD_FILES):
        raise InputError(f"trial record {str(d)!r} already exists: choose another trial_id "
                          "(records are never overwritten) or continue it with resume")
    check_dir(d, "record_dir")
    return d


def check_resumable(folder: str | Path) -> dict | None:
    """Refuse (named) a record that cannot be continued: no ``config.json``, a finished result,
    a ``result.json`` that does not parse, files that do not belong together (more decisions
    than touch lines, touch images no line names beyond the one a crash can leave), a folder
    that cannot be written. Returns the failed result to set aside, or None."""
    d = Path(folder)
    if not (d / "config.json").is_file():
        raise InputError(f"resume: {str(d)!r} is not a trial record (no config.json)")
    res = read_result(d)
    if res is not None and "error" not in res:
        raise InputError(f"resume: trial record {str(d)!r} already has its result; nothing "
                          "to resume")
    lines = _read_jsonl(d / "touches.jsonl")
    decisions = _read_jsonl(d / "decisions.jsonl")
    if len(decisions) > len(lines):
        raise InputError(f"resume: {str(d / 'decisions.jsonl')!r} holds {len(decisions)} "
                          f"decisions but {str(d / 'touches.jsonl')!r} only {len(lines)} "
                          "touches: the files do not belong together")
    named = {t.get("image") for t in lines}
    extras = [n for t in lines if not t.get("interrupted") for n in (t.get("extra") or [])]
    last = max((int(t.get("seq", 0)) for t in lines), default=0)
    orphans = sorted(f.name for f in d.glob("touch_*.png") if f.name not in named
                     and _seq_of(f) != last + 1)
    if orphans:
        raise InputError(f"resume: touch images in {str(d)!r} that no line of touches.jsonl "
                          f"names: {', '.join(orphans[:5])}"
                          f"{' ...' if len(orphans) > 5 else ''}")
    missing = [t["image"] for t in lines if t.get("image") and not t.get("interrupted")
               and not (d / t["image"]).is_file()] + [n for n in extras
                                                      if not (d / n).is_file()]
    if missing:
        raise InputError(f"resume: touch images named in touches.jsonl are missing from "
                          f"{str(d)!r}: {', '.join(missing[:5])}"
                          f"{' ...' if len(missing) > 5 else ''}")
    check_dir(d, "resume")
    if not os.access(d, os.W_OK):
        raise InputError(f"resume: {str(d)!r} is not writable")
    return res


def _seq_of(f: Path) -> int:
    try:
        return int(f.name.split("_")[1])
    except (IndexError, ValueError):
        return -1


class TrialRecord:
    """Writer for one trial's record folder.

    ``resume=False``: a new folder (an existing record is never overwritten). ``resume=True``:
    continue an existing record that has no finished result; numbering goes on after the last
    touch on disk."""

    def __init__(self, root: str | Path, trial_id: str, resume: bool = False,
                 min_free_mb: float = MIN_FREE_MB) -> None:
        check_trial_id(trial_id)
        self.dir = Path(root) / trial_id
        self.min_free_mb = float(min_free_mb)
        self.n_touches = 0
        self._no_contact: tuple[np.ndarray, str] | None = None
        self._lock = threading.Lock()      # a touch's image and line are written together
        self.closed = False
        if resume:
            res = check_resumable(self.dir)
            self.check_space("resume")
            if res is not None:                 # a failed trial: its error goes to the events
                append_event(self.dir, {"event": "failed", "result": res})
                os.remove(self.dir / "result.json")
            for f in self.dir.glob("*.jsonl"):      # a torn last line stays a line of its own
                _close_torn(f, self.dir / "events.jsonl")
            self.n_touches = _last_seq(self.dir)
            return
        check_new_record(root, trial_id)
        self.check_space("new trial")
        self.dir.mkdir(parents=True, exist_ok=True)

    def check_space(self, what: str) -> None:
        """WriteError (a run-time failure, exit status 1) when the record's disk has less than
        ``min_free_mb`` free: checked before a trial and before each touch is written."""
        check_free(self.dir, self.min_free_mb, f"trial record {str(self.dir)!r} ({what})")

    def close(self, timeout_s: float = 5.0) -> None:
        """Wait (up to ``timeout_s``) for a write in progress, then refuse further writes:
        for a process being stopped mid-trial (nothing half-written, no result)."""
        got = self._lock.acquire(timeout=timeout_s)
        self.closed = True
        if got:
            self._lock.release()

    def _open(self) -> None:
        if self.closed:
            raise TrialError(f"trial record {str(self.dir)!r} is closed (the node is stopping)")

    def save_inputs(self, scene_file: str | Path | None, config: dict,
                    scene_text: str | None = None) -> None:
        """``scene.yaml`` (``scene_text``, else a copy of ``scene_file``) and ``config.json``,
        each written whole (WriteError otherwise)."""
        if scene_text is None and scene_file:
            scene_text = Path(scene_file).read_text()
        if scene_text is not None:
            write_bytes(self.dir / "scene.yaml", scene_text.encode())
        write_bytes(self.dir / "config.json", dumps(config).encode())

    def _png(self, path: Path, image: np.ndarray) -> None:
        ok, buf = cv2.imencode(".png", np.ascontiguousarray(image[:, :, ::-1]))
        if not ok:
            raise InputError(f"could not encode {path.name} as PNG")
        _fsync_write(path, buf.tobytes(), False)

    def add_touch(self, image: np.ndarray | None, meta: dict[str, Any],
                  no_contact: np.ndarray | None = None,
                  extra: np.ndarray | None = None) -> Path | None:
        """Write the image (RGB uint8, any size; None = no usable image), its further
        in-contact frames (``extra``: (K, H, W, 3) RGB uint8 or None, each a PNG), the sensor's
        no-contact frame that came with it (written only when it differs from the last one)
        and the metadata line, last (the line commits the touch).

        Returns the image path. Called before the touch is used for anything."""
        with self._lock:
            self._open()
            self.check_space(f"touch {self.n_touches + 1}")
            return self._add_touch(image, meta, no_contact, extra)

    def _add_touch(self, image: np.ndarray | None, meta: dict[str, Any],
                   no_contact: np.ndarray | None,
                   extra: np.ndarray | None = None) -> Path | None:
        seq = self.n_touches + 1
        img_path = None
        written: list[Path] = []
        try:
            if image is not None:
                img_path = self.dir / f"touch_{seq:04d}_{meta.get('platform_id', 'x')}.png"
                self._png(img_path, image)
                written.append(img_path)
            extra_names = []
            if image is not None and extra is not None:
                for k, frame in enumerate(extra, 1):
                    name = f"extra_{seq:04d}_{meta.get('platform_id', 'x')}_{k}.png"
                    self._png(self.dir / name, frame)
                    written.append(self.dir / name)
                    extra_names.append(name)
            nc_name, nc_new = None, False
            if no_contact is not None:
                if self._no_contact is not None and np.array_equal(self._no_contact[0],
                                                                   no_contact):
                    nc_name = self._no_contact[1]
                else:
                    nc_name, nc_new = f"no_contact_{seq:04d}.png", True
                    self._png(self.dir / nc_name, no_contact)
                    written.append(self.dir / nc_name)
            line = dict(meta, seq=seq, image=img_path.name if img_path else None)
            if extra_names:
                line["extra"] = extra_names
            if nc_name is not None:
                line["no_contact"] = nc_name
            append_line(self.dir / "touches.jsonl", _line(line), self.dir / "events.jsonl")
        except BaseException:
            for f in written:        # a touch is its line: no image without one is left
                f.unlink(missing_ok=True)
            raise
        self.n_touches = seq
        if nc_new:
            self._no_contact = (np.array(no_contact, copy=True), nc_name)
        return img_path

    def reject_touch(self, seq: int, reason: str) -> None:
        """Mark touch ``seq`` (already on disk) as not used, e.g. refused by the core's guard."""
        with self._lock:
            self._open()
            append_line(self.dir / "rejections.jsonl", _line({"seq": seq, "reason": reason}),
                        self.dir / "events.jsonl")

    def add_decision(self, state: dict[str, Any]) -> None:
        with self._lock:
            self._open()
            append_line(self.dir / "decisions.jsonl", _line(state), self.dir / "events.jsonl")

    def finish(self, result: dict[str, Any]) -> Path:
        """Write ``result.json`` atomically (temporary file, fsync, rename)."""
        with self._lock:
            self._open()
            tmp = self.dir / "result.json.tmp"
            _fsync_write(tmp, dumps(result).encode(), False)
            os.replace(tmp, self.dir / "result.json")
            fd = os.open(self.dir, os.O_RDONLY)     # the rename itself survives a power loss
            try:
                os.fsync(fd)
            finally:
                os.close(fd)
            return self.dir / "result.json"

    def write_checkpoint(self, state: dict[str, Any], learner_state: bytes,
                         after_seq: int) -> Path:
        """The trial's state after a round (``TrialEngine.checkpoint``), made from the touches
        up to number ``after_seq`` of ``touches.jsonl``: the learner's opaque
        bytes in ``learner_<round>.state``, then ``checkpoint.json`` (the engine's state, the
        last touch on disk, the learner file's name, size and SHA-256) replaces the previous
        one atomically; older learner files are removed after. A crash at any point leaves
        the previous checkpoint or the new one, whole."""
        with self._lock:
            self._open()
            name = f"learner_{int(state['round']):04d}.state"
            write_bytes(self.dir / name, learner_state)
            head = {"state": state, "after_seq": int(after_seq), "learner_file": name,
                    "learner_bytes": len(learner_state),
                    "learner_sha256": hashlib.sha256(learner_state).hexdigest()}
            write_bytes(self.dir / CHECKPOINT, dumps(head, indent=None).encode())
            for f in self.dir.glob("learner_*.state"):
                if f.name != name:
                    f.unlink(missing_ok=True)
            return self.dir / CHECKPOINT


CHECKPOINT = "checkpoint.json"


def read_checkpoint(folder: str | Path) -> tuple[dict, int, bytes] | None:
    """The last checkpoint of a record: (engine state, seq of the last touch on disk when it
    was written, learner bytes); None when the record has none. InputError (the file named)
    when it is unreadable, torn or its learner file is missing or altered."""
    d = Path(folder)
    p = d / CHECKPOINT
    if not p.exists():
        return None
    try:
        head = json.loads(p.read_text())
        name, size, digest = head["learner_file"], head["learner_bytes"], head["learner_sha256"]
        state, after = head["state"], int(head["after_seq"])
    except (OSError, UnicodeDecodeError, json.JSONDecodeError, KeyError, TypeError,
            ValueError) as exc:
        raise InputError(f"checkpoint {str(p)!r} is unreadable ({type(exc).__name__}: "
                         f"{exc})") from None
    if not isinstance(name, str) or "/" in name or not isinstance(state, dict):
        raise InputError(f"checkpoint {str(p)!r} is malformed")
    try:
        data = (d / name).read_bytes()
    except OSError as exc:
        raise InputError(f"checkpoint {str(p)!r}: its learner file {name!r} cannot be read "
                         f"({exc.strerror or exc})") from None
    if len(data) != size or hashlib.sha256(data).hexdigest() != digest:
        raise InputError(f"checkpoint {str(p)!r}: its learner file {name!r} is not the one "
                         f"written ({len(data)} bytes, {size} written; SHA-256 differs)")
    return state, after, data


NUM = (int, float)
# the fields a reader relies on, per file: field -> allowed JSON types (None: null); a field
# that is absent is fine, one of another type refuses the file (InputError, named)
FIELDS: dict[str, dict[str, tuple]] = {
    "touches.jsonl": {"seq": (int,), "image": (str, None), "no_contact": (str, None),
                      "extra": ([str], None),
                      "platform_id": (str, None), "platform_index": (int, None),
                      "accepted": (bool, None), "interrupted": (bool, None),
                      "reason": (str, None), "force_n": (*NUM, None),
                      "depth_m": (*NUM, None), "stamp": (*NUM, None),
                      "requested": (*NUM, None), "pose": ([(*NUM, None)], None),
                      "attempts": (int, None)},
    "rejections.jsonl": {"seq": (int,), "reason": (str, None)},
    "decisions.jsonl": {"round": (int, None), "belief": ([(*NUM, None)],), "touches": ([int],),
                        "next": (str, None), "done": (bool, None), "prediction": (str, None)},
    "events.jsonl": {"event": (str,)},
    "session_events.jsonl": {"event": (str,)},
    "result.json": {"prediction": (str, None), "touches": (int, None),
                    "stop_reason": (str, None), "elapsed_s": (*NUM, None),
                    "correct": (bool, None), "sure": (bool, None),
                    "confidence": (*NUM, None), "error": (str,), "trial_id": (str, None)},
}


def _is(v: Any, t: Any) -> bool:
    if t is None:
        return v is None
    if isinstance(t, list):        # [element types]: a list of them
        return isinstance(v, list) and all(_is(x, t[0]) for x in v)
    if isinstance(t, tuple):
        return any(_is(v, u) for u in t)
    if t in (int, float) and isinstance(v, bool):
        return False               # JSON true is not a number
    return isinstance(v, t)


def _kind(t: Any) -> str:
    if t is None:
        return "null"
    if isinstance(t, list):
        return f"a list of {_kind(t[0])}"
    if isinstance(t, tuple):
        return " or ".join(_kind(u) for u in t)
    return {int: "integer", float: "number", str: "string", bool: "true/false"}.get(
        t, t.__name__)


def check_fields(obj: Any, fields: dict[str, tuple], where: str) -> dict:
    """``obj`` as a JSON object whose ``fields`` have their types; InputError naming
    ``where`` and the field otherwise."""
    if not isinstance(obj, dict):
        raise InputError(f"{where}: expected a JSON object, got {type(obj).__name__}")
    for k, types in fields.items():
        if k in obj and not _is(obj[k], types):
            raise InputError(f"{where}: field {k!r} is {json.dumps(obj[k])[:40]}, expected "
                             f"{_kind(types)}")
    return obj


def _torn_lines(d: Path, name: str) -> set[int]:
    """Numbers of the lines of ``d/name`` ended as torn (``TORN_LINE`` notes)."""
    out: set[int] = set()
    text = ""
    for f in NOTE_FILES:
        try:
            text += (d / f).read_text() + "\n"
        except (OSError, UnicodeDecodeError):
            continue
    for line in text.splitlines():
        try:
            e = json.loads(line)
        except json.JSONDecodeError:
            continue
        if isinstance(e, dict) and e.get("event") == TORN_LINE and e.get("file") == name \
                and isinstance(e.get("line"), int):
            out.add(e["line"])
    return out


def _read_jsonl(path: Path) -> list[dict]:
    """The lines of a JSONL file of a record; InputError naming the file, the line (and the
    field) when a line is not JSON, not an object or a field has another type. The one line
    that may not parse is a crashed writer's torn line: the last one, or one ended before
    the next append (``TORN_LINE``); it is skipped."""
    if not path.exists():
        return []
    try:
        text = path.read_text()
    except (OSError, UnicodeDecodeError) as exc:
        raise InputError(f"{str(path)!r} cannot be read ({exc})") from None
    fields = FIELDS.get(path.name, {})
    lines = text.splitlines()
    torn: set[int] | None = None
    out = []
    for i, line in enumerate(lines, 1):
        try:
            obj = json.loads(line)
        except json.JSONDecodeError as exc:
            if i == len(lines):
                continue                # the torn last line of a crashed writer
            if torn is None:
                torn = _torn_lines(path.parent, path.name)
            if i in torn:
                continue                # one ended before the next line was appended
            raise InputError(f"{str(path)!r}, line {i} of {len(lines)}: not a JSON line "
                             f"({exc.msg} at column {exc.colno}): the file is damaged (only "
                             "the last line may be torn, by a crash)") from None
        out.append(check_fields(obj, fields, f"{str(path)!r}, line {i}"))
    return out


def read_result(folder: str | Path) -> dict | None:
    """``result.json`` of a record, None when absent; a result that does not parse or whose
    fields have other types is an error naming the file and the field (it is written
    atomically, so it is never torn)."""
    p = Path(folder) / "result.json"
    if not p.exists():
        return None
    try:
        res = json.loads(p.read_text())
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise InputError(f"{str(p)!r} is not valid JSON ({exc})") from None
    return check_fields(res, FIELDS["result.json"], repr(str(p)))


def _read_png(path: Path) -> np.ndarray | None:
    bgr = cv2.imread(str(path), cv2.IMREAD_COLOR)
    return None if bgr is None else bgr[:, :, ::-1].copy()


def read_record(folder: str | Path, images: bool = True) -> dict[str, Any]:
    """Load a record folder: touches (with images as arrays: ``array``, ``no_contact_array``,
    ``extra_arrays``: a list, None for a frame that does not read), decisions, events, result
    (or None). ``images=False`` skips the PNGs."""
    d = Path(folder)
    if not d.is_dir():
        raise InputError(f"trial record {str(d)!r} not found")
    touches = _read_jsonl(d / "touches.jsonl")
    rejected = {r["seq"]: r["reason"] for r in _read_jsonl(d / "rejections.jsonl")}
    for t in touches:
        if t.get("seq") in rejected:
            t.update(accepted=False, reason=rejected[t["seq"]])
    if images:
        cache: dict[str, np.ndarray | None] = {}
        for t in touches:
            if t.get("image"):
                t["array"] = _read_png(d / t["image"])
            if t.get("extra"):
                t["extra_arrays"] = [_read_png(d / n) for n in t["extra"]]
            if t.get("no_contact"):
                if t["no_contact"] not in cache:
                    cache[t["no_contact"]] = _read_png(d / t["no_contact"])
                t["no_contact_array"] = cache[t["no_contact"]]
    return {"touches": touches, "decisions": _read_jsonl(d / "decisions.jsonl"),
            "events": _read_jsonl(d / "events.jsonl"), "result": read_result(d)}


# ------------------------------------------------------------------------------ the answer

def press_durations(touches: list[dict]) -> list[float]:
    """Each press's recorded time [s]: its ``press_s`` (the motion node's, approach start to
    lift-off, as ``tactex bench press`` counts) where the touch has one, else request to
    capture (``stamp - requested``); touches with neither (or a request time of 0, never
    taken) are left out."""
    out = []
    for t in touches:
        ps = t.get("press_s")
        if isinstance(ps, (int, float)) and math.isfinite(ps) and ps > 0:
            out.append(float(ps))
        elif t.get("stamp") and t.get("requested"):       # 0.0: a request time never taken
            out.append(float(t["stamp"]) - float(t["requested"]))
    return out


def read_config(folder: str | Path) -> dict:
    """``config.json`` of a record ({} when absent or unreadable); InputError naming the file
    and the field when it is not an object or a section is not one."""
    p = Path(folder) / "config.json"
    try:
        cfg = json.loads(p.read_text())
    except (OSError, UnicodeDecodeError, json.JSONDecodeError):
        return {}
    return check_fields(cfg, {k: (dict, None) for k in ("trial", "session", "explorer",
                                                        "learner", "cli")}, repr(str(p)))


def not_sure(result: dict, stop_confidence: float | None, belief: float | None) -> bool:
    """A trial that ran out of rounds or touches with its answer's belief below the stop
    confidence it was given (no stop confidence: 0 or unknown -> never 'not sure'). A result
    that carries the engine's own ``sure`` (``TrialOutcome.sure``) is read from it."""
    if result.get("sure") is not None:
        return not result["sure"]
    if result.get("stop_reason") in (None, "", "confident") or not stop_confidence:
        return False
    return belief is None or belief < stop_confidence


def result_not_sure(folder: str | Path, result: dict) -> bool:
    """``not_sure`` of the result of record ``folder``: its stop confidence from the
    record's config.json, the answer's belief from the result's ``confidence``."""
    conf = (read_config(folder).get("trial") or {}).get("stop_confidence")
    return not_sure(result, conf, result.get("confidence"))


def stop_text(result: dict, unsure: bool) -> str:
    """How a trial stopped, for a person: "not sure" when it ran out of rounds or touches
    below its stop confidence (``not_sure``), else its stop reason."""
    return "not sure" if unsure else str(result.get("stop_reason") or "")
