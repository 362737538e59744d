"""A study session: the trials of a trial file run one after another in one graph start.

Pure Python (no ROS). ``load_session`` checks a trial file against the scene and the fabric
catalogue before anything moves: every fabric must be a catalogue fabric (number or name),
every trial must place as many fabrics as the scene has platforms, ids must be unique; the
error names the file and the row. Each trial gets what the operator must place where
(``placement``: platform id -> fabric name), the platforms that hold the true match
(``truth``) and its seed (session seed + position in the file).

Session folder ``<session_dir>/``::

    session.json           the session as it was started: its id, the trial file's SHA-256,
                           trials, placements, seeds and the settings it is fixed to
    session_events.jsonl   prompts, confirmations, trials started / finished, timeouts, resumes
    trial_<id>/            one trial record per trial (``record.TrialRecord``)
    session_result.json    written once every trial has its result (atomic)
    report.html            the session report (``tactex_ros.trial.report``)

``progress`` tells from the folder which trials are done, which one was interrupted (its record
exists without a result: it is resumed at the touch where it stopped) and which are pending.
"""

from __future__ import annotations

import hashlib
import json
import os
import re
import uuid
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

from ..core.errors import InputError
from .record import read_result
from .trialfile import find_trial_file, load_trials

SESSION_FILE = "session.json"
EVENTS_FILE = "session_events.jsonl"
RESULT_FILE = "session_result.json"
REPORT_FILE = "report.html"


def record_name(trial_id: str) -> str:
    """The folder name of a session trial's record: ``trial_<id>`` (unsafe characters -> _)."""
    return "trial_" + re.sub(r"[^A-Za-z0-9_.-]", "_", str(trial_id))


@dataclass
class SessionTrial:
    """One trial of a session: where each fabric goes and which platforms match."""

    id: str
    position: int                   # 0-based order in the trial file
    seed: int                       # the explorer's seed for this trial
    placement: dict[str, str]       # platform id -> fabric name (scene order, reference first)
    truth: list[str]                # comparison platform ids that hold the reference's fabric

    @property
    def record_name(self) -> str:
        """The trial record's folder name inside the session folder."""
        return record_name(self.id)

    def instructions(self) -> list[str]:
        """What the operator places where, one line per platform."""
        return [f"platform {pid}: {fab}" for pid, fab in self.placement.items()]


@dataclass
class Session:
    name: str
    path: str
    trials: list[SessionTrial] = field(default_factory=list)
    sha256: str = ""                # of the trial file's bytes

    def to_dict(self) -> dict[str, Any]:
        return {"name": self.name, "path": self.path, "trial_file_sha256": self.sha256,
                "trials": [asdict(t) for t in self.trials]}


def file_sha256(path: str | Path) -> str:
    """SHA-256 (hex) of a file's bytes."""
    return hashlib.sha256(Path(path).read_bytes()).hexdigest()


def check_record_names(ids: list[str], where: str) -> None:
    """Refuse trial ids whose record folders (``record_name``) are one and the same (``a b``
    and ``a_b``; ``é`` and ``ü``): the second trial would find the first one's result."""
    seen: dict[str, str] = {}
    for tid in ids:
        name = record_name(tid)
        if name in seen:
            raise InputError(f"{where}: trial ids {seen[name]!r} and {tid!r} both map to the "
                             f"record folder {name!r} (characters other than A-Z a-z 0-9 _ . - "
                             "become _): give them ids that differ in those characters")
        seen[name] = tid


def catalogue_names(path: str | Path | None = None) -> list[str]:
    """Fabric names of the catalogue (``config/fabrics.yaml``) in number order (1-based)."""
    from ..core.paths import config_dir, read_yaml
    p = Path(path) if path else config_dir() / "fabrics.yaml"
    doc = read_yaml(p, "fabric catalogue")
    try:
        return [str(e["name"]) for e in doc["fabrics"]]
    except (TypeError, KeyError) as exc:
        raise InputError(f"fabric catalogue {p}: expected 'fabrics' with names ({exc})") \
            from None


def _fabric(item: Any, names: list[str], where: str) -> str:
    if isinstance(item, bool) or not isinstance(item, (int, str)):
        raise InputError(f"{where}: {item!r} is not a fabric number or name")
    if isinstance(item, int):
        if not 1 <= item <= len(names):
            raise InputError(f"{where}: unknown fabric {item} (the catalogue numbers "
                              f"1..{len(names)})")
        return names[item - 1]
    if item not in names:
        raise InputError(f"{where}: unknown fabric {item!r} (not in the catalogue "
                          "config/fabrics.yaml)")
    return item


