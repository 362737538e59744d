"""What `tactex prepare` does to a library's descriptors, described once: ``PrepareSettings``
(the metric and the belief temperature's calibration; the class defaults are the product's)
and ``prepare``, which fits the representation and calibrates it. `tactex prepare` makes its
options from this schema, and the lab's ``experiment unseen`` prepares each of its settings
with it (stating where it wants other values than these defaults).

The schema imports only pydantic (`tactex prepare --help` builds it); ``prepare`` imports the
numpy modules when it runs.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import TYPE_CHECKING, Literal

from .config import SHIPPED_STOP
from .schema import Schema, param

if TYPE_CHECKING:
    import numpy as np

    from .config import DescriptorSettings
    from .representation import Representation


class PrepareSettings(Schema):
    """How a representation file is prepared from a library's descriptors."""

    kind: Literal["none", "whiten", "lda"] = param(
        "whiten", "the metric: whiten (within-class whitening; measured best, "
                  "docs/research/unseen_materials.md), lda (Fisher directions of the library, "
                  "--dims of them), none (descriptor as is; the file then only carries the "
                  "calibrated temperature)")
    dims: int = param(24, "output dimensions of --kind lda, below the descriptor's size (129 "
                          "with the height map, 106 without)", 1, 128)
    shrink: float = param(1.0, "ridge added to the within-class covariance (standardised units)",
                          1e-6, 1e6)
    calibration: Literal["stop", "target", "nll", "off"] = param(
        "off", "belief temperature from left-out library trials: stop (largest whose wrong "
               "stops stay <= 1 - theta at theta 0.8, 0.9, 0.95), target (<= --max-wrong at "
               "--stop-at), nll, off (default: the config's temperature; the calibrated ones "
               "stopped wrong more often on unseen classes, docs/research/unseen_materials.md)")
    stop_at: float = param(SHIPPED_STOP, "the trials' stop threshold, for --calibration target",
                           0.5, 0.9999)
    max_wrong: float = param(0.03, "wrong-stop rate allowed at --stop-at, for --calibration "
                                   "target", 0.0, 0.5)
    calibration_folds: int = param(3, "class folds of the left-out trials", 2, 20)
    calibration_scenes: int = param(40, "left-out trials per fold", 1, 10000)
    calibration_budget: int = param(10, "touches after the baseline per left-out trial", 1, 100)
    evidence_nearest: int = param(
        0, "the e-value stop's null from each class's N nearest classes only (the different "
           "material of a scene of alike fabrics); 0: every other class", 0, 1000)
    calibration_start: float | None = param(
        None, "temperature the left-out trials run with (default: the config's)", 1e-4, 10.0)


def prepare(descriptors: dict[str, np.ndarray], settings: PrepareSettings,
            cfg: DescriptorSettings, seed: int = 0) -> Representation:
    """The representation of the library ``{class: (n, D) descriptors}`` as ``settings`` say:
    the metric fitted on every class, and (``calibration`` not off) the belief temperature
    calibrated on left-out trials run with the learner settings ``cfg``
    (``core/calibration.py``), with what they measured in ``Representation.calibration``."""
    from functools import partial

    from . import calibration, representation
    s = settings
    fit = partial(representation.fit, shrink=s.shrink, kind=s.kind, dims=s.dims)
    rep = fit(descriptors)
    rep.frames = int(cfg.descriptor_frames)
    from .descriptor import embedding_of
    emb = embedding_of(cfg)
    rep.embedding = emb.identity if emb is not None else ""
    rep.embedding_frames = int(cfg.descriptor_embedding_frames) if emb is not None else 0
    evidence = heldout_evidence(descriptors, fit, s.calibration_folds, seed,
                                nearest=s.evidence_nearest)
    rep.evidence = evidence.to_dict() if evidence is not None else {}
    if s.calibration != "off":
        trajs = calibration.trajectories(descriptors, fit, cfg, folds=s.calibration_folds,
                                         scenes=s.calibration_scenes,
                                         budget=s.calibration_budget, seed=seed,
                                         temperature0=s.calibration_start)
        rep.temperature = calibration.fit_temperature(
            trajs, s.calibration, *(((s.stop_at,), s.max_wrong)
                                    if s.calibration == "target" else ()))
        rep.calibration = dict(calibration.report(trajs, rep.temperature),
                               method=s.calibration, folds=s.calibration_folds,
                               budget=s.calibration_budget)
    return rep


def heldout_evidence(descriptors: dict[str, np.ndarray],
                     fit_rep: Callable[[dict[str, np.ndarray]], Representation], folds: int,
                     seed: int = 0, nearest: int = 0):
    """The e-value stop's evidence model (``core/evidence.py``) in the prepared space, fitted
    as a new material meets it: the library's classes in ``folds`` class folds, each fold
    described by the representation ``fit_rep`` fits on the other folds (pairs only within a
    fold). A fold is skipped when it has fewer than 2 classes or the others cannot be fitted;
    None when no fold is left (a library too small: its file then holds no evidence model).
    ``nearest``: ``fit_evidence``'s (the null from each class's nearest classes only)."""
    from .calibration import class_split
    from .errors import InputError
    from .evidence import fit_evidence
    classes = sorted(descriptors)
    spaces = []
    for held in class_split(classes, folds, seed):
        if len(held) < 2:
            continue
        try:
            rep = fit_rep({c: descriptors[c] for c in classes if c not in held})
        except InputError:                 # the other folds too few to fit a metric
            continue
        spaces.append({c: rep.apply(descriptors[c]) for c in held})
    try:
        return fit_evidence(spaces, seed=seed, nearest=nearest) if spaces else None
    except InputError:                     # no class with two presses in any fold
        return None
