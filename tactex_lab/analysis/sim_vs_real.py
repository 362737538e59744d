"""Sim-to-real report: do simulated presses look like, and rank learners like, real presses?

Two parts (``tactex sim compare``):

1. **Frame statistics per class family.** For real presses (first frame = no contact, the
   strongest-contact frame) and simulated presses (the same sensor without and with contact):
   the no-contact frame's mean and spatial std per RGB channel, the noise between two
   no-contact frames (mean |difference|), the contact difference's level (mean
   |contact - no contact| [grey levels]) and its spectrum (share of its power above
   0.1 cycles/px, and its shares in the bands 0-0.02, 0.02-0.05, 0.05-0.1 cycles/px). Real
   classes are grouped by how they press (``REAL_FAMILIES``: soft,
   firm textured, smooth), simulated fabrics by their softness (soft >= 0.5) and by
   construction family. Each shared group is compared as sim / real ratio with the 25 % target.
2. **Ranking agreement.** A set of learner settings (``DEFAULT_SETTINGS``, in the syntax of
   ``tactex experiment real``) runs through the real-press evaluation on simulated and on real
   scenes (``experiments.ranking.run_ranking``: scene draw, runner, belief after every touch);
   Spearman rho between the two rankings with a bootstrap interval
   (``analysis.stats.spearman_interval``) and the accuracy gap (real - sim).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import cv2
import numpy as np

from tactex_ros.core.errors import InputError

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

# Learner settings ranked on both sides, in ``tactex experiment real`` syntax
# (label=preset[:PATH=value,...], ``experiments/curves.parse_setting``): the shipped descriptor
# model and its levers (strategies, prior spread, the no-contact frame) and two CNN settings.
DEFAULT_SETTINGS: tuple[str, ...] = (
    "default=default",
    "random=default:trial.strategy=random",
    "variance=default:trial.strategy=variance",
    "entropy=default:trial.strategy=entropy",
    "yoto=default:trial.strategy=yoto",
    "no_contact_off=default:learner.descriptor_no_contact=false",
    "prior0.5=default:learner.match_prior_scale=0.5",
    "prior3=default:learner.match_prior_scale=3.0",
    "cnn=cnn",
    "cnn_random=cnn:trial.strategy=random",
)


BAND_EDGES = (0.0, 0.02, 0.05, 0.1)   # cycles/px: the bands below the high-frequency share


def _power(diff: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Power spectrum of the grey, mean-removed (H, W, 3) difference image and the radial
    frequency [cycles/px] of every bin."""
    g = diff.astype(np.float64).mean(axis=2)
    p = np.abs(np.fft.fft2(g - g.mean())) ** 2
    f = np.hypot(np.fft.fftfreq(g.shape[0])[:, None], np.fft.fftfreq(g.shape[1])[None, :])
    return p, f


def hf_share(diff: np.ndarray, cutoff: float = 0.1) -> float:
    """Share of the (grey, mean-removed) power of a (H, W, 3) difference image above
    ``cutoff`` cycles/px."""
    p, f = _power(diff)
    total = p.sum()
    return float(p[f > cutoff].sum() / total) if total > 0 else 0.0


def band_shares(diff: np.ndarray, edges: tuple[float, ...] = BAND_EDGES) -> np.ndarray:
    """Shares of the difference image's power in the radial bands [edges[i], edges[i + 1])
    cycles/px (with ``hf_share`` above the last edge they sum to 1)."""
    p, f = _power(diff)
    total = p.sum()
    if total <= 0:
        return np.zeros(len(edges) - 1)
    last = len(edges) - 2        # the last band includes its top edge (hf_share is above it)
    return np.array([p[(f >= a) & ((f < b) | ((f == b) & (i == last)))].sum()
                     for i, (a, b) in enumerate(zip(edges[:-1], edges[1:], strict=True))]) / total


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
            "hf_share": hf_share(d), "band_shares": band_shares(d)}


STAT_KEYS = ("no_contact_mean_rgb", "no_contact_std_rgb", "noise_mean_abs", "diff_mean_abs",
             "hf_share", "band_shares")


def summarise(stats: list[dict[str, Any]]) -> dict[str, Any]:
    """Mean of every statistic over presses (vectors per channel), and the count."""
    if not stats:
        return {"presses": 0}
    out: dict[str, Any] = {"presses": len(stats)}
    for k in STAT_KEYS:
        v = np.mean([np.asarray(s[k], dtype=float) for s in stats], axis=0)
        out[k] = np.round(v, 3).tolist() if np.ndim(v) else round(float(v), 4)
    return out


