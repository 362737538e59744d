"""Sim-to-real report: do simulated presses look like, and rank learners like, real presses?

Two parts (``tactex sim compare``):

1. **Frame statistics per class family.** For real presses (first frame = no contact, the
   strongest-contact frame) and simulated presses (the same sensor without and with contact):
   the no-contact frame's mean and spatial std per RGB channel, the noise between two
   no-contact frames (mean |difference|), the contact difference's level (mean
   |contact - no contact| [grey levels]) and its spectrum (share of its power above
   0.1 cycles/px). Real classes are grouped by how they press (``REAL_FAMILIES``: soft,
   firm textured, smooth), simulated fabrics by their softness (soft >= 0.5) and by
   construction family. Each shared group is compared as sim / real ratio with the 25 % target.
2. **Ranking agreement.** A set of learner settings (``LearnerConfig`` overrides of the CNN
   preset ``cnn``, ``SETTINGS``) runs the same kind of scene on both sides: 1 reference +
   C comparisons of distinct classes (catalogue fabrics / real classes), seeded, the same
   scenes for every setting. Per setting: accuracy on simulated scenes and on real scenes;
   Spearman rho between the two rankings with a bootstrap interval (scenes resampled, paired
   across settings) and the accuracy gap (real - sim).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from ..core.errors import TactexError

# How octopi-dev's classes press (by looking at the objects, not at their frames).
REAL_FAMILIES: dict[str, tuple[str, ...]] = {
    "soft": ("cotton_ball", "feather_duster", "plush_ball", "sponge", "sponge_soft", "tissue",
             "toilet_paper", "paper_towel"),
    "firm_textured": ("basket", "wires", "strainer_head", "hairbrush_bristles",
                      "toothbrush_bristles", "steel_wool", "millet", "rice", "bubble_wrap",
                      "sponge_rough"),
    "smooth": ("aluminium_foil", "eraser", "leather_book", "leatherback_book", "masking_tape",
               "rubber_slippers", "wood_ruler", "tennis_ball"),
}
SOFT_THRESHOLD = 0.5          # simulated fabrics with softness >= this form the "soft" group
TARGET_REL = 0.25             # every statistic within 25 % of the real value

# Learner settings ranked on both sides: overrides of preset "cnn" (48 px, 8 steps, lr 3e-3,
# batch 32, dropout 0.5, 10 rotations per touch).
SETTINGS: dict[str, dict[str, Any]] = {
    "cnn": {},
    "input32": {"input_size": 32},
    "input96": {"input_size": 96},
    "steps4": {"steps": 4},
    "steps16": {"steps": 16},
    "lr1e-3": {"lr": 1e-3},
    "lr1e-2": {"lr": 1e-2},
    "batch8": {"batch_size": 8},
    "dropout0.2": {"dropout": 0.2},
    "augment3": {"augment": 3},
    "fourier": {"fourier": True},
}


def hf_share(diff: np.ndarray, cutoff: float = 0.1) -> float:
    """Share of the (grey, mean-removed) power of a (H, W, 3) difference image above
    ``cutoff`` cycles/px."""
    g = diff.astype(np.float64).mean(axis=2)
    p = np.abs(np.fft.fft2(g - g.mean())) ** 2
    fy = np.fft.fftfreq(g.shape[0])[:, None]
    fx = np.fft.fftfreq(g.shape[1])[None, :]
    total = p.sum()
    return float(p[np.hypot(fx, fy) > cutoff].sum() / total) if total > 0 else 0.0


@dataclass
class Press:
    """One press for the statistics: no-contact frame, a second no-contact frame (noise),
    strongest contact; all (240, 320, 3) uint8 RGB."""

    group: str
    family: str
    name: str
    no_contact: np.ndarray
    no_contact2: np.ndarray
    contact: np.ndarray


def press_stats(p: Press) -> dict[str, Any]:
    nc = p.no_contact.astype(np.float32)
    d = p.contact.astype(np.float32) - nc
    return {"no_contact_mean_rgb": nc.reshape(-1, 3).mean(0),
            "no_contact_std_rgb": nc.reshape(-1, 3).std(0),
            "noise_mean_abs": float(np.abs(p.no_contact2.astype(np.float32) - nc).mean()),
            "diff_mean_abs": float(np.abs(d).mean()),
            "hf_share": hf_share(d)}


STAT_KEYS = ("no_contact_mean_rgb", "no_contact_std_rgb", "noise_mean_abs", "diff_mean_abs",
             "hf_share")


def summarise(stats: list[dict[str, Any]]) -> dict[str, Any]:
    """Mean of every statistic over presses (vectors per channel), and the count."""
    if not stats:
        return {"presses": 0}
    out: dict[str, Any] = {"presses": len(stats)}
    for k in STAT_KEYS:
        v = np.mean([np.asarray(s[k], dtype=float) for s in stats], axis=0)
        out[k] = np.round(v, 3).tolist() if np.ndim(v) else round(float(v), 4)
    return out


def real_presses(real_dir: str, per_class: int) -> list[Press]:
    """The first ``per_class`` presses of every class of a replay folder (videos only)."""
    from ..core.contact import strongest_contact
    from ..sources.replay import ReplaySource, read_video
    rep = ReplaySource(real_dir)
    fam_of = {c: f for f, cs in REAL_FAMILIES.items() for c in cs}
    out = []
    for cls in rep.classes:
        for path in rep.presses(cls)[:per_class]:
            try:
                arr = read_video(path)[..., ::-1]            # BGR -> RGB
            except TactexError:
                continue                                     # an image, not a press video
            if len(arr) < 3:
                continue
            idx, _ = strongest_contact(arr)
            fam = fam_of.get(cls, "other")
            out.append(Press(fam, fam, cls, np.ascontiguousarray(arr[0]),
                             np.ascontiguousarray(arr[1]), np.ascontiguousarray(arr[idx])))
    if not out:
        raise TactexError(f"--real {real_dir}: no press videos found")
    return out


def sim_presses(per_class: int, seed: int, classes: list[str] | None = None) -> list[Press]:
    """``per_class`` simulated presses of every catalogue fabric (or of ``classes``)."""
    from .source import SimSource
    sim = SimSource()
    rng = np.random.default_rng([seed, 61])
    out = []
    for name in classes or sim.classes:
        fab = sim.fabric(name)
        group = "soft" if fab.softness >= SOFT_THRESHOLD else "firm_textured"
        for _ in range(per_class):
            out.append(Press(group, fab.family, name, sim.renderer.no_contact(rng),
                             sim.renderer.no_contact(rng), sim.press(name, rng)))
    return out


def frame_report(real: list[Press], sim: list[Press]) -> dict[str, Any]:
    """Statistics per group and family on both sides, and sim / real ratios per shared group."""
    rs, ss = [press_stats(p) for p in real], [press_stats(p) for p in sim]
    out: dict[str, Any] = {"real": {"all": summarise(rs)}, "sim": {"all": summarise(ss)}}
    for side, presses, stats in (("real", real, rs), ("sim", sim, ss)):
        for key in ("group", "family"):
            for g in sorted({getattr(p, key) for p in presses}):
                out[side].setdefault(g, summarise(
                    [s for p, s in zip(presses, stats) if getattr(p, key) == g]))
    checks = []
    for g in ("all", "soft", "firm_textured"):
        r, s = out["real"].get(g), out["sim"].get(g)
        if not r or not s or not r["presses"] or not s["presses"]:
            continue
        for k in STAT_KEYS:
            rv, sv = np.atleast_1d(r[k]).astype(float), np.atleast_1d(s[k]).astype(float)
            ratio = sv / np.where(rv == 0, np.nan, rv)
            ok = bool(np.all(np.abs(ratio - 1) <= TARGET_REL))
            checks.append({"group": g, "statistic": k, "real": r[k], "sim": s[k],
                           "ratio": np.round(ratio, 3).tolist(), "within_25pct": ok})
    out["checks"] = checks
    out["checks_passed"] = sum(c["within_25pct"] for c in checks)
    return out


# ------------------------------------------------------------------------------ ranking

def scene_classes(classes: list[str], comparisons: int, seed: int) -> list[str]:
    """[reference, comparison 1..C]: C distinct classes, the reference one of them."""
    if len(classes) < comparisons:
        raise TactexError(f"--comparisons {comparisons}: only {len(classes)} classes")
    rng = np.random.default_rng([seed, 71])
    comps = [str(c) for c in rng.choice(classes, comparisons, replace=False)]
    return [comps[int(rng.integers(comparisons))]] + comps


def spearman(a: np.ndarray, b: np.ndarray) -> float:
    """Spearman's rho (average ranks for ties); nan if either side is constant."""
    from scipy.stats import rankdata
    ra, rb = rankdata(a), rankdata(b)
    if np.std(ra) == 0 or np.std(rb) == 0:
        return float("nan")
    return float(np.corrcoef(ra, rb)[0, 1])


