"""``tactex experiment library``: the learning curve of a robot that files every touched press
under its fabric's name (``core/library.py``; docs/research/fabric_library.md).

A replayed study session: 32 trials (the thesis's count), each a 1 + 4 scene drawn as a study
places fabrics: 4 distinct classes of the replay library, uniformly, the reference one of them
(seeded by the session's seed), so fabrics come back across the session. The fabric library
starts empty; after each trial, every press video it touched joins the library under its class
name. Every trial is run twice on the same touches, learning off (today's scene-only belief)
and on (the belief asks the library): the policy (infogain) does not depend on the library or
on the stop threshold, so both runs touch the same presses, and the stop rule is applied
offline to the belief after every decision (``curves.at_stop``), exactly as a live stop.

Presses: each press video is described once (``press_cache``, under /tmp); a trial draws its
presses as ``ReplayTrial`` does (seeded permutation of the class's videos, the reference's videos
kept from its comparison when there are enough). A trial is never helped by the very press
video it touches: before every decision the library the belief sees leaves out every video the
trial has touched so far.
"""

from __future__ import annotations

import argparse
from pathlib import Path
from collections.abc import Callable

import numpy as np

from tactex_ros.core.config import SHIPPED_STOP, TrialConfig, preset
from tactex_ros.core.errors import InputError
from tactex_ros.core import texture
from tactex_ros.core.library import EVIDENCE_WEIGHT, FabricLibrary
from tactex_lab.analysis import charts
from tactex_lab.analysis.stats import mcnemar_exact, wilcoxon_paired, wilson
from tactex_lab.experiments.common import results_dir, write_json
from tactex_lab.experiments.curves import BeliefCurve, at_stop, curve
from tactex_lab.experiments.press_cache import (FEATURES, CachedPresses,
                                                add_contact_verdicts, build_cache, load_cache)

def arm_names(weights: list[float]) -> list[str]:
    """'off' (today's belief) and one learning arm per evidence weight: 'on' for the shipped
    weight, 'on_w<weight>' for another."""
    return ["off"] + ["on" if w == EVIDENCE_WEIGHT else f"on_w{w:g}" for w in weights]


def study_scenes(classes: list[str], trials: int, comparisons: int, seed: int
                 ) -> list[list[str]]:
    """``trials`` scenes [reference, comparisons...]: distinct classes drawn uniformly, the
    reference one of the comparisons."""
    rng = np.random.default_rng([seed, 33])
    out = []
    for _ in range(trials):
        comps = [classes[i] for i in rng.choice(len(classes), comparisons, replace=False)]
        out.append([comps[int(rng.integers(comparisons))]] + comps)
    return out


#: ``--learner``: the shipped default (descriptor, height map and the sim embedding, each press
#: described by the product's own ``raw_descriptor``) or the earlier study's 106-number
#: strongest-frame descriptor without height map or embedding (``press_cache`` "frame").
LEARNERS = ("shipped", "descriptor")


def learner_cfg(learner: str, dim: int, library: bool):
    """The learner settings a trial of ``--learner`` runs with (contact guards off: the cache
    marks refused presses itself), for cached descriptors of size ``dim``."""
    if learner == "shipped":
        return preset("default", guards=False, fabric_library=library)
    if learner == "descriptor":
        return preset("descriptor", guards=False, fabric_library=library,
                      descriptor_height_map=dim != texture.DIM)
    raise InputError(f"--learner must be one of {', '.join(LEARNERS)}, got {learner!r}")


