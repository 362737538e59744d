"""Scene protocols of the 1 + C experiments: ``random`` (the comparisons drawn uniformly from
the source's classes, ``sources.trial_scene``) and ``hard`` (the reference's nearest classes,
as a fabric study picks materials that feel alike; issue 51).

``hard``: the reference class r is drawn (seeded) from the source's classes; its comparisons
are r and the C - 1 classes whose mean descriptor is nearest to r's. The distance is the
shipped descriptor's (the learner's raw descriptor under the default settings), weighted per
dimension by the inverse of the pooled within-class variance *fitted on another library*
(``--metric-library``, class-disjoint: none of its classes is in the scene). The class means
themselves are those of the scene's own library (every press of each class): a class exists
only there, and "alike" is a property of these materials as pressed. Nothing the trial's
learner or stop uses is fitted on them, so the scenes are chosen, not learned from.
"""

from __future__ import annotations

import numpy as np

from tactex_ros.core.errors import InputError

#: Floor of a dimension's within-class variance, relative to the median over dimensions (a
#: constant dimension would otherwise weigh infinitely).
VAR_FLOOR = 1e-3


def metric_weights(by_class: dict[str, np.ndarray]) -> np.ndarray:
    """(D,) the diagonal metric of a library: 1 / (pooled within-class variance + ``VAR_FLOOR``
    x its median), from ``by_class`` {class: (n_k, D) descriptors}; classes of one press add
    nothing to the pool. InputError when no class has two presses."""
    ss, dof = None, 0
    for x in by_class.values():
        x = np.asarray(x, dtype=np.float64)
        if x.ndim != 2:
            raise InputError(f"descriptors must be (presses, D), got shape {x.shape}")
        if ss is None:
            ss = np.zeros(x.shape[1])
        if x.shape[0] > 1:
            ss = ss + ((x - x.mean(axis=0)) ** 2).sum(axis=0)
            dof += x.shape[0] - 1
    if ss is None or dof == 0:
        raise InputError("metric library: needs a class with at least two presses")
    var = ss / dof
    return 1.0 / (var + VAR_FLOOR * float(np.median(var)) + 1e-300)


def nearest_classes(means: dict[str, np.ndarray], weights: np.ndarray, reference: str,
                    k: int) -> list[str]:
    """The ``k`` classes of ``means`` {class: (D,) mean descriptor} other than ``reference``
    nearest to it by sum_j w_j (m_j - r_j)^2, nearest first (ties: class name)."""
    if reference not in means:
        raise InputError(f"reference class {reference!r} has no mean descriptor")
    if not 0 <= k <= len(means) - 1:
        raise InputError(f"{k} nearest classes asked, {len(means) - 1} others known")
    r = np.asarray(means[reference], dtype=np.float64)
    w = np.asarray(weights, dtype=np.float64)
    d = {c: float((w * (np.asarray(m, dtype=np.float64) - r) ** 2).sum())
         for c, m in means.items() if c != reference}
    return sorted(d, key=lambda c: (d[c], c))[:k]


def hard_scene(means: dict[str, np.ndarray], weights: np.ndarray, comparisons: int,
               seed: int) -> tuple[list[str], int]:
    """A hard scene: ([reference, comparison 1..C] classes, the true match 1..C). The
    reference is drawn from the sorted classes of ``means`` (seeded); the comparisons are it
    and its ``comparisons - 1`` nearest classes (``nearest_classes``), in a seeded order."""
    if comparisons < 2:
        raise InputError(f"a scene needs >= 2 comparisons, got {comparisons}")
    names = sorted(means)
    if len(names) < comparisons:
        raise InputError(f"--comparisons {comparisons}: the source has only {len(names)} "
                         "classes")
    rng = np.random.default_rng([seed, 53])
    ref = names[int(rng.integers(len(names)))]
    comps = [ref] + nearest_classes(means, weights, ref, comparisons - 1)
    comps = [comps[i] for i in rng.permutation(len(comps))]
    return [ref] + comps, comps.index(ref) + 1


def library_descriptors(src, cfg) -> dict[str, np.ndarray]:
    """{class: (presses, D) raw descriptors} of every press of a replay source ``src`` under
    the learner settings ``cfg`` (``descriptor.raw_descriptor``); unreadable presses are left
    out (InputError for a class with none)."""
    from tactex_ros.core.descriptor import raw_descriptor
    out = {}
    for c in src.classes:
        rows = []
        for path in src.presses(c):
            try:
                rows.append(raw_descriptor(src.touch(path), cfg))
            except InputError:
                continue
        if not rows:
            raise InputError(f"class {c!r}: no readable press to describe")
        out[c] = np.stack(rows)
    return out


class SceneDraw:
    """Draws the scenes of an experiment by its protocol: ``draw(seed) -> (classes, truth)``.

    ``random``: ``sources.trial_scene`` (as before). ``hard``: ``hard_scene`` on the source's
    class means, with the metric fitted on ``metric_library`` (a replay:DIR other than the
    source; InputError otherwise). ``cfg``: the learner settings whose descriptor is used."""

    def __init__(self, protocol: str, src, comparisons: int, cfg=None,
                 metric_library: str | None = None, source_spec: str = "") -> None:
        from tactex_ros.sources import open_source
        if protocol not in ("random", "hard"):
            raise InputError(f"--scene-protocol {protocol!r}: random or hard")
        self.protocol, self.src, self.comparisons = protocol, src, comparisons
        self.means: dict[str, np.ndarray] = {}
        self.weights: np.ndarray | None = None
        if protocol == "random":
            return
        if not metric_library:
            raise InputError("--scene-protocol hard needs --metric-library replay:DIR (a "
                             "library other than the source, for the metric)")
        if not source_spec.startswith("replay:") or not metric_library.startswith("replay:"):
            raise InputError("--scene-protocol hard: the source and --metric-library must be "
                             "replay:DIR folders")
        other = open_source(metric_library)
        shared = sorted(set(other.classes) & set(src.classes))
        if shared:
            raise InputError(f"--metric-library {metric_library}: shares classes {shared} with "
                             "the source; the metric must be fitted on other classes")
        if cfg is None:
            from tactex_ros.core.config import preset
            cfg = preset("default")
        self.weights = metric_weights(library_descriptors(other, cfg))
        self.means = {c: x.mean(axis=0) for c, x in library_descriptors(src, cfg).items()}

    def draw(self, seed: int) -> tuple[list[str], int]:
        """The scene of ``seed``: [reference, comparisons...] classes and the match (1..C)."""
        if self.protocol == "random":
            from tactex_ros.sources import trial_scene
            return trial_scene(self.src, self.comparisons, seed)
        return hard_scene(self.means, self.weights, self.comparisons, seed)