THUMB = (8, 6)                # (width, height) of the no-contact thumbnail [px]


def background_pattern(frame: np.ndarray) -> np.ndarray:
    """The no-contact frame's large-scale pattern: an 8x6 area-average thumbnail, each channel
    with its mean removed and divided by its spread -> (144,) float64 (brightness and contrast
    left out: they have their own statistics)."""
    t = cv2.resize(frame.astype(np.float32), THUMB, interpolation=cv2.INTER_AREA)
    t = t.astype(np.float64).reshape(-1, 3)
    sd = t.std(axis=0)
    return ((t - t.mean(axis=0)) / np.where(sd > 0, sd, 1.0)).ravel()


def _between_within(values: list[np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
    """Split of per-press vectors grouped by session: (between-session std, within-session
    std), per element. Between: std of the session means less the share the pooled within
    spread explains (method of moments, floored at 0). Within: the median over sessions of
    each session's std (robust: octopi-dev has a few presses recorded in another session, e.g.
    a class's 6th press, which would dominate a pooled std)."""
    means = np.array([v.mean(axis=0) for v in values])
    dof = sum(len(v) - 1 for v in values)
    pooled = sum(((v - v.mean(axis=0)) ** 2).sum(axis=0) for v in values) / dof
    n_h = len(values) / sum(1.0 / len(v) for v in values)     # harmonic mean of press counts
    between_var = np.maximum(means.var(axis=0, ddof=1) - pooled / n_h, 0.0)
    within = np.median(np.array([v.std(axis=0, ddof=1) for v in values]), axis=0)
    return np.sqrt(between_var), within


SESSION_KEYS = ("session_mean_between_rgb", "session_mean_within_rgb",
                "session_std_between_rgb", "session_std_within_rgb",
                "session_pattern_between", "session_pattern_within")


def session_stats(presses: list[Press]) -> dict[str, Any]:
    """How no-contact frames vary between recording sessions and within one.

    Presses are grouped by ``name`` (a real class was recorded in one session; a simulated
    fabric in recorded mode too); groups with fewer than 2 presses are left out. Per channel:
    between- and within-session std of the frame's mean [grey levels] and of its spatial
    std [grey levels]; of the thumbnail pattern (``background_pattern``): the RMS over its
    elements of the between- and within-session std [units of the channel spread]. Also
    ``identity_1nn``: share of presses whose nearest other no-contact frame (8x6 thumbnail,
    Euclidean) is of the same session, with the counts it depends on."""
    by: dict[str, list[Press]] = {}
    for p in presses:
        by.setdefault(p.name, []).append(p)
    groups = [g for g in by.values() if len(g) >= 2]
    if len(groups) < 2:
        return {"sessions": len(groups)}
    out: dict[str, Any] = {"sessions": len(groups),
                           "presses": sum(len(g) for g in groups)}
    frames = [[p.no_contact.astype(np.float32).reshape(-1, 3) for p in g] for g in groups]
    for key, fn in (("mean", lambda f: f.mean(axis=0)), ("std", lambda f: f.std(axis=0))):
        b, w = _between_within([np.array([fn(f) for f in fs]) for fs in frames])
        out[f"session_{key}_between_rgb"] = np.round(b.astype(float), 3).tolist()
        out[f"session_{key}_within_rgb"] = np.round(w.astype(float), 3).tolist()
    b, w = _between_within([np.array([background_pattern(p.no_contact) for p in g])
                            for g in groups])
    out["session_pattern_between"] = round(float(np.sqrt(np.mean(b ** 2))), 4)
    out["session_pattern_within"] = round(float(np.sqrt(np.mean(w ** 2))), 4)
    thumbs = np.array([cv2.resize(p.no_contact.astype(np.float32), THUMB,
                                  interpolation=cv2.INTER_AREA).ravel()
                       for g in groups for p in g], dtype=np.float64)
    label = np.repeat(np.arange(len(groups)), [len(g) for g in groups])
    d = ((thumbs[:, None, :] - thumbs[None, :, :]) ** 2).sum(-1)
    np.fill_diagonal(d, np.inf)
    out["identity_1nn"] = round(float((label[d.argmin(axis=1)] == label).mean()), 4)
    return out


def real_presses(real_dir: str, per_class: int) -> list[Press]:
    """The first ``per_class`` presses of every class of a replay folder (videos only)."""
    from tactex_ros.core.contact import strongest_contact
    from tactex_ros.sources.replay import ReplaySource, read_video
    rep = ReplaySource(real_dir)
    fam_of = {c: f for f, cs in REAL_FAMILIES.items() for c in cs}
    out = []
    for cls in rep.classes:
        for path in rep.presses(cls)[:per_class]:
            try:
                arr = read_video(path)[..., ::-1]            # BGR -> RGB
            except InputError:
                continue                                     # an image, not a press video
            if len(arr) < 3:
                continue
            idx, _ = strongest_contact(arr)
            fam = fam_of.get(cls, "other")
            out.append(Press(fam, fam, cls, np.ascontiguousarray(arr[0]),
                             np.ascontiguousarray(arr[1]), np.ascontiguousarray(arr[idx])))
    if not out:
        raise InputError(f"--real {real_dir}: no press videos found")
    return out


def sim_presses(per_class: int, seed: int, classes: list[str] | None = None) -> list[Press]:
    """``per_class`` simulated presses of every catalogue fabric (or of ``classes``), each
    fabric recorded in its own session as octopi-dev's classes were (``sim:recorded``)."""
    from tactex_ros.sources import open_source
    sim = open_source("sim:recorded")
    rng = np.random.default_rng([seed, 61])
    out = []
    for name in classes or sim.classes:
        fab = sim.fabric(name)          # an unknown name is an error naming it
        group = "soft" if fab.softness >= SOFT_THRESHOLD else "firm_textured"
        for _ in range(per_class):
            bg = sim.press_background(name, rng)
            out.append(Press(group, fab.family, name, sim.renderer.no_contact(rng, background=bg),
                             sim.renderer.no_contact(rng, background=bg),
                             sim.press(name, rng, background=bg)))
    return out


def first_presses(presses: list[Press], per_class: int) -> list[Press]:
    """The first ``per_class`` presses of every class (``name``), in order."""
    seen: dict[str, int] = {}
    out = []
    for p in presses:
        if seen.get(p.name, 0) < per_class:
            seen[p.name] = seen.get(p.name, 0) + 1
            out.append(p)
    return out


def frame_report(real: list[Press], sim: list[Press],
                 real_sessions: list[Press] | None = None) -> dict[str, Any]:
    """Statistics per group and family on both sides, and sim / real ratios per shared group;
    the session statistics (``session_stats``) of ``real_sessions`` (default ``real``: every
    press of a class helps there) against ``sim``'s, as group ``sessions``."""
    out = _group_report(real, sim)
    rs, ss = session_stats(real_sessions or real), session_stats(sim)
    out["real"]["sessions"], out["sim"]["sessions"] = rs, ss
    if rs.get("sessions", 0) >= 2 and ss.get("sessions", 0) >= 2:
        for k in SESSION_KEYS:
            out["checks"].append(_check("sessions", k, rs[k], ss[k]))
    out["checks_passed"] = sum(c["within_25pct"] for c in out["checks"])
    return out


def _check(group: str, key: str, real: Any, sim: Any) -> dict[str, Any]:
    rv, sv = np.atleast_1d(real).astype(float), np.atleast_1d(sim).astype(float)
    ratio = sv / np.where(rv == 0, np.nan, rv)
    ok = bool(np.all(np.abs(ratio - 1) <= TARGET_REL))
    return {"group": group, "statistic": key, "real": real, "sim": sim,
            "ratio": np.round(ratio, 3).tolist(), "within_25pct": ok}


def _group_report(real: list[Press], sim: list[Press]) -> dict[str, Any]:
    rs, ss = [press_stats(p) for p in real], [press_stats(p) for p in sim]
    out: dict[str, Any] = {"real": {"all": summarise(rs)}, "sim": {"all": summarise(ss)}}
    for side, presses, stats in (("real", real, rs), ("sim", sim, ss)):
        for key in ("group", "family"):
            for g in sorted({getattr(p, key) for p in presses}):
                out[side].setdefault(g, summarise(
                    [s for p, s in zip(presses, stats, strict=True) if getattr(p, key) == g]))
    checks = []
    for g in ("all", "soft", "firm_textured"):
        r, s = out["real"].get(g), out["sim"].get(g)
        if not r or not s or not r["presses"] or not s["presses"]:
            continue
        for k in STAT_KEYS:
            checks.append(_check(g, k, r[k], s[k]))
    out["checks"] = checks
    return out
