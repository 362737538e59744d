"""One trial's life beside the engine, without ROS: its record, resume, decisions, checkpoints,
report and result (``TrialRun``).

The robot side (the explorer node, ``ros/nodes/explorer_node.py``) injects the live touch
function ``press(platform, meta) -> Touch``: it makes the touch (0 = reference, 1..C) and fills
``meta`` (a dict) with what the record keeps of it (time, force, pose, attempts, ...).
``TrialRun`` puts every touch on disk before the engine uses it: an accepted touch with its
image, its further in-contact frames and no-contact frame; a failed one (``TouchFailed``) with its reason; a press cut off by
the fault itself (``TouchInterrupted``) marked ``interrupted``, so a resume makes it again.

With ``resume`` (a record folder) the trial continues an interrupted one: the settings are
checked against the record's (``resume.check_settings``), the recorded touches are handed to the
engine again in order (``resume.Replay``), the learner is restored from the last checkpoint that
fits, and decisions the record already holds are not written twice (a re-made decision whose
belief differs from the recorded one is noted in ``events.jsonl``). Then live touches take
over. A resumed trial ends with the outcome of the uninterrupted one.
"""

from __future__ import annotations

import logging
import os
import time
from pathlib import Path
from typing import Any
from collections.abc import Callable

import numpy as np

from ..core.engine import RoundRecord, TouchFailed, TrialSpec
from ..core.errors import TrialError
from ..core.touch import Touch
from .record import MIN_FREE_MB, TrialRecord, append_event, free_trial_id, read_record

#: ``press(platform, meta)``: the live touch, ``meta`` filled in place for the record
Press = Callable[[int, dict], Touch]

_log = logging.getLogger("tactex.trial")


class TouchInterrupted(TrialError):
    """A touch was cut off by a fault that ends the trial (e.g. the press server is gone): it
    is recorded as ``interrupted`` and made again by a resume."""


def decision_fields(rec: RoundRecord, platform_ids: list[str]) -> dict[str, Any]:
    """A decision as ``tactex/ExplorationState`` carries it (``platform_ids``: reference first):
    the next platform's id ('' when done), belief and uncertainty as float32 values (the
    message's type), touches per comparison."""
    nxt = ("" if rec.platform is None else platform_ids[0] if rec.platform == 0
           else platform_ids[rec.platform])
    scores = list(rec.scores or [0.0] * len(rec.probs))[-len(rec.probs):]
    return {"next": nxt, "belief": [float(np.float32(v)) for v in rec.probs],
            "uncertainty": [float(np.float32(v)) for v in scores],
            "touches": [int(v) for v in rec.touches]}