def load_session(spec: str | Path, platform_ids: list[str], seed: int = 0,
                 catalogue: str | Path | None = None) -> Session:
    """Read and check a trial file for a scene whose platforms are ``platform_ids`` (reference
    first). InputError names the file and the row of the first problem."""
    path = find_trial_file(str(spec))
    doc = load_trials(path)           # unique ids, reference among the comparisons
    check_record_names([t["id"] for t in doc["trials"]], f"trial file {path}")
    names = catalogue_names(catalogue)
    out = Session(name=doc["name"], path=str(Path(path).resolve()), sha256=file_sha256(path))
    for i, t in enumerate(doc["trials"]):
        where = f"trial file {path}, entry {i + 1} (id {t['id']})"
        fabrics = [t["reference"]] + list(t["comparisons"])
        if len(fabrics) != len(platform_ids):
            raise InputError(f"{where}: places {len(fabrics)} fabrics (reference + "
                              f"{len(fabrics) - 1} comparisons) but the scene has "
                              f"{len(platform_ids)} platforms {platform_ids}")
        fabs = [_fabric(f, names, f"{where}, {'reference' if k == 0 else f'comparison {k}'}")
                for k, f in enumerate(fabrics)]
        placement = dict(zip(platform_ids, fabs, strict=True))
        truth = [pid for pid, f in zip(platform_ids[1:], fabs[1:], strict=True) if f == fabs[0]]
        out.trials.append(SessionTrial(id=t["id"], position=i, seed=seed + i,
                                       placement=placement, truth=truth))
    return out


def select_trials(session: Session, text: str) -> list[str] | None:
    """The trial ids ``text`` asks for (``ID[,ID...]``, the explorer's ``trials``; spaces
    around an id are ignored), in the session's order; None for '' (every trial). InputError
    names an unknown id and the session's ids."""
    if not str(text or "").strip():
        return None
    asked = [t.strip() for t in str(text).split(",")]
    ids = [t.id for t in session.trials]
    if not all(asked):
        raise InputError(f"trials {text!r}: an empty id (a ',' with nothing on one side); "
                         f"give ID[,ID...] of session {session.name} (its ids: "
                         f"{', '.join(ids)}), or '' for every trial")
    for t in asked:
        if t not in ids:
            raise InputError(f"trials {text!r}: {t!r} is not a trial of session "
                             f"{session.name} (its ids: {', '.join(ids)})")
    return [i for i in ids if i in asked]


def placement_text(placement: dict[str, str]) -> str:
    """``platform=fabric,...``: the mock camera's ``placement`` parameter."""
    return ",".join(f"{k}={v}" for k, v in placement.items())


def parse_placement(text: str, platform_ids: list[str]) -> dict[str, str]:
    """The inverse of ``placement_text``; every platform id must be one of ``platform_ids``."""
    out: dict[str, str] = {}
    for part in filter(None, (p.strip() for p in text.split(","))):
        pid, sep, fab = part.partition("=")
        if not sep or not pid or not fab:
            raise InputError(f"placement {text!r}: expected platform=fabric,... ({part!r})")
        if pid not in platform_ids:
            raise InputError(f"placement {text!r}: unknown platform {pid!r} (the scene has "
                              f"{platform_ids})")
        out[pid] = fab
    return out


def placed_scene(scene_file: str | Path, placement: dict[str, str]) -> str:
    """The scene YAML text with each platform's ``sim_fabric`` set to the placed fabric."""
    import yaml
    doc = yaml.safe_load(Path(scene_file).read_text())
    for p in doc.get("platforms", []):
        if str(p.get("id")) in placement:
            p["sim_fabric"] = placement[str(p["id"])]
    return yaml.safe_dump(doc, sort_keys=False)


# ------------------------------------------------------------------------------ the folder

def events(session_dir: str | Path) -> list[dict]:
    """The session's events (a torn last line is skipped)."""
    from .record import _read_jsonl
    return _read_jsonl(Path(session_dir) / EVENTS_FILE)


def add_event(session_dir: str | Path, event: dict[str, Any]) -> None:
    """Append one line to ``session_events.jsonl`` (fsync'ed)."""
    from .record import append_line
    d = Path(session_dir)
    d.mkdir(parents=True, exist_ok=True)
    append_line(d / EVENTS_FILE, (json.dumps(event) + "\n").encode(), d / EVENTS_FILE)


