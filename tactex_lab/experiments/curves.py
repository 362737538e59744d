"""Belief curves of real-press scenes: the trials behind ``tactex experiment real``,
``real-sessions``, ``unseen`` and the ranking of ``tactex sim compare``.

A *scene* is 1 reference + C comparisons drawn from a set of classes with
``sources.assign_platforms`` (the same draw as ``tactex trial --seed S``); a *setting* is
``label=preset[:PATH=value,...]`` (``parse_setting``). Every setting runs every scene without a
stop rule up to a budget of touches after the baseline and records the belief after every
decision (``curve``: a ``BeliefCurve``, typed until ``runs.json``); the readings of a curve (``at_budget``, ``at_stop``) and the paired tests
of settings on the same scenes (``paired_at_budgets``, ``paired_at_thresholds``) follow from it.
"""

from __future__ import annotations

from dataclasses import dataclass, fields
from typing import Any

import numpy as np

from tactex_ros.core.config import trial_preset
from tactex_ros.core.engine import RoundRecord, confident
from tactex_ros.core.errors import InputError
from tactex_lab.analysis.stats import mcnemar_exact, wilcoxon_paired
from tactex_lab.experiments.common import budget_index, parse_set
from tactex_lab.experiments.runner import Backend, TrialJob, run_jobs


def parse_setting(text: str) -> tuple[str, str, str | None, dict[str, Any]]:
    """``label=preset[:PATH=val,PATH=val]`` -> (label, preset, strategy or None, overrides).

    Overrides are dotted schema paths (``tactex_ros.core.schema.overrides``):
    ``learner.<field>`` and ``trial.strategy``."""
    from tactex_ros.core.config import PRESETS
    label, sep, rest = text.partition("=")
    if not sep or not label:
        raise InputError(f"--setting {text!r}: expected label=preset[:PATH=value,...]")
    pre, _, kv = rest.partition(":")
    if pre not in PRESETS:
        raise InputError(f"--setting {text!r}: unknown preset {pre!r}; one of "
                         f"{', '.join(PRESETS)}")
    over = parse_set([it for it in kv.split(",") if it], f"--setting {text!r}:", ("strategy",))
    return label, pre, over.get("trial", {}).get("strategy"), over.get("learner", {})


def draw_scenes(classes: list[str], n: int, comparisons: int, seed0: int) -> list[list[str]]:
    """``n`` scenes [reference, comparisons...] from ``classes`` (seeds seed0 ..)."""
    from tactex_ros.sources import assign_platforms
    if len(classes) < comparisons:
        raise InputError(f"{len(classes)} classes cannot fill {comparisons} comparisons")
    return [assign_platforms(classes, comparisons, None, None, seed0 + i)[0] for i in range(n)]


@dataclass(frozen=True)
class BeliefCurve:
    """One trial read after every decision (the final one last): touches after the baseline
    (``extra``), whether the belief's top platform is the match (``correct``), its top
    probability (``conf``), the decision's time [s] (``decision_s``), how many touches went to
    the platform the belief favoured when choosing it (``believed`` of ``touched``), the
    trial's ``error`` (None: it ran), the scene's ``classes`` [reference, comparisons...] when
    known, and what ``experiment ladder`` adds per decision: ``cpu`` (cumulative learner CPU
    [s]), ``models`` and the trial's ``escalations`` / ``notes``.

    ``to_json`` / ``from_json``: the form of ``runs.json`` (key order and values as they
    were written before the curve was typed; an unset optional field is left out)."""

    extra: tuple[int, ...]
    correct: tuple[bool, ...]
    conf: tuple[float, ...]
    decision_s: tuple[float, ...]
    believed: int = 0
    touched: int = 0
    error: str | None = None
    classes: tuple[str, ...] | None = None
    cpu: tuple[float, ...] | None = None
    escalations: tuple[dict, ...] | None = None
    notes: tuple[str, ...] | None = None
    models: tuple[str, ...] | None = None

    def to_json(self) -> dict[str, Any]:
        """The JSON form (lists for tuples)."""
        out: dict[str, Any] = {}
        for f in fields(self):
            v = getattr(self, f.name)
            if v is None and f.name in _OPTIONAL:
                continue
            out[f.name] = list(v) if isinstance(v, tuple) else v
        return out

    @classmethod
    def from_json(cls, d: dict[str, Any]) -> BeliefCurve:
        """A curve from its JSON form; InputError names an unknown or missing field."""
        names = {f.name for f in fields(cls)}
        unknown = sorted(set(d) - names)
        missing = [k for k in ("extra", "correct", "conf", "decision_s") if k not in d]
        if unknown or missing:
            raise InputError(f"belief curve: unknown fields {unknown}, missing {missing}; "
                             f"known: {', '.join(sorted(names))}")
        return cls(**{k: tuple(v) if isinstance(v, list) else v for k, v in d.items()})


_OPTIONAL = ("classes", "cpu", "escalations", "notes", "models")


def curve(decisions: list[RoundRecord], truth: int, error: str | None = None,
          classes: list[str] | None = None) -> BeliefCurve:
    """Every decision of a trial (platform indices, the final one last; ``truth`` 1..C) -> its
    ``BeliefCurve`` (of the scene ``classes`` when given)."""
    extra, correct, conf, decision_s = [], [], [], []
    believed = touched = 0
    prev = None
    for r in decisions:
        probs = np.asarray(r.probs)
        base = len(r.probs) + 1                 # the baseline: every platform once
        extra.append(int(sum(r.touches) + r.reference_touches - base))
        correct.append(bool(int(np.argmax(probs)) + 1 == truth))
        conf.append(float(probs.max()))
        decision_s.append(float(r.decision_s))
        if prev is not None and prev.platform not in (None, 0):
            touched += 1
            believed += int(prev.platform == int(np.argmax(prev.probs)) + 1)
        prev = r
    return BeliefCurve(tuple(extra), tuple(correct), tuple(conf), tuple(decision_s), believed,
                       touched, error, None if classes is None else tuple(classes))


