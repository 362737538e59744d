"""An e-value stop rule: a likelihood-ratio martingale per comparison, stopped at 1 / alpha.

Evidence of one touch. When a touch of platform p arrives (descriptor x, in the learner's
descriptor space, the prepared representation applied where there is one), it is compared with
the mean m of the OTHER side's earlier touches (n of them): a reference touch with every
comparison c already touched, a touch of comparison c with the reference. Its evidence is the
normalised distance ``z = ||x - m|| / sqrt(1 + 1/n)`` (for touches of one material the
denominator keeps the spread of z the same whatever n is).

The model (``EvidenceModel``): log z is normal under each hypothesis,
``H1`` "c is the reference's material" (mean ``mu_same``, spread ``sd_same``) and the null
``H0`` "c is a different material" (``mu_diff``, ``sd_diff``), both fitted on a library's
descriptors (``fit_evidence``: pairs of touches of one class for H1, of two classes for H0).

The e-process (``EProcess``): ``E_c`` starts at 1 and is multiplied, touch after touch, by the
likelihood ratio ``f1(z) / f0(z)`` of every new observation concerning c. Stop rule: name c
once ``E_c >= 1 / alpha`` and no other comparison's has (two above it: a wrong one broke the
null, the trial touches on). Ville's inequality gives ``P_H0(E_c ever >= 1/alpha) <= alpha`` for
each wrong comparison c, at every stopping time (looking after every touch costs nothing)
PROVIDED THAT
  (1) under H0 each new observation z, given the trial so far, follows f0 (the touches are
      independent draws and the null is correctly specified for this sensor and these
      materials: a new family whose different materials are closer than the library's breaks
      it), and
  (2) the ratio uses only the past (the model is fixed before the trial).
The observations of one trial share the means m, so (1) is an approximation; where it fails is
measured per family (``tactex experiment stop-rules``, docs/research/sequential_stop.md).

Pure numpy; no torch.
"""

from __future__ import annotations

import json
import math
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

import numpy as np

from .errors import InputError

#: A floor on the normalised distance before its log (two identical descriptors).
_Z_FLOOR = 1e-12


@dataclass(frozen=True)
class EvidenceModel:
    """Log-normal models of the normalised distance z between touches of one material
    (``*_same``) and of two materials (``*_diff``, the null); all in log units of z."""

    mu_same: float
    sd_same: float
    mu_diff: float
    sd_diff: float

    def __post_init__(self) -> None:
        for name in ("mu_same", "sd_same", "mu_diff", "sd_diff"):
            v = getattr(self, name)
            if not (isinstance(v, (int, float)) and math.isfinite(v)):
                raise InputError(f"evidence model: {name} must be a finite number, got {v!r}")
        for name in ("sd_same", "sd_diff"):
            if getattr(self, name) <= 0:
                raise InputError(f"evidence model: {name} must be > 0, got "
                                 f"{getattr(self, name)}")

    def log_ratio(self, z: float) -> float:
        """log f1(z) / f0(z) of one normalised distance ``z`` (>= 0): > 0 speaks for a match."""
        if not (math.isfinite(z) and z >= 0):
            raise InputError(f"evidence: distance must be finite and >= 0, got {z}")
        lz = math.log(max(z, _Z_FLOOR))

        def log_normal(mu: float, sd: float) -> float:
            return -0.5 * ((lz - mu) / sd) ** 2 - math.log(sd)

        return log_normal(self.mu_same, self.sd_same) - log_normal(self.mu_diff, self.sd_diff)

    def to_dict(self) -> dict[str, float]:
        return asdict(self)

    @classmethod
    def from_dict(cls, data: dict, origin: str = "evidence model") -> EvidenceModel:
        """The model from its JSON mapping; InputError names a missing or bad key."""
        try:
            return cls(**{k: float(data[k]) for k in ("mu_same", "sd_same", "mu_diff",
                                                      "sd_diff")})
        except KeyError as exc:
            raise InputError(f"{origin}: missing {exc.args[0]!r}") from None
        except (TypeError, ValueError) as exc:
            raise InputError(f"{origin}: {exc}") from None


def normalised_distance(x: np.ndarray, others: list[np.ndarray]) -> float:
    """``||x - mean(others)|| / sqrt(1 + 1/n)`` of a (D,) descriptor against n >= 1 earlier
    (D,) descriptors of the other side."""
    if not others:
        raise InputError("normalised_distance needs at least one earlier touch")
    m = np.mean(np.stack(others), axis=0)
    return float(np.linalg.norm(np.asarray(x, float) - m) / math.sqrt(1.0 + 1.0 / len(others)))