def shipped_features(cache: dict[str, np.ndarray], root: str | Path, cache_dir: str | Path
                     ) -> np.ndarray:
    """(n, D) every cached press described as the shipped default learner describes a touch
    (``core.descriptor.raw_descriptor``, D = ``descriptor_size``), in the cache's row order;
    kept in ``<cache_dir>/<folder>_shipped.npz`` with the paths it was made from."""
    from tactex_ros.core.descriptor import raw_descriptor
    from tactex_ros.sources.replay import ReplaySource
    path = Path(cache_dir) / f"{Path(root).name}_shipped.npz"
    paths = cache["path"].astype(str)
    if path.is_file():
        with np.load(path) as z:
            if z["path"].astype(str).tolist() == paths.tolist():
                return z["x"]
    print(f"describing every press of {root} with the shipped learner -> {path}", flush=True)
    cfg = preset("default")
    src = ReplaySource(root)
    x = np.stack([raw_descriptor(src.touch(Path(p)), cfg) for p in paths])
    np.savez(path, x=x, path=paths)
    return x


def run_trial_arm(x: np.ndarray, cls: np.ndarray, scene: list[str], seed: int, budget: int,
                  library: FabricLibrary | None, weight: float = EVIDENCE_WEIGHT,
                  rejected: np.ndarray | None = None, learner: str = "shipped"
                  ) -> tuple[BeliefCurve, list[tuple[int, str]]]:
    """One trial on the cached presses (no stop rule, ``budget`` touches after the baseline):
    its belief curve and the (platform, press row) it touched (a ``rejected`` press included:
    it failed and was pressed again, ``CachedPresses``). With ``library`` the belief asks it,
    less the videos touched so far. ``x`` holds the descriptors ``learner`` makes."""
    from tactex_ros.core.engine import TrialSpec
    from tactex_ros.sources.replay import ReplayTrial
    cfg = learner_cfg(learner, x.shape[1], library is not None)
    spec = TrialSpec(len(scene) - 1, cfg, TrialConfig(strategy="infogain", rounds=budget,
                                                      stop_confidence=0.0),
                     seed=seed, library=library)
    eng = spec.engine()
    replay = ReplayTrial(CachedPresses(x, cls, rejected), scene, seed)
    touched: set[str] = set()

    def touch(platform: int):
        t = replay(platform)
        video = replay.log[-1][1]
        if library is not None and video not in touched:
            touched.add(video)
            eng.learner.use_library(library.without(touched), weight)
        return t

    truth = scene[1:].index(scene[0]) + 1
    res = eng.run(touch, truth=truth)     # the touches leave their own videos out of its library
    return curve(res.rounds + [res.final], truth), list(replay.log)


def run_session(x: np.ndarray, cls: np.ndarray, seed: int, args: argparse.Namespace,
                log: Callable[[str], None] = print, rejected: np.ndarray | None = None
                ) -> list[dict]:
    """One replayed session of ``args.trials`` trials, learning off and on with each of
    ``args.weights`` (paired: the same touches). A ``rejected`` press (the contact guard's)
    fails when touched and never joins the library, as a refused touch on the robot."""
    classes = sorted(set(cls.tolist()))
    lib = FabricLibrary()
    rows = []
    for t, scene in enumerate(study_scenes(classes, args.trials, args.comparisons, seed)):
        known = set(lib.fabrics)
        row = {"session_seed": seed, "trial": t + 1, "scene": scene,
               "reference_known": scene[0] in known,
               "platforms_known": sum(c in known for c in scene[1:]),
               "library": lib.state()}
        logs = {}
        for arm, w in zip(arm_names(args.weights), [None] + list(args.weights), strict=True):
            c, logs[arm] = run_trial_arm(x, cls, scene, seed * 1000 + t, args.budget,
                                         None if w is None else lib, w or EVIDENCE_WEIGHT,
                                         rejected, args.learner)
            ok, extra, sure = at_stop(c, args.stop)
            row[arm] = {"correct": bool(ok), "touches_after_baseline": int(extra),
                        "stopped": bool(sure), "wrong_stop": bool(sure and not ok),
                        "final_correct": bool(c.correct[-1])}
        if any(v != logs["off"] for v in logs.values()):
            raise RuntimeError(f"trial {t + 1}: the arms touched different presses")
        for platform, video in logs["off"]:
            if rejected is None or not rejected[int(video)]:
                lib = lib.add(scene[platform], x[int(video)], [video])
        rows.append(row)
        log(f"seed {seed} trial {t + 1:2d} ref known {row['reference_known']!s:5} "
            + "  ".join(f"{a} {row[a]['correct']!s:5} {row[a]['touches_after_baseline']:2d}"
                        for a in logs) + "  "
            f"library {lib.presses} presses / {len(lib.fabrics)} fabrics")
    return rows


