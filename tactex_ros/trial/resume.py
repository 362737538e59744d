"""Resume an interrupted trial from its record (no ROS here).

The trial engine is deterministic given the outcome of every touch: the same touches, failures
and refusals in the same order lead to the same ``decide()`` calls, the same learner state and
the same random draws. So a trial is resumed by running a fresh engine (same settings, same
seed) with ``run(touch_fn)`` where ``touch_fn`` is a ``Replay``: it hands back the touches on
disk in their recorded order (a recorded failure is raised again as ``TouchFailed``, a touch
the contact guard refused is handed back and refused again), and only once they are used up
does it call the live touch function. The engine re-decides at exactly the recorded points,
and the trial goes on to the same number of rounds or stop rule.

A press that was cut off by the fault itself (the record marks it ``interrupted``) is not
replayed: the resumed trial makes that touch again, as the uninterrupted one did. If the
engine asks for another platform than the record holds next, the record was made with other
settings or code, and ``Replay`` raises a ``InputError`` naming the touch.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from collections.abc import Callable

import numpy as np

from ..core.engine import TouchFailed, TrialEngine, TrialSpec
from ..core.errors import InputError
from ..core.touch import Touch
from .record import read_checkpoint, read_record


@dataclass
class RecordedTouch:
    """One line of ``touches.jsonl`` as the engine saw it."""

    seq: int
    platform_index: int            # 0 = reference, 1..C comparisons
    platform_id: str
    touch: Touch | None            # None: the touch failed (``reason``)
    reason: str = ""
    rejected: bool = False         # written, then refused by the core's guard


def recorded_touches(record: dict) -> list[RecordedTouch]:
    """The touches of a loaded record (``read_record``) in arrival order, interrupted presses
    left out, each with its further in-contact frames (``Touch.extra``) where the record keeps
    them (a record made before they were kept: the strongest frame alone). A touch whose image
    or extra frame is missing or unreadable is refused (nothing is guessed)."""
    out = []
    for t in record["touches"]:
        if t.get("interrupted"):
            continue
        seq = int(t.get("seq", 0))
        if "platform_index" not in t:
            raise InputError(f"resume: touch {seq} of the record has no platform_index")
        touch = None
        if t.get("image"):
            arr = t.get("array")
            if arr is None:
                raise InputError(f"resume: image {t['image']!r} of touch {seq} is missing or "
                                 "unreadable")
            extra = t.get("extra_arrays")
            if extra is not None and any(a is None for a in extra):
                bad = [n for n, a in zip(t["extra"], extra, strict=True) if a is None]
                raise InputError(f"resume: extra frame(s) {bad} of touch {seq} are missing or "
                                 "unreadable")
            touch = Touch(frame=arr, no_contact=t.get("no_contact_array"),
                          extra=np.stack(extra) if extra else None)
        elif t.get("accepted", False):
            raise InputError(f"resume: touch {seq} is marked accepted but has no image")
        out.append(RecordedTouch(seq=seq, platform_index=int(t["platform_index"]),
                                 platform_id=str(t.get("platform_id", "")), touch=touch,
                                 reason=str(t.get("reason") or "touch failed"),
                                 rejected=touch is not None and not t.get("accepted", True)))
    return out


class Replay:
    """A ``touch_fn`` for ``TrialEngine.run``: the recorded touches in order, then ``live``.

    ``current`` is the recorded touch handed back last (None once live), so a caller can tell
    a replayed touch (already on disk) from a new one."""

    def __init__(self, recorded: list[RecordedTouch],
                 live: Callable[[int], Touch | np.ndarray], platform_ids: list[str]) -> None:
        self.recorded = list(recorded)
        self.live = live
        self.platform_ids = platform_ids
        self.pos = 0
        self.current: RecordedTouch | None = None

    @property
    def replaying(self) -> bool:
        """True while recorded touches remain."""
        return self.pos < len(self.recorded)

    def __call__(self, platform: int) -> Touch | np.ndarray:
        if not self.replaying:
            self.current = None
            return self.live(platform)
        r = self.recorded[self.pos]
        self.pos += 1
        self.current = r
        if r.platform_index != platform:
            want = self.platform_ids[platform] if 0 <= platform < len(self.platform_ids) \
                else str(platform)
            raise InputError(f"resume: the record diverges at touch {r.seq}: it holds a touch "
                             f"of {r.platform_id or r.platform_index}, the trial asks for "
                             f"{want} (other settings or code than the interrupted run)")
        if r.touch is None:
            raise TouchFailed(r.reason, retry=False)
        return r.touch


def restore_engine(spec: TrialSpec, folder: str | Path, recorded: list[RecordedTouch],
                   guard_reference: bool = True) -> tuple[TrialEngine, int, str]:
    """The engine of a resumed trial: restored from the record's last checkpoint (the
    learner's state after its last round, ``TrialRecord.write_checkpoint``) when there is one
    that fits, else a fresh one that re-trains while the recorded touches are replayed.
    Returns (engine, number of the last recorded touch the checkpoint covers, 0 for none; a
    line saying which way it went). A checkpoint that is unreadable, altered or does not fit
    the record is not used (the line says why): the touches on disk are the ground truth.
    ``guard_reference``: the contact guard gets the first recorded no-contact frame back
    (``TrialRun``'s)."""
    how = f"re-training on the {len(recorded)} recorded touches"
    try:
        got = read_checkpoint(folder)
    except InputError as exc:
        return spec.engine(), 0, f"{exc}; not used, {how}"
    if got is None:
        return spec.engine(), 0, f"no learner checkpoint in the record, {how}"
    state, after, blob = got
    eng = spec.engine()
    stored = [(r.platform_index, r.touch) for r in recorded
              if r.seq <= after and r.touch is not None and not r.rejected]
    try:
        if recorded and after > max(r.seq for r in recorded) or after < 1:
            raise InputError(f"it covers touches up to {after}, the record holds "
                             f"{max((r.seq for r in recorded), default=0)}")
        eng.restore(state, stored, blob)
    except (InputError, KeyError, TypeError, ValueError, IndexError, AttributeError) as exc:
        # a damaged state (wrong types, missing keys) can fail after the checks in restore():
        # the half-restored engine is dropped, the touches on disk are re-trained on
        return spec.engine(), 0, f"checkpoint does not fit the record ({exc}); not used, {how}"
    for r in recorded if guard_reference else ():    # the guard's no-contact frame, as it was
        if r.seq <= after and r.touch is not None and r.touch.no_contact is not None:
            if eng.guard is not None and not eng.guard.has_reference:
                eng.guard.set_reference(r.touch.no_contact)
            break
    return eng, after, (f"learner restored from the checkpoint of round {len(eng.records)} "
                        f"(touches 1..{after}); "
                        f"{sum(r.seq > after for r in recorded)} recorded touches replayed")


def load_replay(folder: str | Path, live: Callable[[int], Touch | np.ndarray],
                platform_ids: list[str]) -> tuple[Replay, dict]:
    """A ``Replay`` of the record in ``folder`` and the loaded record."""
    rec = read_record(folder)
    return Replay(recorded_touches(rec), live, platform_ids), rec


# settings that may change between the interrupted run and its resume (where, how long, how fast)
_FREE = {"explorer": {"resume", "record_dir", "trial_id", "exit_when_done", "nice",
                      "press_timeout_s", "server_timeout_s", "press_silence_s", "press_action",
                      "pause_timeout_s", "state_topic", "marker_topic", "touch_image_topic",
                      "goal_answer_s", "goal_renew_s", "min_free_mb", "run_id",
                      "scene_file", "session_file", "session_dir", "trials", "auto_confirm",
                      "confirm_timeout_s", "prompt_topic", "placement_service", "diag_period_s"},
         "learner": {"threads"}, "trial": set(),
         # ``tactex trial`` (cli/main.py): its options; where the record goes and how much
         # the console shows may change
         "cli": {"resume", "record_dir", "trial_id", "json", "quiet"}}


def check_settings(folder: str | Path, now: dict[str, dict]) -> None:
    """Refuse a resume whose settings differ from the record's ``config.json`` where they
    change the trial (seed, strategy, model, rounds, stop rule, every learner setting); the
    error names the first field that differs. ``now``: {section: settings dict}. A record
    written before the learners had their own settings holds every learner's fields; those the
    learner now lacks are not compared (``learner.model`` decides which apply)."""
    import json
    p = Path(folder) / "config.json"
    try:
        was = json.loads(p.read_text())
    except (OSError, json.JSONDecodeError) as exc:
        raise InputError(f"resume: cannot read {str(p)!r} ({exc})") from None
    for section, free in _FREE.items():
        a = json.loads(json.dumps(was.get(section, {}), default=str))
        b = json.loads(json.dumps(now.get(section, {}), default=str))
        for k in sorted(set(b) if section == "learner" else set(a) | set(b)):
            if k not in free and a.get(k) != b.get(k):
                raise InputError(f"resume: {section}.{k} is {b.get(k)!r} now but "
                                 f"{a.get(k)!r} in the record {str(folder)!r}; a resumed "
                                 "trial runs with the settings it started with")


def record_settings(folder: str | Path) -> dict:
    """The settings a trial record was started with, flat (``config``, ``seed``, ...,
    ``learner.*``, ``trial.*``; from its ``config.json``: the explorer's section, or
    ``tactex trial``'s ``cli``), those a resume may change (``_FREE``) left out. InputError naming the folder when it has no readable config.json."""
    import json
    from ..core.schema import flatten
    p = Path(folder) / "config.json"
    try:
        rec = json.loads(p.read_text())
        entrance = "explorer" if "explorer" in rec or "cli" not in rec else "cli"
        out = {k: v for k, v in rec[entrance].items() if k not in _FREE[entrance]}
        out.update(flatten({"learner": rec["learner"], "trial": rec["trial"]}))
    except (OSError, ValueError, KeyError, TypeError, AttributeError) as exc:
        raise InputError(f"resume {str(folder)!r}: not a trial record with a config.json "
                         f"({type(exc).__name__}: {exc})") from None
    return {k: v for k, v in out.items() if k.partition(".")[2] not in _FREE["learner"]
            or not k.startswith("learner.")}


def settings_from_record(folder: str | Path, now: dict, unset: list[dict] = ()) -> dict:
    """The settings that continue the trial recorded in ``folder``: ``now`` (flat; what the
    resume was given) with every setting of the record (``record_settings``) put in, so a
    resume needs no option but the record. A value of ``now`` counts as given when it is
    none of the ``unset`` ones (flat settings with nothing given, e.g. the node's defaults
    under the default preset and under the record's); a given value other than the record's
    is refused (InputError, exit status 2) naming the setting and both values. Called by
    the one resolver of every entrance (``trial.settings.resolve_settings``) alone."""
    rec = record_settings(folder)
    for k in sorted(rec):
        if k in now and now[k] != rec[k] and all(u.get(k) != now[k] for u in unset):
            raise InputError(f"resume: {k} = {now[k]!r} given but the record {str(folder)!r} "
                             f"has {k} = {rec[k]!r}; a resumed trial keeps the settings it "
                             "started with (leave it out)")
    out = {k: v for k, v in now.items() if not k.startswith(("learner.", "trial."))
           or k.partition(".")[2] in _FREE[k.partition(".")[0]]}
    out.update(rec)
    d = Path(folder).resolve()
    out.update(resume=str(d), record_dir=str(d.parent), trial_id=d.name)
    return out


def record_scene(folder: str | Path) -> str:
    """The scene file a resume of the record in ``folder`` runs on: the one it names when its
    bytes are the record's copy (``scene.yaml``), else the copy. InputError when neither is
    there."""
    import json
    d = Path(folder)
    try:
        orig = Path(json.loads((d / "config.json").read_text())["explorer"].get("scene_file")
                    or "")
    except (OSError, ValueError, KeyError, TypeError, AttributeError):
        orig = Path("")
    copy = d / "scene.yaml"
    if not copy.is_file() and not orig.is_file():
        raise InputError(f"resume {str(folder)!r}: the record has no scene.yaml and its "
                         f"scene_file {str(orig)!r} is not a file; give the scene")
    same = orig.is_file() and copy.is_file() and orig.read_bytes() == copy.read_bytes()
    return str(orig if same or not copy.is_file() else copy)


def catch_up(folder: str | Path, touch_fn: Callable[[int], Touch | np.ndarray]) -> int:
    """Bring a touch function whose touches follow from the ones made before (a replayed or
    simulated source, ``sources.TouchSource.trial``) to where the trial recorded in
    ``folder`` left it: ``touch_fn`` is called for every recorded touch (interrupted presses
    left out), in order, and what it gives is dropped, so its next touch is the one the
    uninterrupted trial got next. InputError naming the touch when it gives another touch
    than the record holds (another source, or its files changed since). Returns the number
    of touches made."""
    from ..core.touch import as_touch
    n = 0
    for t in read_record(folder)["touches"]:
        if t.get("interrupted"):
            continue
        seq = int(t.get("seq", 0))
        try:
            got = as_touch(touch_fn(int(t["platform_index"]))).frame
        except TouchFailed:
            got = None
        except KeyError:
            raise InputError(f"resume: touch {seq} of the record has no platform_index") \
                from None
        n += 1
        was = t.get("array") if t.get("image") else None
        if (got is None) != (t.get("image") is None) or \
                (was is not None and not np.array_equal(was, got)):
            raise InputError(f"resume: the source gives another touch {seq} than the record "
                             f"{str(folder)!r} holds (another source, or its files changed "
                             "since the trial started)")
    return n
