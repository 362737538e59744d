"""The belief's temperature calibrated on a library of presses with classes left out.

A temperature chosen on one family of materials need not hold on another (issue 23: the stop at
0.9 made 2.5 % wrong stops on held-out objects and 9.2 % on fabrics). ``tactex prepare`` therefore
calibrates it on the lab's own library, on classes the representation did not see:

1. the library's classes are split into ``folds`` (seeded); for every fold the representation
   is fitted on the other folds' classes (``fit_rep``) and ``scenes`` trials of 1 reference +
   ``comparisons`` platforms are run on the fold's classes, through the trial engine itself
   (``TrialEngine``, strategy ``infogain``, no stop rule, ``budget`` touches after the
   baseline), each press given by its known descriptor (``Touch.descriptor``);
2. at every decision the untempered log evidence l (``MatchModel.log_evidence``) and the true
   match are kept (``Trajectory``);
3. ``fit_temperature`` picks beta for belief = softmax(beta l): ``nll`` minimises the negative
   log-likelihood of the true match over all decisions; ``stop`` takes the largest beta (log grid, ascending)
   up to which the wrong-stop rate (the trial's first decision with belief >= theta is wrong)
   stays at most 1 - theta at every theta of ``thetas`` on these left-out trials; ``target``
   the largest up to which the wrong-stop rate at the trial's own threshold stays at most a
   chosen rate (e.g. 3 % at 0.9: the issue's target, not 1 - theta).

The policy's touches depend on the temperature the trajectories were run with (``temperature0``);
the fitted beta is applied to the recorded evidence, not re-run (one pass; ``prepare`` documents
it).
"""

from __future__ import annotations

from dataclasses import dataclass
from collections.abc import Callable

import numpy as np

from .config import DescriptorSettings, TrialConfig
from .errors import InputError
from .match import softmax
from .representation import Representation
from .touch import Touch

#: A valid (non-constant) sensor-sized frame for touches whose descriptor is given; it is never
#: described.
PLACEHOLDER_FRAME = np.random.default_rng(0).integers(0, 256, (240, 320, 3), dtype=np.uint8)


@dataclass
class Trajectory:
    """One left-out trial: (steps, C) untempered log evidence after every decision, the true
    match (0..C-1), the touches after the baseline at every decision (steps,), and the two best
    comparisons' separation at every decision (steps,; ``MatchModel.separation``, the stop's
    "not sure" rule)."""

    evidence: np.ndarray
    truth: int
    extra: np.ndarray
    separation: np.ndarray | None = None


def class_split(classes: list[str], folds: int, seed: int) -> list[list[str]]:
    """``classes`` shuffled (seeded) into ``folds`` groups of near-equal size."""
    order = [classes[i] for i in np.random.default_rng([seed, 41]).permutation(len(classes))]
    return [sorted(order[i::folds]) for i in range(folds)]


def _scene(classes: list[str], presses: dict[str, np.ndarray], comparisons: int,
           rng: np.random.Generator) -> tuple[list[str], int, Callable[[int], Touch]]:
    """Classes [reference, comparisons...], the true match (1..C) and a touch function that
    draws each platform's presses in a seeded order, the reference's presses kept from the
    matching comparison while others remain."""
    comps = [classes[i] for i in rng.choice(len(classes), comparisons, replace=False)]
    truth = int(rng.integers(comparisons))
    plat = [comps[truth]] + comps
    order = {c: list(rng.permutation(len(presses[c]))) for c in sorted(set(plat))}
    used: dict[str, list[int]] = {c: [] for c in order}
    ref_used: set[int] = set()

    def touch(p: int) -> Touch:          # the draw of sources/replay.py's ReplayTrial
        c = plat[p]
        fresh = [i for i in order[c] if i not in used[c]]
        if p != 0:
            fresh = [i for i in fresh if i not in ref_used]
        if not fresh:
            pool = [i for i in order[c] if i not in ref_used] or order[c]
            fresh = sorted(pool, key=lambda i: used[c].count(i))[:1]
        i = fresh[0]
        used[c].append(i)
        if p == 0:
            ref_used.add(i)
        return Touch(PLACEHOLDER_FRAME, None, None, presses[c][i])

    return plat, truth + 1, touch