def summarise(rows: list[dict], blocks: int, arms: list[str]) -> dict:
    """Per arm and subset (all, reference new, reference seen before): accuracy (Wilson 95 %),
    mean touches after the baseline, wrong stops; paired McNemar (correct) and Wilcoxon
    (touches) of every learning arm against off; and the learning curve over blocks of trial
    positions."""
    def stats(sub: list[dict]) -> dict:
        out: dict = {"n": len(sub)}
        for arm in arms:
            k = sum(r[arm]["correct"] for r in sub)
            w = sum(r[arm]["wrong_stop"] for r in sub)
            out[arm] = {"accuracy": k / len(sub) if sub else float("nan"),
                        "accuracy_ci95": wilson(k, len(sub)),
                        "touches_mean": float(np.mean([r[arm]["touches_after_baseline"]
                                                       for r in sub])) if sub else float("nan"),
                        "wrong_stops": w, "wrong_stop_rate": w / len(sub) if sub else
                        float("nan"), "wrong_stop_ci95": wilson(w, len(sub))}
        for arm in arms[1:] if sub else []:
            out[arm]["mcnemar_vs_off"] = mcnemar_exact([r[arm]["correct"] for r in sub],
                                                       [r["off"]["correct"] for r in sub])
            out[arm]["wilcoxon_touches_vs_off"] = wilcoxon_paired(
                [r[arm]["touches_after_baseline"] for r in sub],
                [r["off"]["touches_after_baseline"] for r in sub])
        return out

    n = max(r["trial"] for r in rows)
    edges = np.linspace(0, n, blocks + 1).round().astype(int)
    curve_rows = []
    for lo, hi in zip(edges[:-1], edges[1:], strict=True):
        sub = [r for r in rows if lo < r["trial"] <= hi]
        curve_rows.append({"trials": [int(lo) + 1, int(hi)],
                           "reference_known_share": float(np.mean([r["reference_known"]
                                                                   for r in sub])),
                           **{k: stats(s) for k, s in (
                               ("all", sub), ("reference_new", [r for r in sub
                                                                if not r["reference_known"]]),
                               ("reference_known", [r for r in sub if r["reference_known"]]))}})
    return {"all": stats(rows),
            "reference_new": stats([r for r in rows if not r["reference_known"]]),
            "reference_known": stats([r for r in rows if r["reference_known"]]),
            "curve": curve_rows}