def ranking_report(sim_correct: np.ndarray, real_correct: np.ndarray, names: list[str],
                   sim_p: np.ndarray | None = None, real_p: np.ndarray | None = None,
                   boot: int = 2000, seed: int = 0) -> dict[str, Any]:
    """``*_correct``: (settings, scenes) 0/1 per trial (same scenes for every setting);
    ``*_p``: the same trials' final probability of the true match (a finer score).
    Spearman rho of accuracy (and of mean true-match probability) with a bootstrap 95 %
    interval (scenes resampled on each side, paired across settings) and the gaps."""
    sim_correct, real_correct = np.asarray(sim_correct, float), np.asarray(real_correct, float)
    if sim_correct.shape[0] != len(names) or real_correct.shape[0] != len(names):
        raise TactexError("one row of trial outcomes per setting expected")
    rng = np.random.default_rng([seed, 73])

    def rho_ci(a: np.ndarray, b: np.ndarray) -> dict[str, Any]:
        point = spearman(a.mean(1), b.mean(1))
        draws = []
        for _ in range(boot):
            ia = rng.integers(0, a.shape[1], a.shape[1])
            ib = rng.integers(0, b.shape[1], b.shape[1])
            r = spearman(a[:, ia].mean(1), b[:, ib].mean(1))
            if np.isfinite(r):
                draws.append(r)
        lo, hi = (np.percentile(draws, [2.5, 97.5]).tolist() if draws
                  else [float("nan"), float("nan")])
        return {"rho": point, "ci95": [lo, hi], "bootstrap_draws_defined": len(draws)}

    acc_s, acc_r = sim_correct.mean(1), real_correct.mean(1)
    out: dict[str, Any] = {
        "settings": {n: {"sim_accuracy": float(a), "real_accuracy": float(b),
                         "gap_real_minus_sim": float(b - a)}
                     for n, a, b in zip(names, acc_s, acc_r)},
        "accuracy_spearman": rho_ci(sim_correct, real_correct),
        "mean_gap_real_minus_sim": float(np.mean(acc_r - acc_s)),
        "mean_abs_gap": float(np.mean(np.abs(acc_r - acc_s))),
        "sim_scenes": int(sim_correct.shape[1]), "real_scenes": int(real_correct.shape[1]),
        "n_settings": len(names),
    }
    if sim_p is not None and real_p is not None:
        out["true_match_probability_spearman"] = rho_ci(np.asarray(sim_p, float),
                                                        np.asarray(real_p, float))
    return out