class TrialRun:
    """Open (``record_dir/trial_id``) or resume (``resume``: a record folder) one trial of
    ``spec`` and run it with the live touch function ``press``.

    ``inputs``: what config.json keeps of the settings ({section: dict}; a resume refuses
    other values where they change the trial); ``scene_file``: copied into a new record;
    ``placed_scene``: scene text written instead (a session trial's placement);
    ``check_record(folder)``: more checks of a record to resume (the scene's platforms);
    ``log(level, text)``: where warnings and notes go (``logging`` levels);
    ``min_free_mb``: the free disk the record keeps before the trial and each touch [MB];
    ``guard_reference``: the contact guard takes the first touch's no-contact frame as the
    sensor session's (the robot: one camera serves every touch); False where each touch
    comes from a session of its own and is judged against its own frame before it arrives
    (a replay: ``engine.refusing_no_contact``)."""

    def __init__(self, spec: TrialSpec, record_dir: str | Path, trial_id: str = "", *,
                 press: Press, inputs: dict[str, Any], resume: str | Path | None = None,
                 scene_file: str | Path | None = None, placed_scene: str | None = None,
                 check_record: Callable[[Path], None] | None = None,
                 log: Callable[[int, str], None] | None = None,
                 min_free_mb: float = MIN_FREE_MB, guard_reference: bool = True) -> None:
        self.spec = spec
        self.guard_reference = guard_reference
        self.min_free_mb = float(min_free_mb)
        self.ids = list(spec.platform_ids or ["reference"] + [f"c{i + 1}" for i in
                                                               range(spec.comparisons)])
        self.press = press
        self.log = log or (lambda level, text: _log.log(level, text))
        self.engine = spec.engine()          # settings refused here, before anything is written
        self.replay = None
        self._replay_decisions: list[dict] = []
        self._decisions = 0
        self._warned: set[str] = set()
        self.result: dict | None = None
        #: what of the finished trial could not be written beside its result (report.html):
        #: the caller ends with a run-time failure naming each file (exit status 1)
        self.write_failures: list[str] = []
        if resume:
            self._open_resume(Path(resume).resolve(), inputs, check_record)
        else:
            self.trial_id = trial_id or free_trial_id(record_dir)
            self.record = TrialRecord(record_dir, self.trial_id, min_free_mb=self.min_free_mb)
            self.record.save_inputs(scene_file, inputs, scene_text=placed_scene)

    def _open_resume(self, d: Path, inputs: dict,
                     check_record: Callable[[Path], None] | None) -> None:
        from .resume import check_settings, load_replay, restore_engine
        self.record = TrialRecord(d.parent, d.name, resume=True, min_free_mb=self.min_free_mb)
        self.trial_id = d.name
        check_settings(d, inputs)
        if check_record is not None:
            check_record(d)
        self.replay, rec = load_replay(d, self._live, self.ids)
        self.engine, after, how = restore_engine(self.spec, d, self.replay.recorded,
                                                 self.guard_reference)
        self.replay.recorded = [r for r in self.replay.recorded if r.seq > after]
        self._replay_decisions = rec["decisions"]
        self._decisions = len(self.engine.records)     # decisions restored, not re-made
        # a damaged checkpoint is not used: the learner re-trains, and the console says so
        self.log(logging.WARNING if "not used" in how else logging.INFO, f"resume: {how}")
        append_event(d, {"event": "resumed", "after_touch": self.record.n_touches,
                         "touches_replayed": len(self.replay.recorded),
                         "decisions_on_disk": len(rec["decisions"]),
                         "checkpoint_round": len(self.engine.records), "how": how,
                         "time": time.time(), "command": os.environ.get("TACTEX_COMMAND", ""),
                         "run_id": str(inputs.get("explorer", {}).get("run_id", ""))})

    @property
    def dir(self) -> Path:
        return self.record.dir

    def _warn_once(self, key: str, text: str) -> None:
        if key not in self._warned:
            self._warned.add(key)
            self.log(logging.WARNING, text)

    # ------------------------------------------------------------------ touches
    def touch(self, platform: int) -> Touch:
        """The engine's ``touch_fn``: a recorded touch while a resume replays, then live ones."""
        if self.replay is None:
            return self._live(platform)
        got = self.replay(platform)
        if self.replay.current is not None and isinstance(got, Touch):
            self._set_guard_reference(got.no_contact)
        return got

    def _live(self, platform: int) -> Touch:
        """Press ``platform``; the touch (or why it failed) is on disk before it is used."""
        meta: dict[str, Any] = {"platform_id": self.ids[platform], "platform_index": platform}
        try:
            touch = self.press(platform, meta)
        except TouchFailed as exc:
            self.record.add_touch(None, dict(meta, accepted=False, reason=str(exc)))
            self.log(logging.WARNING, f"touch of {self.ids[platform]} failed: {exc}")
            raise
        except TouchInterrupted as exc:     # the press never ended: a resume makes it again
            self.record.add_touch(None, dict(meta, accepted=False, reason=str(exc),
                                             interrupted=True))
            raise
        self.record.add_touch(touch.frame, dict(meta, accepted=True),
                              no_contact=touch.no_contact, extra=touch.extra)
        self._set_guard_reference(touch.no_contact)
        return touch

    def _on_rejected(self, platform: int, exc: Exception) -> None:
        """The engine refused the last recorded touch (e.g. the guard: a blank frame)."""
        cur = self.replay.current if self.replay is not None else None
        if cur is not None:              # a replayed touch: marked already, unless cut off
            if not cur.rejected:
                self.record.reject_touch(cur.seq, str(exc))
            return
        self.record.reject_touch(self.record.n_touches, str(exc))
        self.log(logging.WARNING, f"touch rejected: {exc}")

    def _set_guard_reference(self, no_contact: np.ndarray | None) -> None:
        """Give the core's contact guard the sensor's no-contact frame (first valid one)."""
        guard = self.engine.guard
        if guard is None or guard.has_reference or no_contact is None or \
                not self.guard_reference:
            return
        guard.set_reference(no_contact)

    # ------------------------------------------------------------------ decisions
    def _decision(self, rec: RoundRecord) -> dict[str, Any]:
        """Write the decision after round ``rec`` (unless a resume re-made one the record
        holds) and return it; then the learner's checkpoint."""
        eng = self.engine
        pred = self.ids[int(np.argmax(rec.probs)) + 1] if eng.done else ""
        d = decision_fields(rec, self.ids)
        line = {"round": rec.round, "next": d["next"], "belief": d["belief"],
                "uncertainty": d["uncertainty"], "touches": d["touches"], "model": rec.model,
                "decision_s": rec.decision_s, "done": eng.done, "prediction": pred,
                "sure": eng.sure if eng.done else None, "time": time.time()}
        if self.replay is None or not self._replayed_decision(d["belief"]):
            self.record.add_decision(line)
        self._checkpoint()
        return line

    def _replayed_decision(self, belief: list[float]) -> bool:
        """True for a decision a resumed trial re-made that the record already holds (a
        recomputed belief that differs from the recorded one is noted in events.jsonl)."""
        i, self._decisions = self._decisions, self._decisions + 1
        if i >= len(self._replay_decisions):
            return False
        was = self._replay_decisions[i].get("belief") or []
        diff = float(np.max(np.abs(np.subtract(was, belief)))) \
            if len(was) == len(belief) else float("inf")
        if diff > 1e-4:
            append_event(self.record.dir, {"event": "replay_differs", "decision": i + 1,
                                           "max_belief_diff": diff})
            self.log(logging.WARNING, f"resume: decision {i + 1} differs from the record "
                                      f"(belief by up to {diff:.3g})")
        return True

    def _checkpoint(self) -> None:
        """After a round: the learner's state into the record, so a resume continues from it
        instead of re-training (a learner without the hook, e.g. the descriptor, writes none).
        A failure here never stops the trial: a resume re-trains."""
        ck = self.engine.checkpoint()
        if ck is None:
            return
        rp = self.replay
        after = rp.recorded[rp.pos - 1].seq if rp is not None and rp.replaying and rp.pos \
            else self.record.n_touches
        try:
            self.record.write_checkpoint(ck[0], ck[1], after)
        except (OSError, TrialError) as exc:
            self._warn_once("checkpoint", f"learner checkpoint not written: {exc}")

    # ------------------------------------------------------------------ the trial
    def run(self, on_decision: Callable[[RoundRecord, dict], None] | None = None,
            extra: Callable[[dict], dict] | None = None, t0: float | None = None) -> dict:
        """Run the trial to its result: written to ``result.json`` with ``report.html`` beside
        it, and returned. ``on_decision(rec, line)`` sees every decision after it is recorded;
        ``extra(result)`` adds fields before the result is written; ``t0``: when the trial
        started (``time.monotonic``) for ``elapsed_s``."""
        eng = self.engine

        def on_round(rec: RoundRecord) -> None:
            line = self._decision(rec)
            if on_decision is not None:
                on_decision(rec, line)

        res = eng.run(self.touch, on_round=on_round, on_rejected=self._on_rejected)
        out = res.to_dict()
        out.update(trial_id=self.trial_id, record=str(self.record.dir),
                   strategy=eng.trial_cfg.strategy, model=eng.learner.model_name,
                   seed=self.spec.seed,
                   fabric_library=getattr(eng.learner, "library_state", {"used": False}))
        if self.replay is not None:
            out["resumed"] = [e for e in read_record(self.record.dir, images=False)["events"]
                              if e.get("event") == "resumed"]
        if out.get("truth") is None:
            from .report import scene_truth
            same = scene_truth(self.record.dir)   # a simulated scene names every fabric
            if same:
                out.update(truth=same[0] if len(same) == 1 else None, truth_platforms=same,
                           correct=out.get("prediction") in same)
        if t0 is not None:
            out["elapsed_s"] = time.monotonic() - t0
        if extra is not None:
            out.update(extra(out))
        self.result = out
        self.record.finish(out)
        self._write_report()
        return out

    def skip(self, by: dict[str, Any]) -> dict:
        """The operator skipped the trial: its result says so (``skipped``, no answer; ``by``:
        who asked), its presses so far stay in the record."""
        self.result = {"skipped": True, "trial_id": self.trial_id, "prediction": None,
                       "stop_reason": "skipped", "touches": self.record.n_touches,
                       "record": str(self.record.dir), "seed": self.spec.seed, **by}
        self.record.finish(self.result)
        return self.result

    def fail(self, exc: BaseException) -> dict:
        """The trial ended in ``exc``: the error is its recorded result."""
        self.result = {"error": f"{type(exc).__name__}: {exc}", "trial_id": self.trial_id}
        try:
            self.record.finish(self.result)
        except TrialError as why:     # e.g. the disk is full: the record stays resumable
            self.log(logging.ERROR, f"the failure could not be recorded: {why}")
        return self.result

    def _write_report(self) -> None:
        """``report.html`` beside the result; a failure there never loses the trial (the
        result is on disk) but is one of ``write_failures``."""
        try:
            from .report import write_trial_report
            write_trial_report(self.record.dir)
        except Exception as exc:  # noqa: BLE001 - the record is the ground truth
            why = (str(exc) if str(self.record.dir / "report.html") in str(exc) else
                   f"{str(self.record.dir / 'report.html')!r} not written: {exc}")
            self.write_failures.append(why)
            self.log(logging.WARNING, f"report.html not written: {exc}")

    def close(self) -> None:
        """The process is stopping mid-trial: a write in progress finishes, nothing more."""
        self.record.close()