def trajectories(presses: dict[str, np.ndarray],
                 fit_rep: Callable[[dict], Representation] | None,
                 cfg: DescriptorSettings, folds: int = 3, scenes: int = 40, comparisons: int = 4,
                 budget: int = 10, temperature0: float | None = None,
                 seed: int = 0) -> list[Trajectory]:
    """Left-out trials on the library ``{class: (n, D) descriptors}`` (see the module
    docstring). ``temperature0``: the temperature the trials run with (default: the
    representation's, else ``cfg.match_temperature`` scaled by D / k: the log evidence sums
    over the k dimensions). ``fit_rep`` None: the descriptors as given, no representation (the
    shipped default; its temperature ``cfg.match_temperature``)."""
    from .engine import TrialSpec
    classes = sorted(c for c, x in presses.items() if len(x) >= 2)
    if folds < 2:
        raise InputError(f"calibration needs >= 2 class folds, got {folds}")
    groups = class_split(classes, folds, seed)
    if min(len(g) for g in groups) < comparisons:
        raise InputError(f"calibration: {len(classes)} library classes with >= 2 presses "
                          f"cannot fill {folds} folds of >= {comparisons} classes; give a "
                          "larger library or fewer --calibration-folds")
    cfg = cfg.replace(model="descriptor", representation="", guards=False)
    tcfg = TrialConfig(strategy="infogain", rounds=budget, stop_confidence=0.0)
    out: list[Trajectory] = []
    for k, held in enumerate(groups):
        rep = None if fit_rep is None else fit_rep({c: presses[c] for c in classes
                                                    if c not in held})
        beta = temperature0 or (cfg.match_temperature if rep is None
                                else rep.temperature if np.isfinite(rep.temperature)
                                else cfg.match_temperature * rep.mean.size / rep.dims)
        rng = np.random.default_rng([seed, 53, k])
        for s in range(scenes):
            plat, truth, touch = _scene(held, presses, comparisons, rng)
            eng = TrialSpec(comparisons, cfg, tcfg, seed=seed * 1000 + s, representation=rep,
                            temperature=float(beta)).engine()
            ev: list[np.ndarray] = []
            extra: list[int] = []
            sep: list[float] = []

            def keep(rec, eng=eng, ev=ev, extra=extra, sep=sep) -> None:
                ev.append(eng.learner.match.log_evidence())
                extra.append(eng.total_touches - (comparisons + 1))
                sep.append(eng.learner.match.separation())

            eng.run(touch, truth=truth, on_round=keep)        # keep reads its learner
            out.append(Trajectory(np.stack(ev), truth - 1, np.array(extra), np.array(sep)))
    return out


def _decisions(trajs: list[Trajectory]) -> tuple[np.ndarray, np.ndarray]:
    ev = np.concatenate([t.evidence for t in trajs])
    y = np.concatenate([np.full(len(t.evidence), t.truth) for t in trajs])
    return ev, y


def nll(trajs: list[Trajectory], beta: float) -> float:
    """Mean negative log-likelihood of the true match over every decision at temperature beta."""
    ev, y = _decisions(trajs)
    p = softmax(beta * ev)[np.arange(len(y)), y]
    return float(-np.mean(np.log(np.clip(p, 1e-300, 1.0))))


def _padded(trajs: list[Trajectory]) -> tuple[np.ndarray, np.ndarray]:
    """(N, S, C) evidence, shorter trajectories padded with their last decision (which cannot
    move a first crossing), and the (N,) truths."""
    s = max(len(t.evidence) for t in trajs)
    ev = np.stack([np.concatenate([t.evidence, np.repeat(t.evidence[-1:], s - len(t.evidence),
                                                         axis=0)]) for t in trajs])
    return ev, np.array([t.truth for t in trajs])


def wrong_stop_rate(trajs: list[Trajectory], beta: float, theta: float) -> float:
    """Share of trajectories whose first decision with belief >= theta predicts wrong."""
    ev, y = _padded(trajs)
    b = softmax(beta * ev)                                    # (N, S, C)
    hit = b.max(axis=2) >= theta                              # (N, S)
    first = np.argmax(hit, axis=1)
    stopped = hit.any(axis=1)
    pred = np.argmax(b[np.arange(len(y)), first], axis=1)
    return float(np.sum(stopped & (pred != y)) / max(1, len(trajs)))


