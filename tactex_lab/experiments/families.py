"""``tactex experiment families``: the belief's temperature and the stop's "not sure" rule
chosen with a whole family of materials held out (issue 33, docs/research/calibration_families.md).

Families: replay folders of recorded presses (``../shared``'s octopi-dev, octopi-objects) and
``sim`` (the simulator's catalogue fabrics, ``config/fabrics.yaml``, pressed by the sim touch
source in one live session: one no-contact frame, as a robot records). Every press is described
once (the strongest frame; ``--feature frame_hm``: today's 129-number descriptor with the height
map, ``frame``: the 106-number descriptor of earlier releases) into a cache under
``--cache-dir`` (never the repository).

Per family and seed the trials of ``core/calibration.py``'s ``trajectories`` (3 class folds x
``--scenes`` scenes of 1 reference + 4 comparisons, the trial engine with infogain, no stop
rule, ``--budget`` touches after the baseline) are run at today's temperature
(``match_temperature``), keeping the untempered log evidence and the two best comparisons'
separation at every decision.

Leave one family out: for each family F, every calibration is chosen on the *other* families'
trials only, then F's trials are run again at the chosen temperature (same scenes, the policy
then touches with that belief) and scored: the wrong-stop rate (stopped sure on a wrong
comparison, share of all trials) at each theta with its Wilson interval, accuracy at the stop,
touches after the baseline, ECE (10 bins) over every decision and over the sure stops; paired
against today's default on the same scenes (exact McNemar on right/wrong at the stop, Wilcoxon
on touches). Calibrations: ``pooled`` (``fit_temperature`` stop on the training families'
trials pooled), ``worst`` (``fit_temperature_families``: wrong stops <= 1 - theta on every
training family separately), ``worst_target`` (every training family <= 3 % at 0.9).

The "not sure" rule (``TrialConfig.stop_separation``): a sure stop also needs the two best
comparisons' separation above s0. It only ends a trial or not, it does not change the touches,
so it is applied exactly to the recorded trials; s0 is chosen per held-out family on the other
families (the smallest s0 that keeps every training family's wrong stops at 0.9 <= 3 %).
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np

from tactex_ros.core import calibration as cal
from tactex_ros.core.config import SHIPPED_STOP, preset
from tactex_ros.core.errors import InputError
from tactex_ros.core.match import softmax
from tactex_lab.analysis.stats import mcnemar_exact, wilcoxon_paired, wilson
from tactex_lab.experiments.common import results_dir, write_json
from tactex_lab.experiments.press_cache import by_class, cached

THETAS = (0.8, 0.9, 0.95)
#: The "not sure" rule's thresholds tried (0 = off).
SEPARATIONS = (0.0, 0.5, 1.0, 1.5, 2.0, 3.0, 4.0, 6.0)
#: The issue's goal for wrong stops at the shipped stop 0.9.
GOAL = 0.03
#: ``--feature``: the descriptor each press is described by -> (preset, overrides) of the
#: learner settings that describe it (``feature_settings``).
FEATURES = {"frame_hm": ("descriptor", {"descriptor_height_map": True}),
            "frame": ("descriptor", {"descriptor_height_map": False}),
            "default": ("default", {})}


def feature_settings(feature: str):
    """The learner settings whose ``raw_descriptor`` is ``feature`` and whose
    ``match_temperature`` is its temperature: ``frame_hm`` the 129-number descriptor, ``frame``
    the 106 numbers of earlier releases (both 0.05), ``default`` the shipped default (the 129
    numbers and the shipped network's embedding of the 4-frame burst: 257 numbers, 0.0251)."""
    if feature not in FEATURES:
        raise InputError(f"feature {feature!r}: use one of {', '.join(FEATURES)}")
    name, over = FEATURES[feature]
    return preset(name, **over)


def sim_presses(per_class: int, seed: int = 0, feature: str = "frame_hm"
                ) -> dict[str, np.ndarray]:
    """{fabric: (per_class, D) descriptors} of the catalogue fabrics, pressed by the sim touch
    source in one live session (``SimSource.trial``: one no-contact frame for every press),
    described as ``feature`` (``feature_settings``)."""
    from tactex_ros import sources
    from tactex_ros.core.descriptor import raw_descriptor
    src = sources.open_source("sim")
    cfg = feature_settings(feature)
    names = src.classes
    touch = src.trial(names, seed)
    return {n: np.stack([raw_descriptor(touch(i), cfg) for _ in range(per_class)])
            for i, n in enumerate(names)}


def family_presses(spec: str, cache_dir: Path, per_class: int, feature: str = "frame"
                   ) -> dict[str, np.ndarray]:
    """{class: (n, D) descriptors} of family ``spec`` (``sim`` or a replay folder) described
    by ``feature`` (``FEATURES``), cached (replay folders: ``press_cache``'s ``<folder>.npz``,
    with the height map ``<folder>_candidates.npz``, as ``experiment unseen``; the shipped
    default, described by the product's own ``raw_descriptor``, ``<folder>_default.npz``)."""
    feature_settings(feature)
    tag = {"frame": "", "frame_hm": "_hm", "default": "_default"}[feature]
    if spec == "sim":
        path = cache_dir / f"sim_{per_class}{tag}.npz"
        if not path.is_file():
            x = sim_presses(per_class, feature=feature)
            np.savez(path, **x)
        with np.load(path) as z:
            return {k: z[k] for k in z.files}
    root = Path(spec)
    if not root.is_dir():
        raise InputError(f"family {spec!r}: 'sim' or a replay folder")
    if feature == "default":
        path = cache_dir / f"{root.name}_default.npz"
        if not path.is_file():
            print(f"describing every press of {root} as the shipped default -> {path}",
                  flush=True)
            np.savez(path, **replay_presses(root, feature_settings(feature)))
        with np.load(path) as z:
            return {k: z[k] for k in z.files}
    return by_class(cached(root, cache_dir, candidates=feature == "frame_hm"), feature)


def replay_presses(root: Path, cfg) -> dict[str, np.ndarray]:
    """{class: (n, D) descriptors} of every press of the replay folder ``root`` as the
    product describes a touch with learner settings ``cfg`` (``raw_descriptor``)."""
    from tactex_ros.core.descriptor import raw_descriptor
    from tactex_ros.sources.replay import ReplaySource
    src = ReplaySource(root)
    return {c: np.stack([raw_descriptor(src.touch(p), cfg) for p in src.presses(c)])
            for c in src.classes}


def outcome(trajs: list[cal.Trajectory], beta: float, theta: float,
            s0: float = 0.0) -> dict[str, np.ndarray]:
    """Per trial under stop threshold ``theta`` and the "not sure" rule ``s0`` (0 = off):
    ``sure`` (stopped on the rule), ``correct`` (the prediction at the end), ``extra`` (touches
    after the baseline at the end), ``conf`` (top belief at the end)."""
    rows = []
    for t in trajs:
        b = softmax(beta * t.evidence)
        top = b.max(axis=1)
        ok = top >= theta
        if s0 > 0:
            ok &= t.separation > s0
        i = int(np.argmax(ok)) if ok.any() else len(b) - 1
        rows.append((bool(ok.any()), int(np.argmax(b[i])) == t.truth, t.extra[i], top[i]))
    sure, correct, extra, conf = map(np.array, zip(*rows, strict=True))
    return {"sure": sure, "correct": correct, "extra": extra.astype(float), "conf": conf}


def score(trajs: list[cal.Trajectory], beta: float, s0: float = 0.0) -> dict:
    """Wrong stops [Wilson], accuracy, touches, not-sure share and ECE per theta."""
    out = {"temperature": beta, "trials": len(trajs), "ece_decisions": cal.ece(trajs, beta)}
    for th in THETAS:
        o = outcome(trajs, beta, th, s0)
        n, wrong = len(trajs), int(np.sum(o["sure"] & ~o["correct"]))
        out[str(th)] = {
            "wrong_stop": wrong / n, "wrong_stop_ci": wilson(wrong, n),
            "accuracy": float(o["correct"].mean()), "touches": float(o["extra"].mean()),
            "not_sure": float(1 - o["sure"].mean()),
            "accuracy_sure": float(o["correct"][o["sure"]].mean()) if o["sure"].any() else None,
            "ece_stops": cal.ece_of(o["conf"][o["sure"]], o["correct"][o["sure"]])}
    return out


def paired(a: list[cal.Trajectory], beta_a: float, b: list[cal.Trajectory], beta_b: float,
           s0_a: float = 0.0, s0_b: float = 0.0) -> dict:
    """McNemar (right/wrong at the stop) and Wilcoxon (touches) of a against b per theta, the
    same scenes in the same order."""
    res = {}
    for th in THETAS:
        oa, ob = outcome(a, beta_a, th, s0_a), outcome(b, beta_b, th, s0_b)
        res[str(th)] = {"mcnemar_p": mcnemar_exact(oa["correct"], ob["correct"])["p"],
                        "wrong_stop_mcnemar_p": mcnemar_exact(~(oa["sure"] & ~oa["correct"]),
                                                              ~(ob["sure"] & ~ob["correct"]))["p"],
                        "wilcoxon_p": wilcoxon_paired(oa["extra"], ob["extra"])["p"]}
    return res


def choose_separation(train: list[list[cal.Trajectory]], beta: float) -> float:
    """The smallest s0 of ``SEPARATIONS`` whose wrong stops at the shipped stop stay <= ``GOAL`` on every
    training family (the largest tried when none does)."""
    for s0 in SEPARATIONS:
        if all(np.mean((o := outcome(t, beta, SHIPPED_STOP, s0))["sure"] & ~o["correct"]) <= GOAL + 1e-12
               for t in train):
            return s0
    return SEPARATIONS[-1]


def run_family(name: str, presses: dict[str, np.ndarray], seeds: list[int],
               args: argparse.Namespace, beta: float) -> list[cal.Trajectory]:
    """The family's trials at temperature ``beta``, every seed, in a fixed order; each seed's
    trials kept in ``--cache-dir`` (reused by a later run with the same settings)."""
    out = []
    for s in seeds:
        feature = getattr(args, "feature", "frame")
        tag = "" if feature == "frame" else f"_{feature}"
        path = Path(args.cache_dir) / (f"trials_{name}{tag}_b{beta:.6g}_s{s}_f{args.folds}"
                                       f"_n{args.scenes}_k{args.budget}.npz")
        if not path.is_file():
            ts = cal.trajectories(presses, None, feature_settings(feature), folds=args.folds,
                                  scenes=args.scenes, budget=args.budget, temperature0=beta,
                                  seed=s)
            np.savez(path, **{f"{k}_{i}": getattr(t, k) for i, t in enumerate(ts)
                              for k in ("evidence", "extra", "separation")},
                     truth=np.array([t.truth for t in ts]))
        with np.load(path) as z:
            out += [cal.Trajectory(z[f"evidence_{i}"], int(y), z[f"extra_{i}"],
                                   z[f"separation_{i}"]) for i, y in enumerate(z["truth"])]
    return out


def run_families(args: argparse.Namespace) -> dict:
    cache = Path(args.cache_dir)
    cache.mkdir(parents=True, exist_ok=True)
    names = [Path(f).name if f != "sim" else "sim" for f in args.family]
    if len(set(names)) != len(names) or len(names) < 3:
        raise InputError(f"--family: >= 3 distinct families, got {names}")
    out = results_dir(args.out, "families", {k: v for k, v in vars(args).items()
                                             if k != "func"})
    beta0 = feature_settings(args.feature).match_temperature
    fams, base = {}, {}
    for name, spec in zip(names, args.family, strict=True):
        fams[name] = family_presses(spec, cache, args.per_class, args.feature)
        t0 = time.time()
        base[name] = run_family(name, fams[name], args.seed, args, beta0)
        print(f"{name}: {len(fams[name])} classes, {len(base[name])} trials at {beta0} "
              f"({time.time() - t0:.0f} s)", flush=True)
    if args.baseline_only:
        return {}
    summary: dict = {"feature": args.feature,
                     "descriptor_dim": int(next(iter(fams[names[0]].values())).shape[1]),
                     "families": {n: {"classes": len(fams[n]),
                                      "presses": int(sum(len(v) for v in fams[n].values()))}
                                  for n in names}, "default_temperature": beta0, "held_out": {}}
    for held in names:
        if args.held_out and held not in args.held_out:
            continue
        train = [base[n] for n in names if n != held]
        pool = [t for ts in train for t in ts]
        betas = {"default": beta0,
                 "pooled": cal.fit_temperature(pool, "stop", THETAS),
                 "worst": cal.fit_temperature_families(train, "stop", THETAS),
                 "worst_target": cal.fit_temperature_families(train, "target", (SHIPPED_STOP,),
                                                                GOAL)}
        runs = {"default": base[held]}
        res: dict = {"trained_on": [n for n in names if n != held], "settings": {}}
        for label, beta in betas.items():
            if label != "default":
                done = [k for k, b in betas.items() if b == beta and k in runs]
                t0 = time.time()
                runs[label] = runs[done[0]] if done else run_family(
                    held, fams[held], args.seed, args, beta)
                print(f"held out {held}: {label} {beta:.4g} ({time.time() - t0:.0f} s)",
                      flush=True)
            res["settings"][label] = {**score(runs[label], beta),
                                      "vs_default": paired(runs[label], beta, base[held], beta0)}
        s0 = choose_separation(train, beta0)
        res["separation"] = {
            "chosen": s0,
            "sweep": {str(s): score(base[held], beta0, s) for s in SEPARATIONS},
            "vs_default": paired(base[held], beta0, base[held], beta0, s0, 0.0),
            "would_have_been_wrong": would_have_been_wrong(base[held], beta0, s0)}
        summary["held_out"][held] = res
        write_json(out / "summary.json", summary)
    print_tables(summary)
    return summary


def would_have_been_wrong(trajs: list[cal.Trajectory], beta: float, s0: float) -> dict:
    """Per theta: trials the rule turns from sure to not sure, and how many of those stopped
    wrong without it."""
    res = {}
    for th in THETAS:
        off, on = outcome(trajs, beta, th), outcome(trajs, beta, th, s0)
        turned = off["sure"] & ~on["sure"]
        res[str(th)] = {"turned_not_sure": int(turned.sum()),
                        "of_which_wrong": int(np.sum(turned & ~off["correct"]))}
    return res


def _pct(x: float) -> str:
    return f"{100 * x:.1f} %"


def print_tables(summary: dict) -> None:
    """Markdown tables of the summary (docs/research/calibration_families.md)."""
    print("| held out | setting | temperature | " + " | ".join(
        f"wrong stops {th} [95 %]" for th in THETAS) + f" | acc / touches at {SHIPPED_STOP:g} | "
        f"ECE decisions / stops ({SHIPPED_STOP:g}) | McNemar p, Wilcoxon p vs default "
        f"({SHIPPED_STOP:g}) |")
    print("|" + " --- |" * (6 + len(THETAS) - 1 + 1))
    for held, r in summary["held_out"].items():
        for label, s in r["settings"].items():
            w = " | ".join(f"{_pct(s[str(th)]['wrong_stop'])} [{_pct(s[str(th)]['wrong_stop_ci'][0])}"
                           f", {_pct(s[str(th)]['wrong_stop_ci'][1])}]" for th in THETAS)
            at = s[str(SHIPPED_STOP)]
            v = s["vs_default"][str(SHIPPED_STOP)]
            print(f"| {held} | {label} | {s['temperature']:.4g} | {w} | "
                  f"{at['accuracy']:.3f} / {at['touches']:.2f} | "
                  f"{s['ece_decisions']:.3f} / {at['ece_stops']:.3f} | "
                  f"{v['mcnemar_p']:.2g}, {v['wilcoxon_p']:.2g} |")
    print()
    print(f"| held out | s0 | wrong stops {SHIPPED_STOP:g} [95 %] | not sure | acc (all / sure) "
          "| touches |")
    print("| --- | --- | --- | --- | --- | --- |")
    for held, r in summary["held_out"].items():
        for s0, s in r["separation"]["sweep"].items():
            x = s[str(SHIPPED_STOP)]
            mark = " (chosen)" if float(s0) == r["separation"]["chosen"] else ""
            print(f"| {held} | {s0}{mark} | {_pct(x['wrong_stop'])} [{_pct(x['wrong_stop_ci'][0])}"
                  f", {_pct(x['wrong_stop_ci'][1])}] | {_pct(x['not_sure'])} | "
                  f"{x['accuracy']:.3f} / {x['accuracy_sure'] or float('nan'):.3f} | "
                  f"{x['touches']:.2f} |")


def register(esub: argparse._SubParsersAction) -> None:
    p = esub.add_parser("families", help="leave-one-family-out calibration of the belief's "
                                         "temperature and the stop's not-sure rule")
    p.add_argument("--family", action="append", required=True,
                   help="'sim' (the catalogue fabrics) or a replay folder; >= 3 (repeat)")
    p.add_argument("--cache-dir", required=True,
                   help="per-press descriptors, e.g. under /tmp (never the repository)")
    p.add_argument("--feature", choices=list(FEATURES), default="frame_hm",
                   help="each press's descriptor: default = the shipped default's (257 numbers: "
                        "the height map and the shipped network's embedding of the burst), "
                        "frame_hm = the 129-number descriptor, frame = the 106 numbers of "
                        "earlier releases")
    p.add_argument("--per-class", type=int, default=6, help="sim presses per fabric")
    p.add_argument("--scenes", type=int, default=40, help="scenes per class fold and seed")
    p.add_argument("--folds", type=int, default=3)
    p.add_argument("--budget", type=int, default=10, help="touches after the baseline")
    p.add_argument("--seed", type=int, nargs="+", default=[0, 1, 2])
    p.add_argument("--held-out", nargs="+", metavar="NAME",
                   help="only these held-out families (folder names or sim); default: each")
    p.add_argument("--baseline-only", action="store_true",
                   help="only run (and cache) every family's trials at today's temperature")
    p.add_argument("--out")

    def func(args: argparse.Namespace) -> int:
        for name in ("per_class", "scenes", "budget"):
            if getattr(args, name) < 2:
                raise InputError(f"--{name.replace('_', '-')} must be >= 2, got "
                                 f"{getattr(args, name)}")
        run_families(args)
        return 0

    p.set_defaults(func=func)