def read_session_file(session_dir: str | Path) -> dict[str, Any] | None:
    """``session.json`` of a folder checked to be a tactex session's (None when absent);
    InputError naming the path when it is torn, not JSON or not a session's (no session id,
    trial file hash, trials or settings)."""
    p = Path(session_dir) / SESSION_FILE
    if not p.exists():
        return None
    try:
        was = json.loads(p.read_text())
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise InputError(f"session {str(p)!r} is unreadable or torn ({exc}): it is not a "
                         "session this folder can continue; choose another session folder") \
            from None
    keys = {"session_id": str, "trial_file_sha256": str, "trials": list, "settings": dict}
    bad = [k for k, t in keys.items() if not isinstance(was, dict)
           or not isinstance(was.get(k), t)]
    if bad:
        raise InputError(f"session {str(p)!r} is not a tactex session's (missing or wrong "
                         f"type: {', '.join(bad)}); choose another session folder")
    from .record import check_fields
    for i, t in enumerate(was["trials"]):
        where = f"session {str(p)!r}, trial {i + 1}"
        check_fields(t, TRIAL_FIELDS, where)
        missing = [k for k in TRIAL_FIELDS if k not in t]
        if missing:
            raise InputError(f"{where}: missing {', '.join(missing)}")
        if not all(isinstance(v, str) for v in t["placement"].values()):
            raise InputError(f"{where}: field 'placement' must map platform ids to fabric "
                             "names (strings)")
    return was


TRIAL_FIELDS: dict[str, tuple] = {"id": (str,), "position": (int,), "seed": (int,),
                                  "placement": (dict,), "truth": ([str],)}


def check_session_dir(session_dir: str | Path, trial_file: str | Path | None = None) -> bool:
    """Before a session starts (``graph run --session``) or its node opens the folder:
    ``session_dir`` is a folder that can be written, and either holds nothing of another
    session or is this trial file's session (its ``session.json`` parses and names the same
    trial file bytes). True when a session is there to continue. InputError (exit status 2)
    naming the path and the reason otherwise; nothing is written."""
    from ..core.outputs import check_dir
    d = Path(session_dir)
    check_dir(d, "session_dir")
    if d.is_dir() and not os.access(d, os.W_OK | os.X_OK):
        raise InputError(f"session_dir {str(d)!r}: not writable")
    was = read_session_file(d)
    if was is None:
        if d.is_dir():
            left = sorted(f.name for f in d.iterdir() if f.name == RESULT_FILE or
                          f.name == EVENTS_FILE or
                          (f.name.startswith("trial_") and f.is_dir()))
            if left:
                raise InputError(f"session_dir {str(d)!r} holds session files without "
                                 f"{SESSION_FILE} ({', '.join(left[:3])}): it is not a "
                                 "session this can continue; choose another session folder")
        return False
    if trial_file is not None:
        sha = file_sha256(find_trial_file(str(trial_file)))
        if was["trial_file_sha256"] != sha:
            raise InputError(f"session folder {str(d)!r} holds session {was['session_id']} "
                             f"of trial file {was.get('path')!r} (SHA-256 "
                             f"{was['trial_file_sha256'][:12]}), not of {str(trial_file)!r} "
                             f"({sha[:12]}): choose another session folder")
    return True


def settings_problem(was: dict[str, Any], now: dict[str, Any]) -> str | None:
    """The first setting a session was started with that a continuation changes, named with
    both values; None when they agree."""
    for k in sorted(set(was) | set(now)):
        if was.get(k) != now.get(k):
            return (f"setting {k!r} was {was.get(k)!r} when the session started and is "
                    f"{now.get(k)!r} now")
    return None