def at_budget(c: BeliefCurve, k: int) -> bool:
    """Correct after ``k`` touches after the baseline (``common.budget_index``)."""
    idx = budget_index(c.extra, k)
    return bool(idx >= 0 and c.correct[idx])


def stop_index(c: BeliefCurve, theta: float) -> int | None:
    """The decision at which a trial with stop threshold ``theta`` stops confident (None:
    never; it then ends at its last decision)."""
    for i, conf in enumerate(c.conf):
        if confident(conf, theta):
            return i
    return None


def at_stop(c: BeliefCurve, theta: float) -> tuple[bool, int, bool]:
    """(correct, touches after the baseline, stopped confident) under stop threshold theta."""
    i = stop_index(c, theta)
    if i is not None:
        return c.correct[i], c.extra[i], True
    return c.correct[-1], c.extra[-1], False


def belief_curves(scenes: list[list[str]], settings: list[tuple], source: str, seed: int,
                  budget: int, tag: str, backend: Backend = Backend(), threads: int = 1,
                  quiet: bool = False, contact_guard: bool = False
                  ) -> dict[str, list[BeliefCurve]]:
    """Run every scene (``[reference, comparisons...]`` classes) with every setting of
    ``parse_setting`` on ``source``, no stop rule, ``budget`` touches after the baseline; scene
    i has seed ``seed + i`` for every setting (paired). Returns {label: [curve per scene]}
    (``BeliefCurve``s with their scene's ``classes``). ``contact_guard``: a press without
    contact against its own no-contact frame is refused and pressed again, as on the robot
    (``TrialJob.contact_guard``)."""
    jobs = []
    for i, classes in enumerate(scenes):
        for label, pre, strategy, over in settings:
            jobs.append(TrialJob(source=source, seed=seed + i,
                                 trial=trial_preset(pre, strategy=strategy, rounds=budget,
                                                    stop_confidence=0.0), preset=pre,
                                 overrides=over, platform_classes=classes,
                                 comparisons=len(classes) - 1, catch_errors=True,
                                 no_contact_reference=False, contact_guard=contact_guard,
                                 trial_id=f"{tag}{i}", tags={"setting": label, "set": tag}))
    res = run_jobs(jobs, backend, threads=threads, description=f"{tag} scenes x settings",
                   quiet=quiet)
    out: dict[str, list[BeliefCurve]] = {s[0]: [] for s in settings}
    for r in res:
        out[r.job.tags["setting"]].append(curve(r.decisions, r.truth, r.error, r.classes))
    empty = [c for cs in out.values() for c in cs if not c.extra]
    if empty:          # no decision to score: refused presses, not a figure (IndexError before)
        why = sorted({c.error or "no decision" for c in empty})
        raise InputError(f"{source}: {len(empty)} of {len(res)} trials ended before their "
                         f"first decision, so they cannot be scored (e.g. every press of a "
                         f"class refused); scenes {[list(c.classes or ()) for c in empty][:3]}"
                         f": {'; '.join(why[:3])}")
    return out


def _paired(curves: dict[str, list[BeliefCurve]], reference: str, points, outcome) -> dict:
    """Every setting against ``reference`` on the same scenes at each point (a budget or a
    threshold): ``outcome(curve, point)`` gives (correct, touches after the baseline or None).
    {setting: {str(point): {"reference", "setting" (accuracies), "p" (exact McNemar)[,
    "touches_p" (Wilcoxon on touches, where outcomes carry touches)]}}}."""
    out = {}
    for lab, cs in curves.items():
        if lab == reference:
            continue
        row = {}
        for pt in points:
            a = [outcome(c, pt) for c in curves[reference]]
            b = [outcome(c, pt) for c in cs]
            ok_a, ok_b = [x[0] for x in a], [x[0] for x in b]
            row[str(pt)] = {"reference": float(np.mean(ok_a)), "setting": float(np.mean(ok_b)),
                            "p": mcnemar_exact(ok_a, ok_b)["p"]}
            if a and a[0][1] is not None:
                row[str(pt)]["touches_p"] = wilcoxon_paired([x[1] for x in a],
                                                            [x[1] for x in b])["p"]
        out[lab] = row
    return out


def paired_at_budgets(curves: dict[str, list[BeliefCurve]], reference: str,
                      budgets: tuple[int, ...] = (0, 1, 3, 5, 10)) -> dict:
    """Exact McNemar of every setting against ``reference`` at fixed touch budgets (no stop
    rule), on the same scenes: {setting: {str(k): {"reference", "setting", "p"}}}."""
    return _paired(curves, reference, budgets, lambda c, k: (at_budget(c, k), None))


def paired_at_thresholds(curves: dict[str, list[BeliefCurve]], reference: str,
                         thresholds: list[float]) -> dict:
    """Every setting against ``reference`` under each stop threshold, on the same scenes:
    {setting: {str(theta): {"reference", "setting" (accuracies), "p" (exact McNemar),
    "touches_p" (Wilcoxon on touches after the baseline)}}}."""
    return _paired(curves, reference, thresholds, at_stop)
