"""The rows of an export: one per touch, read from what tactex leaves on disk.

Inputs (``collect``): a trial record (``trial/record.py``: ``touches.jsonl`` + PNGs), a study
session (``session.json`` + ``trial_*/`` records), a folder holding records or sessions, or a
``replay:DIR`` library of recorded presses (``sources/replay.py``: one row per press file, its
touch encoded as PNG). A row (``FIELDS``) keeps the PNG bytes exactly as the record holds
them, so an image loaded back compares byte for byte with the file.

Labels: the material of a platform comes from the record's ``scene.yaml`` (``sim_fabric`` or
``replay_class``, a session's placement is written there) or, for a library, the press's class
folder; the decision that followed a touch is the record's decision made right after it (a
trial decides once every platform has its baseline touch, then after every accepted touch);
the trial's outcome is its ``result.json`` (prediction, stop reason) and, where the materials
are known, whether the predicted platform holds the reference's material.
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any
from collections.abc import Iterator

from ..core.errors import InputError
from ..trial.record import read_record

#: Columns of a row, in order, with their meaning (units); ``image``/``no_contact`` are PNG
#: bytes (None where there is none), ``extra`` a list of PNG bytes.
FIELDS: dict[str, str] = {
    "trial_id": "the trial record's folder name ('' for a library press)",
    "session": "the session folder's name ('' outside a session)",
    "seq": "touch number in the trial (1-based; a library's press number)",
    "platform_id": "platform touched (reference, c1..cN; '' for a library press)",
    "platform_index": "0 = reference, 1..N = comparisons (-1 for a library press)",
    "material": "material on that platform where the scene knows it (else '')",
    "image": "contact image, lossless PNG (RGB)",
    "no_contact": "the sensor's no-contact frame that came with the touch, lossless PNG",
    "extra": "further in-contact frames of the same press (the capture's burst; a library "
             "press's extra frames), lossless PNG each, in time order (empty: none)",
    "force_n": "tared normal force at capture [N]",
    "depth_m": "penetration below the platform surface at capture [m]",
    "pose": "end-effector position at capture in the robot base frame [m] (x, y, z)",
    "press_time": "capture time [s since the epoch]",
    "accepted": "the touch was used (False: refused, 'reason' says why)",
    "reason": "why a touch was not used",
    "next_platform": "the decision that followed this touch: platform chosen next ('' = stop)",
    "belief": "that decision's belief over the comparisons (sums to 1)",
    "belief_platforms": "the comparisons the belief is over, in order",
    "prediction": "the trial's predicted platform",
    "prediction_material": "material on the predicted platform (where known)",
    "reference_material": "material on the reference (where known)",
    "correct": "the prediction holds the reference's material (None when unknown)",
    "stop_reason": "why the trial ended (confident, rounds, max_touches; '' unknown)",
    "source_file": "the library's press file (relative to the library), '' for records",
}


@dataclass
class Trial:
    """One trial's part of an export: its rows and what the dataset card says of it."""

    name: str
    rows: list[dict[str, Any]]
    config: dict[str, Any] = field(default_factory=dict)
    result: dict[str, Any] | None = None


def is_record(d: Path) -> bool:
    return (d / "touches.jsonl").is_file() or (d / "config.json").is_file()


def is_session(d: Path) -> bool:
    from ..trial.session import SESSION_FILE
    return (d / SESSION_FILE).is_file()


def _materials(d: Path) -> dict[str, str]:
    """platform id -> material from the record's scene.yaml ({} when it names none)."""
    p = d / "scene.yaml"
    if not p.is_file():
        return {}
    from ..robot.scene import load_scene
    try:
        scene = load_scene(p)
    except InputError:
        return {}
    return {pl.id: pl.sim_fabric or pl.replay_class for pl in scene.ordered
            if pl.sim_fabric or pl.replay_class}


def _json(p: Path) -> dict:
    try:
        return json.loads(p.read_text()) if p.is_file() else {}
    except (OSError, json.JSONDecodeError) as exc:
        raise InputError(f"{str(p)!r} is not readable JSON ({exc})") from None