def run(args: argparse.Namespace) -> dict:
    out = results_dir(args.out, "fabric_library",
                      {k: v for k, v in vars(args).items() if k != "func"})
    results = {}
    for root in args.replay:
        path = Path(args.cache_dir) / f"{Path(root).name}.npz"
        if not path.is_file():
            print(f"describing every press of {root} -> {path}")
            build_cache(root, path)
        cache = load_cache(path)
        cls = cache["cls"]
        x = (shipped_features(cache, root, args.cache_dir) if args.learner == "shipped"
             else FEATURES["frame"](cache))
        rejected = None
        if args.contact_guard == "on":
            add_contact_verdicts(cache, root, args.cache_dir)
            rejected = ~cache["contact_ok"]
        rows = []
        for s in range(args.sessions):
            rows += run_session(x, cls, args.seed + s, args, rejected=rejected)
        arms = arm_names(args.weights)
        results[Path(root).name] = {"learner": args.learner, "descriptor_size": int(x.shape[1]),
                                    "sessions": args.sessions, "classes": len(set(cls.tolist())),
                                    "presses": int(len(cls)), "arms": arms,
                                    "contact_rejected": ([] if rejected is None else
                                                         cache["path"][rejected].tolist()),
                                    "weights": list(args.weights),
                                    "summary": summarise(rows, args.blocks, arms),
                                    "trials": rows}
    write_json(out / "fabric_library.json", {k: {kk: vv for kk, vv in v.items()}
                                             for k, v in results.items()})
    print(f"chart: {charts.library_curve(out / 'learning_curve.png', results)}")
    for name, r in results.items():
        for sub in ("all", "reference_new", "reference_known"):
            s = r["summary"][sub]
            print(f"{name} {sub:16s} n {s['n']:3d}  " + "  ".join(
                f"{arm}: acc {s[arm]['accuracy']:.3f} touches {s[arm]['touches_mean']:.2f} "
                f"wrong stops {s[arm]['wrong_stops']}" + (
                    f" (McNemar p {s[arm]['mcnemar_vs_off']['p']:.3g}, Wilcoxon p "
                    f"{s[arm]['wilcoxon_touches_vs_off']['p']:.3g})"
                    if "mcnemar_vs_off" in s[arm] else "") for arm in r["arms"]))
    return results


def register(esub: argparse._SubParsersAction) -> None:
    p = esub.add_parser("library", help="learning curve of the fabric library over replayed "
                                        "study sessions (learning on vs off, paired)")
    p.add_argument("--replay", nargs="+", required=True,
                   help="replay folders (each a library of classes, e.g. ../shared/datasets/"
                        "octopi-dev ../shared/datasets/octopi-objects)")
    p.add_argument("--learner", choices=LEARNERS, default="shipped",
                   help="shipped: the default learner as it ships (descriptor, height map, "
                        "embedding); descriptor: the earlier study's 106-number descriptor")
    p.add_argument("--cache-dir", required=True,
                   help="where per-press descriptors are cached, e.g. under /tmp (never the "
                        "repository)")
    p.add_argument("--sessions", type=int, default=3, help="replayed sessions per library")
    p.add_argument("--trials", type=int, default=32, help="trials per session (the thesis's)")
    p.add_argument("--comparisons", type=int, default=4)
    p.add_argument("--contact-guard", choices=("on", "off"), default="on",
                   help="on: a press the product's contact guard rejects is pressed again and "
                        "never joins the library, as on the robot; off: every press counts")
    p.add_argument("--budget", type=int, default=10, help="touches after the baseline")
    p.add_argument("--stop", type=float, default=SHIPPED_STOP,
                   help="stop threshold applied to the belief after every decision")
    p.add_argument("--weights", type=float, nargs="+", default=[EVIDENCE_WEIGHT],
                   help="evidence weights of the library (core/library.py EVIDENCE_WEIGHT), "
                        "one learning arm each")
    p.add_argument("--blocks", type=int, default=4, help="blocks of trial positions (curve)")
    p.add_argument("--seed", type=int, default=0, help="seed of the first session")
    p.add_argument("--out")

    def func(args: argparse.Namespace) -> int:
        for name, low in (("sessions", 1), ("trials", 1), ("comparisons", 2), ("budget", 1),
                          ("blocks", 1)):
            if getattr(args, name) < low:
                raise InputError(f"--{name} must be >= {low}, got {getattr(args, name)}")
        if not all(w > 0 for w in args.weights) or len(set(args.weights)) < len(args.weights):
            raise InputError(f"--weights must be distinct and > 0, got {args.weights}")
        if not 0 < args.stop <= 1:
            raise InputError(f"--stop must be in (0, 1], got {args.stop}")
        Path(args.cache_dir).mkdir(parents=True, exist_ok=True)
        run(args)
        return 0

    p.set_defaults(func=func)