def fit_evidence(descriptors: dict[str, np.ndarray] | list[dict[str, np.ndarray]],
                 max_pairs: int = 20000, seed: int = 0, nearest: int = 0) -> EvidenceModel:
    """Fit ``EvidenceModel`` on a library: ``descriptors`` maps class -> (n_k, D) touches (>= 2
    classes, >= 2 touches in at least one), or is a list of such maps, each in its own space
    (pairs are formed only within one map: e.g. class folds each described by a representation
    fitted on the other folds). Pairs of one class give H1, pairs of two classes the null; at
    most ``max_pairs`` of each, drawn with ``seed``. z of a pair is ``||a - b|| / sqrt(2)``
    (n = 1). Both hypotheses get the larger of the two spreads: the log ratio is then linear
    and falling in log z (a far touch never speaks for a match), and a true null narrower than
    the fitted one only makes the bound conservative (E_0[ratio] < 1). ``nearest`` > 0: the
    null only from pairs of a class with its ``nearest`` nearest classes (distance of class
    means in the map's space): the different material a scene of alike fabrics offers (the
    hard scenes), not the average one; 0: every other class."""
    if nearest < 0:
        raise InputError(f"evidence model: nearest {nearest}: use 0 (every class) or more")
    spaces = [descriptors] if isinstance(descriptors, dict) else list(descriptors)
    same: list[float] = []
    diff: list[float] = []
    for space in spaces:
        groups = [np.asarray(v, float) for v in space.values()]
        if len(groups) < 2:
            raise InputError(f"evidence model: needs >= 2 classes, got {len(groups)}")
        if (any(g.ndim != 2 or len(g) == 0 for g in groups)
                or len({g.shape[1] for g in groups}) != 1):
            raise InputError("evidence model: every class needs (n >= 1, D) descriptors of one D")
        pairs = _null_pairs([g.mean(axis=0) for g in groups], nearest)
        for i, a in enumerate(groups):
            for p in range(len(a)):
                for q in range(p + 1, len(a)):
                    same.append(float(np.linalg.norm(a[p] - a[q])))
                for j in pairs[i]:
                    diff.extend(np.linalg.norm(groups[j] - a[p], axis=1).tolist())
    if len(same) < 2:
        raise InputError("evidence model: needs >= 2 pairs of touches of one class")
    rng = np.random.default_rng(seed)

    def log_z(values: list[float]) -> np.ndarray:
        v = np.asarray(values) / math.sqrt(2.0)
        if len(v) > max_pairs:
            v = rng.choice(v, max_pairs, replace=False)
        return np.log(np.maximum(v, _Z_FLOOR))

    ls, ld = log_z(same), log_z(diff)
    sd = max(float(ls.std()), float(ld.std()), 1e-3)
    return EvidenceModel(mu_same=float(ls.mean()), sd_same=sd, mu_diff=float(ld.mean()),
                         sd_diff=sd)


def _null_pairs(means: list[np.ndarray], nearest: int) -> list[list[int]]:
    """For each class i, the classes j > i it is paired with for the null: every one, or
    (``nearest`` > 0) those among the ``nearest`` nearest of either class (by mean distance;
    each unordered pair once)."""
    n = len(means)
    if nearest <= 0 or nearest >= n - 1:
        return [list(range(i + 1, n)) for i in range(n)]
    m = np.stack(means)
    d = np.linalg.norm(m[:, None, :] - m[None, :, :], axis=2)
    np.fill_diagonal(d, np.inf)
    near = {(min(i, j), max(i, j)) for i in range(n)
            for j in np.argsort(d[i], kind="stable")[:nearest].tolist()}
    return [sorted(j for (a, j) in near if a == i) for i in range(n)]


#: The nulls an e-process can use: the model's (fitted on a library), or the scene's own
NULLS = ("library", "scene")

#: null "scene": the trial's own pairs of touches of two comparisons count once there are this many
SCENE_NULL_MIN_PAIRS = 3


