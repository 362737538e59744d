"""What a trial came to, read from its record once for every page that shows it (the trial
report, the session's rows, the report index): the scene's platforms and fabrics, the answer,
its belief, the truth where known, whether it is not sure, and the verdict."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from ..record import not_sure, read_config, read_record
from .context import scene_fabrics, scene_truth


@dataclass(frozen=True)
class Outcome:
    """A trial's outcome. ``finished``: it has a result without an error; ``correct``: the
    answer is a true match (None: the truth is not known or it did not finish), a not-sure
    answer may be correct here and is never called so (``verdict``)."""

    ids: list[str]                     # platform ids, the reference first
    fabrics: dict[str, str]            # platform id -> fabric, where the record says
    comps: list[str]                   # the comparisons
    prediction: str | None
    belief: float | None               # the final belief in the prediction
    truth: list[str] | None            # the true matches, where known
    finished: bool
    skipped: bool                      # skipped by the operator (no answer)
    unsure: bool
    correct: bool | None
    touches: int                       # accepted touches

    @property
    def verdict(self) -> str:
        """'correct', 'wrong', 'not sure', 'truth unknown', 'skipped' or 'unfinished'."""
        if self.skipped:
            return "skipped"
        if not self.finished:
            return "unfinished"
        if self.unsure:
            return "not sure"
        return {True: "correct", False: "wrong", None: "truth unknown"}[self.correct]


def outcome(folder: str | Path, rec: dict | None = None, cfg: dict | None = None) -> Outcome:
    """The outcome of record ``folder`` (``rec``, ``cfg``: its record and config.json when
    read already)."""
    d = Path(folder)
    rec = rec if rec is not None else read_record(d, images=False)
    cfg = cfg if cfg is not None else read_config(d)
    res = rec["result"] or {}
    ids, fabrics = scene_fabrics(d)
    touches, decisions = rec["touches"], rec["decisions"]
    comps = ids[1:] if ids else sorted({t.get("platform_id") for t in touches} - {None})
    conf = (cfg.get("trial") or {}).get("stop_confidence")
    pred = res.get("prediction")
    truth = res.get("truth_platforms")
    if truth is None and (cfg.get("session") or {}).get("truth") is not None:
        truth = cfg["session"]["truth"]
    finished = bool(res) and "error" not in res
    if truth is None and finished:
        truth = scene_truth(d)             # a record written before result.json kept it
    final_belief = (decisions[-1].get("belief") if decisions else None) or []
    p_belief = (final_belief[comps.index(pred)] if isinstance(pred, str) and pred in comps
                and len(final_belief) == len(comps) else None)
    skipped = bool(res.get("skipped"))
    unsure = finished and not_sure(res, conf, p_belief)
    correct: bool | None = None
    if finished and isinstance(res.get("correct"), bool):
        correct = res["correct"]
    elif finished and truth is not None:
        correct = pred in truth
    return Outcome(ids=ids, fabrics=fabrics, comps=comps, prediction=pred, belief=p_belief,
                   truth=truth, finished=finished, skipped=skipped, unsure=bool(unsure),
                   correct=correct, touches=len([t for t in touches if t.get("accepted")]))