def ece(trajs: list[Trajectory], beta: float, bins: int = 10) -> float:
    """Expected calibration error of the top belief over every decision (equal-width bins)."""
    ev, y = _decisions(trajs)
    b = softmax(beta * ev)
    return ece_of(b.max(axis=1), b.argmax(axis=1) == y, bins)


def ece_of(conf: np.ndarray, correct: np.ndarray, bins: int = 10) -> float:
    """Expected calibration error of (n,) confidences against (n,) right/wrong (equal-width
    bins; nan for n = 0)."""
    conf = np.asarray(conf, dtype=np.float64)
    ok = np.asarray(correct, dtype=np.float64)
    if conf.size == 0:
        return float("nan")
    idx = np.minimum((conf * bins).astype(int), bins - 1)
    return float(sum(abs(conf[idx == i].mean() - ok[idx == i].mean()) * np.sum(idx == i)
                     for i in range(bins) if np.any(idx == i)) / len(conf))


#: Temperatures tried (log grid); the belief's temperature lies far inside it in practice.
GRID = np.geomspace(1e-4, 10.0, 241)


def fit_temperature(trajs: list[Trajectory], method: str = "stop",
                    thetas: tuple[float, ...] = (0.8, 0.9, 0.95),
                    max_wrong: float | None = None) -> float:
    """beta for belief = softmax(beta l) on left-out trajectories (module docstring).
    ``target``: as ``stop`` but the wrong-stop rate at every theta of ``thetas`` must stay at
    most ``max_wrong`` (e.g. 0.03 at the trial's stop threshold 0.9) instead of 1 - theta."""
    if not trajs:
        raise InputError("no calibration trajectories")
    if method == "nll":
        return float(GRID[int(np.argmin([nll(trajs, b) for b in GRID]))])
    if method in ("stop", "target"):
        if method == "target" and not (max_wrong is not None and 0.0 <= max_wrong < 1.0):
            raise InputError(f"calibration target needs a wrong-stop rate in [0, 1), got "
                              f"{max_wrong}")
        best = None
        for b in GRID:                      # ascending: stop at the first violation
            if any(wrong_stop_rate(trajs, b, th) >
                   (1.0 - th if method == "stop" else max_wrong) + 1e-12 for th in thetas):
                break
            best = b
        if best is None:
            raise InputError("calibration: no temperature keeps the wrong stops within "
                              f"1 - theta for thetas {thetas}")
        return float(best)
    raise InputError(f"calibration method {method!r}: one of nll, stop, target")


def fit_temperature_families(families: list[list[Trajectory]], method: str = "stop",
                             thetas: tuple[float, ...] = (0.8, 0.9, 0.95),
                             max_wrong: float | None = None) -> float:
    """The largest beta that meets ``fit_temperature``'s criterion on *every* family's
    left-out trajectories separately (the worst family decides), not on their pool: the
    smallest of the per-family temperatures (the grid walk stops at the first violation, so
    this is the walk over all families at once). ``nll``: not a per-family criterion."""
    if method == "nll" or not families:
        raise InputError(f"per-family calibration: method stop or target and >= 1 family, got "
                          f"{method!r} and {len(families)}")
    return min(fit_temperature(t, method, thetas, max_wrong) for t in families)


def report(trajs: list[Trajectory], beta: float,
           thetas: tuple[float, ...] = (0.8, 0.9, 0.95, 0.98)) -> dict:
    """What the calibration measured at ``beta``: trials, decisions, NLL, ECE and the wrong-stop
    rate per theta on the left-out trajectories."""
    return {"trials": len(trajs), "decisions": int(sum(len(t.evidence) for t in trajs)),
            "temperature": float(beta), "nll": nll(trajs, beta), "ece": ece(trajs, beta),
            "wrong_stop": {str(th): wrong_stop_rate(trajs, beta, th) for th in thetas}}