def record_rows(d: Path, session: str = "") -> Trial:
    """The rows of one trial record folder ``d`` (every touch line, refused ones too). A
    damaged line or a field of another type than the record's (``record.FIELDS``) is an
    InputError naming the file, the line and the field (``read_record``)."""
    rec = read_record(d, images=False)
    mats = _materials(d)
    res = rec["result"] or {}
    decisions = rec["decisions"]
    comparisons = len(decisions[0].get("belief") or []) if decisions else 0
    if not comparisons:
        comparisons = max(len(mats) - 1, 0)
    pred = res.get("prediction") or ""
    ref_mat = mats.get("reference", "")
    pred_mat = mats.get(pred, "") if pred else ""
    correct = (pred_mat == ref_mat) if (pred_mat and ref_mat) else None
    belief_ids = sorted((p for p in mats if p != "reference"), key=_platform_order)
    rows, accepted = [], 0
    for t in rec["touches"]:
        pid = str(t.get("platform_id") or "")
        used = bool(t.get("accepted", False)) and bool(t.get("image"))
        decision: dict = {}
        if used:
            accepted += 1
            k = accepted - (comparisons + 1)
            if comparisons and 0 <= k < len(decisions):
                decision = decisions[k]
        pose = t.get("pose")
        rows.append({
            "trial_id": d.name, "session": session, "seq": int(t.get("seq", 0)),
            "platform_id": pid, "platform_index": int(t.get("platform_index", -1)),
            "material": mats.get(pid, ""),
            "image": _bytes(d, t.get("image")), "no_contact": _bytes(d, t.get("no_contact")),
            "extra": [_bytes(d, n) for n in t.get("extra") or []],
            "force_n": _num(t.get("force_n")), "depth_m": _num(t.get("depth_m")),
            "pose": [_num(v) for v in pose] if isinstance(pose, list) else None,
            "press_time": _num(t.get("stamp")), "accepted": used,
            "reason": str(t.get("reason") or ""),
            "next_platform": (decision.get("next") or "") if decision else None,
            "belief": ([_num(b) for b in decision["belief"]] if decision.get("belief")
                       else None),
            "belief_platforms": (belief_ids if decision.get("belief") and
                                 len(belief_ids) == len(decision["belief"]) else None),
            "prediction": pred, "prediction_material": pred_mat,
            "reference_material": ref_mat, "correct": correct,
            "stop_reason": str(res.get("stop_reason") or ""), "source_file": ""})
    return Trial(d.name, rows, _json(d / "config.json"), rec["result"])


def _platform_order(pid: str) -> tuple[int, str]:
    digits = pid.lstrip("c")
    return (int(digits), pid) if digits.isdigit() else (10**9, pid)


def _num(v: Any) -> float | None:
    """A number of the record (its type checked by ``read_record``: a number or null, NaN
    written as null) as a float, None for null."""
    return None if v is None else float(v)


def _bytes(d: Path, name: Any) -> bytes | None:
    if not name:
        return None
    p = d / str(name)
    try:
        return p.read_bytes()
    except OSError as exc:
        raise InputError(f"record {str(d)!r}: image {name!r} named in touches.jsonl cannot be "
                         f"read ({exc.strerror or exc})") from None


def library_rows(spec: str) -> Iterator[Trial]:
    """One ``Trial`` per class of a ``replay:DIR`` library, one row per press file: the
    press's touch (``sources.replay.load_touch``: strongest contact frame, its no-contact frame,
    its extra in-contact frames) encoded as PNG, the class as its material."""
    import cv2

    from ..sources import open_source
    src = open_source(spec)
    for cls in src.classes:
        rows = []
        for i, f in enumerate(src.presses(cls), 1):
            touch = src.touch(f)
            rows.append({k: None for k in FIELDS} | {
                "trial_id": "", "session": "", "seq": i, "platform_id": "",
                "platform_index": -1, "material": cls, "image": _png(touch.frame, cv2),
                "no_contact": None if touch.no_contact is None else _png(touch.no_contact, cv2),
                "extra": [] if touch.extra is None else [_png(f, cv2) for f in touch.extra],
                "accepted": True, "reason": "", "prediction": "", "prediction_material": "",
                "reference_material": "", "stop_reason": "",
                "source_file": str(Path(f).relative_to(src.root))})
        yield Trial(cls, rows)


def _png(rgb, cv2) -> bytes:
    ok, buf = cv2.imencode(".png", rgb[:, :, ::-1].copy())
    if not ok:
        raise InputError("could not encode a press frame as PNG")
    return buf.tobytes()


def collect(source: str) -> tuple[str, list[Trial]]:
    """What ``source`` is ('record', 'session', 'folder', 'library') and its trials."""
    if source.startswith("replay:"):
        return "library", list(library_rows(source))
    d = Path(source)
    if not d.is_dir():
        raise InputError(f"export: {source!r} is neither a folder (a trial record, a session, "
                         "a folder of them) nor replay:DIR")
    if is_session(d):
        return "session", _session(d)
    if is_record(d):
        return "record", [record_rows(d)]
    trials: list[Trial] = []
    for sub in sorted(p for p in d.iterdir() if p.is_dir()):
        if is_session(sub):
            trials += _session(sub)
        elif is_record(sub):
            trials.append(record_rows(sub))
    if not trials:
        raise InputError(f"export: {str(d)!r} holds no trial record (touches.jsonl, "
                         "config.json) and no session (session.json), nor do its subfolders")
    return "folder", trials


def _session(d: Path) -> list[Trial]:
    return [record_rows(sub, session=d.name) for sub in sorted(d.iterdir())
            if sub.is_dir() and is_record(sub)]