class EProcess:
    """The e-values ``E_c`` of C comparisons, updated touch by touch (see the module text).

    ``null`` "library": the model's null throughout. "scene": the null's mean of log z is also
    estimated from the trial's own touches of two different comparisons (different materials
    where a scene's comparisons are distinct materials, as every protocol here draws them):
    the smaller of the model's ``mu_diff`` and the mean log z of those pairs (each
    ``||a - b|| / sqrt(2)``, as the model's fit), never below ``mu_same``, once
    ``SCENE_NULL_MIN_PAIRS`` pairs exist; every e-value is then recomputed with it. A scene of
    alike materials gets a closer null, so less evidence per touch (the library's average
    different material made hard scenes stop wrong above alpha). The null then depends on the
    trial, so Ville's bound holds only as far as that estimate is the scene's true null:
    measured, not proven (docs/research/sequential_stop.md)."""

    def __init__(self, n_comparisons: int, model: EvidenceModel, alpha: float,
                 null: str = "library") -> None:
        if n_comparisons < 1:
            raise InputError(f"EProcess needs >= 1 comparison, got {n_comparisons}")
        if not 0 < alpha < 1:
            raise InputError(f"stop_alpha must be in (0, 1), got {alpha}")
        if null not in NULLS:
            raise InputError(f"stop_null {null!r}: one of {', '.join(NULLS)}")
        self.model = model
        self.alpha = float(alpha)
        self.null = null
        self.log_e = np.zeros(n_comparisons)      # log E_c
        self.observations = 0
        self._seen: list[tuple[int, float]] = []  # every observation (comparison, z)
        self._scene_lz: list[float] = []          # log z of touch pairs of two comparisons

    def null_mean(self) -> float:
        """The null's mean of log z in use (``mu_diff`` of the model, or the scene's)."""
        m = self.model
        if self.null == "scene" and len(self._scene_lz) >= SCENE_NULL_MIN_PAIRS:
            return max(m.mu_same, min(m.mu_diff, float(np.mean(self._scene_lz))))
        return m.mu_diff

    def _recompute(self) -> None:
        mu0 = self.null_mean()
        m = self.model if mu0 == self.model.mu_diff else EvidenceModel(
            self.model.mu_same, self.model.sd_same, mu0, self.model.sd_diff)
        log_e = np.zeros(len(self.log_e))
        for c, z in self._seen:
            log_e[c] += m.log_ratio(z)
        self.log_e = log_e

    @property
    def evalues(self) -> np.ndarray:
        """(C,) the e-values E_c."""
        return np.exp(self.log_e)

    def observe(self, comparison: int, z: float) -> None:
        """One observation ``z`` concerning comparison ``comparison`` (0..C-1)."""
        if not 0 <= comparison < len(self.log_e):
            raise InputError(f"comparison {comparison} outside 0..{len(self.log_e) - 1}")
        self.model.log_ratio(z)           # validates z
        self._seen.append((comparison, float(z)))
        self.observations += 1
        self._recompute()

    def add_touch(self, platform: int, x: np.ndarray, samples: list[list[np.ndarray]]) -> None:
        """A touch of ``platform`` (0 = reference, 1..C) with descriptor ``x``; ``samples``:
        the descriptors of every platform's EARLIER touches (index 0 = reference)."""
        if platform == 0:
            for c in range(1, len(samples)):
                if samples[c]:
                    self.observe(c - 1, normalised_distance(x, samples[c]))
            return
        if self.null == "scene":               # the scene's own null: two comparisons
            x = np.asarray(x, float)
            for q in range(1, len(samples)):
                if q != platform:
                    self._scene_lz.extend(
                        math.log(max(float(np.linalg.norm(x - y)) / math.sqrt(2.0), _Z_FLOOR))
                        for y in samples[q])
            if not samples[0]:
                self._recompute()
        if samples[0]:
            self.observe(platform - 1, normalised_distance(x, samples[0]))

    def sure(self) -> int | None:
        """The comparison (0..C-1) whose e-value reached 1 / alpha, else None; None too while
        two or more have (a wrong one then already broke the null model: touch on)."""
        above = np.flatnonzero(self.log_e >= math.log(1.0 / self.alpha))
        return int(above[0]) if len(above) == 1 else None

    def state(self) -> dict:
        """What the record and the operator see: the bound and the e-values."""
        return {"rule": "evalue", "alpha": self.alpha, "threshold": 1.0 / self.alpha,
                "evalues": self.evalues.tolist(), "observations": self.observations,
                "null": self.null, "null_mean_log_z": self.null_mean()}


#: The shipped evidence model: fitted by ``tactex experiment evidence-sim`` on the simulator's
#: fabrics only (nothing recorded), for the descriptor space it names.
SHIPPED_EVIDENCE = Path(__file__).parent / "data" / "evidence_sim.json"
SPACE_FIELDS = ("descriptor_height_map", "descriptor_frames", "descriptor_embedding",
                "descriptor_embedding_frames")


def descriptor_space(cfg: Any) -> dict[str, Any]:
    """The settings that decide a descriptor learner's space (what a fitted model needs)."""
    return {k: getattr(cfg, k) for k in SPACE_FIELDS}


def shipped_evidence(cfg: Any, path: Path = SHIPPED_EVIDENCE,
                     prepared: dict | None = None) -> EvidenceModel:
    """The evidence model for learner settings ``cfg``: with a prepared representation
    (``learner.representation``) the one ``tactex prepare`` fitted in its space (``prepared``:
    the file's ``evidence``); else the shipped file's, in the space it was fitted in.
    InputError naming what is missing or differs otherwise."""
    if getattr(cfg, "representation", ""):
        if prepared:
            return EvidenceModel.from_dict(prepared, f"representation file {cfg.representation}"
                                                     " (its evidence model)")
        raise InputError(f"trial.stop_rule 'evalue': representation file {cfg.representation} "
                         "holds no evidence model (made before it was fitted, or from a library "
                         "too small for class folds: >= 4 classes); remake it with `tactex "
                         "prepare`, or use trial.stop_rule=threshold")
    try:
        data = json.loads(Path(path).read_text())
    except (OSError, ValueError) as exc:
        raise InputError(f"evidence model file {path}: {exc}") from None
    want = descriptor_space(cfg)
    if data.get("space") != want:
        raise InputError(f"trial.stop_rule 'evalue': the shipped evidence model ({path.name}) "
                         f"was fitted in the descriptor space {data.get('space')}, these "
                         f"settings' is {want}; use the shipped descriptor settings or "
                         "trial.stop_rule=threshold")
    return EvidenceModel.from_dict(data.get("model", {}), f"evidence model file {path}")