def run_ranking(real_dir: str, settings: dict[str, dict[str, Any]], scenes: int,
                comparisons: int, rounds: int, strategy: str, seed: int, workers: int,
                quiet: bool = False) -> dict[str, Any]:
    """Run every setting on the same ``scenes`` simulated and real scenes; see
    ``ranking_report``."""
    from ..experiments.runner import TrialJob, run_jobs
    from ..sources.replay import ReplaySource
    from .source import SimSource
    if scenes < 1:
        raise TactexError(f"--scenes must be >= 1, got {scenes}")
    if len(settings) < 2:
        raise TactexError("the ranking needs at least 2 settings")
    sides = {"sim": ("sim", SimSource().classes),
             "real": (f"replay:{real_dir}", ReplaySource(real_dir).classes)}
    jobs, keys = [], []
    for side, (spec, classes) in sides.items():
        for k in range(scenes):
            pcs = scene_classes(classes, comparisons, seed + k)
            for name, over in settings.items():
                jobs.append(TrialJob(source=spec, seed=seed + k, strategy=strategy,
                                     rounds=rounds, preset="cnn", overrides=dict(over),
                                     platform_classes=pcs, comparisons=comparisons,
                                     trial_id=f"{side}-{name}-{k}", catch_errors=True))
                keys.append((side, name, k))
    results = run_jobs(jobs, workers=workers, description="sim vs real trials", quiet=quiet)
    names = list(settings)
    corr = {s: np.zeros((len(names), scenes)) for s in sides}
    prob = {s: np.zeros((len(names), scenes)) for s in sides}
    errors = []
    for (side, name, k), res in zip(keys, results):
        i = names.index(name)
        if res.get("error"):
            errors.append(f"{side}/{name}/{k}: {res['error']}")
            continue
        corr[side][i, k] = float(bool(res["correct"]))
        probs = np.asarray(res["final"]["probs"], float)
        prob[side][i, k] = float(probs[res["truth_index"] - 1])
    rep = ranking_report(corr["sim"], corr["real"], names, prob["sim"], prob["real"],
                         seed=seed)
    rep.update(comparisons=comparisons, rounds=rounds, strategy=strategy, preset="cnn",
               overrides=settings, failed_trials=errors,
               trial_wall_s=float(sum(r.get("wall_s", 0.0) for r in results)))
    return rep
