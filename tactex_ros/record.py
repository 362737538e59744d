"""Trial record on disk: every touch is written (and fsync'ed) the moment it arrives.

Layout of ``<root>/<trial_id>/``::

    touches.jsonl        one JSON line per touch, in arrival order (also rejected ones)
    rejections.jsonl     touches refused after they were written (the core's guard)
    touch_0001_c1.png    the touch image (lossless RGB), name = sequence number + platform id
    decisions.jsonl      one JSON line per decision (the exploration state)
    result.json          the trial's result (written last, atomically)
    scene.yaml, config.json   what the trial ran with

Line-per-event files with ``fsync`` after every write lose nothing already recorded when the
process dies; a reader (``read_record``) ignores a torn last line. PNG+JSONL instead of a bag:
an MCAP/rosbag file needs its footer written on close, which a crash never does.
"""

from __future__ import annotations

import json
import os
import shutil
from pathlib import Path
from typing import Any

import cv2
import numpy as np

from .core.errors import TactexError


def _fsync_write(path: Path, data: bytes, append: bool) -> None:
    fd = os.open(path, os.O_WRONLY | os.O_CREAT | (os.O_APPEND if append else os.O_TRUNC),
                 0o644)
    try:
        os.write(fd, data)
        os.fsync(fd)
    finally:
        os.close(fd)


class TrialRecord:
    """Writer for one trial's record folder."""

    def __init__(self, root: str | Path, trial_id: str) -> None:
        if not trial_id or "/" in trial_id:
            raise TactexError(f"trial_id {trial_id!r}: a non-empty name without '/'")
        self.dir = Path(root) / trial_id
        if (self.dir / "touches.jsonl").exists():
            raise TactexError(f"trial record {str(self.dir)!r} already exists: choose another "
                              "trial_id (records are never overwritten)")
        self.dir.mkdir(parents=True, exist_ok=True)
        self.n_touches = 0

    def save_inputs(self, scene_file: str | Path | None, config: dict) -> None:
        if scene_file:
            shutil.copyfile(scene_file, self.dir / "scene.yaml")
        _fsync_write(self.dir / "config.json", json.dumps(config, indent=2).encode(), False)

    def add_touch(self, image: np.ndarray | None, meta: dict[str, Any]) -> Path | None:
        """Write the image (RGB uint8, any size; None = no usable image) and its metadata line.

        Returns the image path. Called before the touch is used for anything."""
        self.n_touches += 1
        img_path = None
        if image is not None:
            img_path = self.dir / f"touch_{self.n_touches:04d}_{meta.get('platform_id', 'x')}.png"
            ok, buf = cv2.imencode(".png", np.ascontiguousarray(image[:, :, ::-1]))
            if not ok:
                raise TactexError(f"could not encode touch {self.n_touches} as PNG")
            _fsync_write(img_path, buf.tobytes(), False)
        line = dict(meta, seq=self.n_touches, image=img_path.name if img_path else None)
        _fsync_write(self.dir / "touches.jsonl", (json.dumps(line) + "\n").encode(), True)
        return img_path

    def reject_touch(self, seq: int, reason: str) -> None:
        """Mark touch ``seq`` (already on disk) as not used, e.g. refused by the core's guard."""
        _fsync_write(self.dir / "rejections.jsonl",
                     (json.dumps({"seq": seq, "reason": reason}) + "\n").encode(), True)

    def add_decision(self, state: dict[str, Any]) -> None:
        _fsync_write(self.dir / "decisions.jsonl", (json.dumps(state) + "\n").encode(), True)

    def finish(self, result: dict[str, Any]) -> Path:
        tmp = self.dir / "result.json.tmp"
        _fsync_write(tmp, json.dumps(result, indent=2).encode(), False)
        os.replace(tmp, self.dir / "result.json")
        return self.dir / "result.json"


def _read_jsonl(path: Path) -> list[dict]:
    if not path.exists():
        return []
    out = []
    for line in path.read_text().splitlines():
        try:
            out.append(json.loads(line))
        except json.JSONDecodeError:
            break  # torn last line of a crashed writer
    return out


def read_record(folder: str | Path) -> dict[str, Any]:
    """Load a record folder: touches (with images as arrays), decisions, result (or None)."""
    d = Path(folder)
    if not d.is_dir():
        raise TactexError(f"trial record {str(d)!r} not found")
    touches = _read_jsonl(d / "touches.jsonl")
    rejected = {r["seq"]: r["reason"] for r in _read_jsonl(d / "rejections.jsonl")}
    for t in touches:
        if t.get("seq") in rejected:
            t.update(accepted=False, reason=rejected[t["seq"]])
    for t in touches:
        if t.get("image"):
            bgr = cv2.imread(str(d / t["image"]), cv2.IMREAD_COLOR)
            t["array"] = None if bgr is None else bgr[:, :, ::-1].copy()
    res = d / "result.json"
    return {"touches": touches, "decisions": _read_jsonl(d / "decisions.jsonl"),
            "result": json.loads(res.read_text()) if res.exists() else None}
