"""The ranking part of the sim-to-real report (``tactex sim compare``,
``analysis/sim_vs_real.py``): the same settings on simulated and real scenes through the belief
curves of ``curves``; Spearman rho of the two rankings."""

from __future__ import annotations

from typing import Any

import numpy as np

from tactex_ros.core.config import SHIPPED_STOP
from tactex_ros.core.errors import InputError
from tactex_lab.analysis.stats import spearman_interval, wilson
from tactex_lab.experiments.curves import (at_budget, at_stop, belief_curves, draw_scenes,
                                           parse_setting)
from tactex_lab.experiments.runner import Backend


def run_ranking(real_dir: str, settings: list[str] | tuple[str, ...], scenes: int,
                comparisons: int, budget: int, seed: int, workers: int,
                sim_spec: str = "sim:recorded", real_one_session: bool = False
                ) -> dict[str, Any]:
    """The ranking part of the sim-to-real report (``tactex sim compare``,
    ``analysis/sim_vs_real.py``): every setting on the same ``scenes`` simulated and real
    scenes (1 + ``comparisons`` distinct classes: catalogue fabrics / the folder's classes),
    through this module's scene draw, runner and belief curves.

    Per setting and side: accuracy after ``budget`` touches after the baseline (Wilson
    interval), accuracy averaged over 0..budget touches, accuracy at the default's stop rule
    (belief 0.9) and the touches it took. Then Spearman rho of the two sides' rankings with
    a bootstrap interval, and the gaps real - sim. ``sim_spec``: the simulated source
    (``sim[:difficulty][:recorded]``; recorded sessions as the real folder's);
    ``real_one_session``: the real presses moved onto one background per trial
    (``replay:DIR:one-session``, to rank against the live simulator ``sim``)."""
    from tactex_ros.sources import open_source
    if not (sim_spec == "sim" or sim_spec.startswith("sim:")):
        raise InputError(f"--sim-source {sim_spec!r}: use sim[:difficulty][:recorded]")
    open_source(sim_spec)            # a bad spec is refused before any work
    if scenes < 2:
        raise InputError(f"--scenes must be >= 2 for a ranking, got {scenes}")
    if budget < 0:
        raise InputError(f"--budget must be >= 0, got {budget}")
    parsed = [parse_setting(s) for s in settings]
    labels = [p[0] for p in parsed]
    if len(labels) < 2 or len(set(labels)) != len(labels):
        raise InputError(f"the ranking needs >= 2 settings with unique labels, got {labels}")
    theta = SHIPPED_STOP
    out: dict[str, Any] = {"settings": {}, "scenes": scenes, "comparisons": comparisons,
                           "budget": budget, "stop_theta": theta, "seed": seed,
                           "setting_specs": list(settings), "sim_source": sim_spec,
                           "real_one_session": real_one_session}
    real_spec = f"replay:{real_dir}" + (":one-session" if real_one_session else "")
    scores: dict[str, dict[str, np.ndarray]] = {}
    for side, spec in (("sim", sim_spec), ("real", real_spec)):
        classes = sorted(open_source(spec).classes)
        curves = belief_curves(draw_scenes(classes, scenes, comparisons, seed),
                               parsed, spec, seed, budget, f"{side}-",
                               Backend("joblib", workers))
        errors = sum(1 for cs in curves.values() for c in cs if c.error)
        at_b = np.array([[at_budget(c, budget) for c in curves[lab]] for lab in labels], float)
        mean_b = np.array([[np.mean([at_budget(c, k) for k in range(budget + 1)])
                            for c in curves[lab]] for lab in labels], float)
        stops = [[at_stop(c, theta) for c in curves[lab]] for lab in labels]
        scores[side] = {"at_budget": at_b, "mean_over_budgets": mean_b}
        for i, lab in enumerate(labels):
            k = int(at_b[i].sum())
            out["settings"].setdefault(lab, {})[side] = {
                "accuracy": k / scenes, "ci95": list(wilson(k, scenes)),
                "accuracy_mean_over_budgets": float(mean_b[i].mean()),
                "accuracy_at_stop": float(np.mean([st[0] for st in stops[i]])),
                "touches_at_stop": float(np.mean([st[1] for st in stops[i]]))}
        out[f"{side}_failed_trials"] = errors
    for lab in labels:
        v = out["settings"][lab]
        v["gap_real_minus_sim"] = v["real"]["accuracy"] - v["sim"]["accuracy"]
    gaps = [out["settings"][lab]["gap_real_minus_sim"] for lab in labels]
    out["accuracy_spearman"] = spearman_interval(scores["sim"]["at_budget"],
                                                 scores["real"]["at_budget"], seed=seed)
    out["mean_over_budgets_spearman"] = spearman_interval(
        scores["sim"]["mean_over_budgets"], scores["real"]["mean_over_budgets"], seed=seed)
    out["mean_gap_real_minus_sim"] = float(np.mean(gaps))
    out["mean_abs_gap"] = float(np.mean(np.abs(gaps)))
    return out