def open_session(session_dir: str | Path, session: Session, settings: dict[str, Any]) -> bool:
    """Create the session folder (``session.json`` with a new session id, the trial file's
    hash, the trials and ``settings``), or check that an existing one is this session (same
    trial file, trials, placements, seeds and settings: a session's settings are fixed in its
    folder); True when an existing session is continued. InputError names the path and, for
    a changed setting, both values."""
    from ..core.outputs import write_bytes
    d = Path(session_dir)
    now = session.to_dict()
    if check_session_dir(d, session.path):
        was = read_session_file(d)
        if was["trials"] != now["trials"]:
            raise InputError(f"session folder {str(d)!r} holds another session (its trials, "
                              "placements or seeds differ from this trial file's): choose "
                              "another session folder")
        problem = settings_problem(was["settings"], settings)
        if problem:
            raise InputError(f"session folder {str(d)!r}: {problem}; a session continues "
                             "with the settings it started with (or start a new session "
                             "folder)")
        return True
    write_bytes(d / SESSION_FILE, json.dumps(dict(now, session_id=uuid.uuid4().hex,
                                                  settings=settings), indent=2).encode())
    return False


def load_started(session_dir: str | Path) -> dict[str, Any]:
    """``session.json`` of a session folder."""
    was = read_session_file(session_dir)
    if was is None:
        raise InputError(f"{str(session_dir)!r} is not a session folder (no {SESSION_FILE})")
    return was


def trial_state(session_dir: str | Path, trial: SessionTrial | dict) -> str:
    """'done' (result without error), 'started' (record without a result, or a failed one:
    resumable) or 'pending'."""
    d = Path(session_dir) / record_name(trial.id if isinstance(trial, SessionTrial)
                                        else trial["id"])
    if not (d / "config.json").is_file():
        return "pending"
    res = read_result(d)
    return "done" if res is not None and "error" not in res else "started"


def finish_session(session_dir: str | Path, result: dict[str, Any]) -> Path:
    """Write ``session_result.json`` atomically."""
    from .record import _fsync_write
    d = Path(session_dir)
    tmp = d / (RESULT_FILE + ".tmp")
    _fsync_write(tmp, json.dumps(result, indent=2).encode(), False)
    os.replace(tmp, d / RESULT_FILE)
    return d / RESULT_FILE


def summary(session_dir: str | Path) -> dict[str, Any]:
    """Per-trial outcome of a session folder (done trials only) and its accuracy. A trial
    that ended not sure (``report.not_sure``: out of rounds or touches below its stop
    confidence) or was skipped by the operator (``skipped``) is counted apart (``not_sure``; its row's ``correct`` None,
    ``guess_correct`` whether its best guess was right) and never as correct: accuracy is
    the sure, right answers over the trials done."""
    from .record import result_not_sure
    d = Path(session_dir)
    started = load_started(d)
    rows = []
    for t in started["trials"]:
        name = record_name(t["id"])
        res = read_result(d / name) if (d / name).is_dir() else None
        if res is None or "error" in res:
            rows.append({"id": t["id"], "record": name, "done": False})
            continue
        if res.get("skipped"):       # done (the session goes on) without an answer
            rows.append({"id": t["id"], "record": name, "done": True, "skipped": True,
                         "prediction": None, "truth": t["truth"], "correct": None,
                         "not_sure": False, "guess_correct": None,
                         "touches": res.get("touches"), "stop_reason": "skipped",
                         "seed": t["seed"], "elapsed_s": None, "placement": t["placement"]})
            continue
        pred = res.get("prediction")
        unsure = result_not_sure(d / name, res)
        rows.append({"id": t["id"], "record": name, "done": True, "prediction": pred,
                     "truth": t["truth"], "correct": None if unsure else pred in t["truth"],
                     "not_sure": unsure, "guess_correct": pred in t["truth"],
                     "touches": res.get("touches"), "stop_reason": res.get("stop_reason"),
                     "seed": t["seed"], "elapsed_s": res.get("elapsed_s"),
                     "placement": t["placement"]})
    done = [r for r in rows if r["done"]]
    answered = [r for r in done if not r.get("skipped")]
    acc = sum(r["correct"] is True for r in answered) / len(answered) if answered else None
    return {"name": started["name"], "trials": rows, "done": len(done), "total": len(rows),
            "accuracy": acc, "not_sure": sum(r["not_sure"] for r in done),
            "skipped": len(done) - len(answered)}


def accuracy_text(summ: dict[str, Any]) -> str:
    """A summary's accuracy as the terminal shows it: ``0.667`` (``n/a`` when no trial was
    answered), with its not-sure and skipped counts when there are any."""
    acc = summ.get("accuracy")
    text = "n/a" if acc is None else f"{acc:.3f}"
    extra = [f"{summ[k]} {k.replace('_', ' ')}" for k in ("not_sure", "skipped")
             if summ.get(k)]
    return text + (f" ({', '.join(extra)})" if extra else "")
