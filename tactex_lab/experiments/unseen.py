"""``tactex experiment unseen``: prepared representations on classes no part of the pipeline saw,
class-disjoint in both directions (issue 23, docs/research/unseen_materials.md).

Two libraries of recorded presses, A and B (``../shared``'s octopi-dev and octopi-objects). For
each direction (test on A with B as the lab's library, and the reverse) every setting:

- prepares on the *library* only: the representation (``core/representation.py``) and the
  belief's temperature calibrated on the library with classes left out
  (``core/calibration.py``), exactly what ``tactex prepare`` does;
- runs the trials of the test side through the trial engine (``core/engine.py``, infogain, no
  stop rule, ``--budget`` touches after the baseline), each press given by its descriptor
  computed once (``build_cache``; the draw of presses is ``ReplayTrial``'s, the scenes are
  ``experiment real``'s, so the scenes and presses are the same as ``tactex experiment real
  --source replay:A`` with the same seed);
- is scored with ``experiment real``'s protocol: 3 class folds of the test side; on each fold's
  *choose* scenes (other folds' classes) the best (setting, theta) with at most
  ``--target-touches`` touches is chosen and measured on the fold's *report* scenes; Wilson
  intervals, exact McNemar and Wilcoxon against the first setting (today's default) on the
  pooled report scenes.

Per-press features (``FEATURES``) tried on top of the shipped 106-number descriptor: several
frames of the press (the strongest + 3 more in contact; the frame at half the strongest contact,
the contact growing), and 2 x 2 regions of the strongest frame (mean and spread over regions);
with ``--candidates``, issue 33's filter bank, height map and contact growth
(``analysis/press_features.py``), screened by ``--screen-features``.

The cache holds descriptors of ``../shared`` presses: write it under /tmp, never into the
repository.
"""

from __future__ import annotations

import argparse
import itertools
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from tactex_ros.core import preparation, representation
from tactex_ros.core.config import TrialConfig, preset
from tactex_ros.core.errors import InputError
from tactex_ros.core.preparation import PrepareSettings
from tactex_lab.analysis import metric_screen
from tactex_lab.experiments.common import results_dir, write_json
from tactex_lab.experiments.curves import BeliefCurve, curve
from tactex_lab.analysis.learned_features import AUGS, SIM_VARIANTS, library_view
from tactex_lab.experiments.press_cache import (FEATURES, CachedPresses, add_contact_verdicts,
                                                by_class, cached)
from tactex_lab.experiments.protocol import (PRESS_TIME_HELP, THRESHOLD_HELP, check_options,
                                             protocol, write_outputs)


#: The lab's preparation where it differs from the product's (``PrepareSettings``'s defaults,
#: what `tactex prepare` does): a setting prepares no metric unless it names one.
LAB_PREPARE: dict[str, Any] = {"kind": "none"}
PREPARE_KEYS = ("kind", "dims", "calibration", "shrink")


@dataclass
class Setting:
    """One way to prepare: per-press feature (the lab's), the product's preparation settings
    (``core/preparation.PrepareSettings``, with ``LAB_PREPARE`` over its defaults) and
    ``temperature``: the trials' ``match_temperature`` (the learner's setting): '' = the
    config's (or the prepared file's), a number, or one of ``FAMILY_CHOICES``: the temperature
    that ``tactex experiment families`` chose with the test side's family held out
    (``--families``)."""

    label: str
    feature: str = "frame"
    prepare: PrepareSettings = field(default_factory=lambda: PrepareSettings(**LAB_PREPARE))
    temperature: str = ""

    @staticmethod
    def parse(text: str) -> Setting:
        """``label=key:value,...`` (keys feature, temperature and the preparation's kind,
        dims, calibration, shrink)."""
        label, sep, rest = text.partition("=")
        if not sep or not label:
            raise InputError(f"--setting {text!r}: expected label=key:value,...")
        kw: dict[str, Any] = {}
        for item in filter(None, rest.split(",")):
            k, _, v = item.partition(":")
            if k not in ("feature", "temperature") + PREPARE_KEYS:
                raise InputError(f"--setting {text!r}: unknown key {k!r}")
            kw[k] = int(v) if k == "dims" else float(v) if k == "shrink" else v
        feature = kw.pop("feature", "frame")
        temperature = kw.pop("temperature", "")
        if feature not in FEATURES:
            raise InputError(f"--setting {text!r}: feature one of {', '.join(FEATURES)}")
        try:
            prep = PrepareSettings(**{**LAB_PREPARE, **kw})
        except InputError as exc:
            raise InputError(f"--setting {text!r}: {exc}") from None
        if temperature and prep.calibration != "off":
            raise InputError(f"--setting {text!r}: temperature and calibration both set the "
                             "belief's temperature; give one")
        if temperature and temperature not in FAMILY_CHOICES + (SIM_CHOICE,):
            try:
                ok = float(temperature) > 0
            except ValueError:
                ok = False
            if not ok:
                raise InputError(f"--setting {text!r}: temperature a number > 0 or one of "
                                 f"{', '.join(FAMILY_CHOICES + (SIM_CHOICE,))}")
        return Setting(label, feature, prep, temperature)

    def to_dict(self) -> dict[str, Any]:
        """The file form: label, feature, the preparation's kind, dims, calibration, shrink, and
        the temperature when one is set."""
        return {"label": self.label, "feature": self.feature,
                **{k: getattr(self.prepare, k) for k in PREPARE_KEYS},
                **({"temperature": self.temperature} if self.temperature else {})}


#: ``temperature:`` values read from ``tactex experiment families``' summary (its settings).
FAMILY_CHOICES = ("pooled", "worst", "worst_target")
#: ``temperature:`` chosen on the simulator's fabrics (a third family, neither side of the
#: direction): the largest that keeps their left-out trials' wrong stops at the shipped stop
#: <= ``SIM_GOAL``, with the setting's representation fitted on the library (``--sim-family``).
SIM_CHOICE = "sim_target"
SIM_GOAL = 0.03


def sim_temperature(setting: Setting, rep: representation.Representation | None,
                    sim: dict[str, np.ndarray], seed: int) -> tuple[float, dict]:
    """``SIM_CHOICE``'s temperature of ``setting`` for one direction: ``core/calibration``'s
    left-out trials on the sim family ``sim`` (a press cache as the library's network sees it,
    ``learned_features.add_to_caches``) described by the setting's feature, the
    representation ``rep`` fitted on the library applied as is; then ``fit_temperature``
    target at the shipped stop. Returns (temperature, what the calibration measured)."""
    from tactex_ros.core import calibration
    from tactex_ros.core.config import SHIPPED_STOP
    trajs = calibration.trajectories(by_class(sim, setting.feature),
                                     None if rep is None else (lambda _d: rep),
                                     preset("descriptor"), seed=seed)
    beta = calibration.fit_temperature(trajs, "target", (SHIPPED_STOP,), SIM_GOAL)
    return beta, calibration.report(trajs, beta)


def setting_temperature(setting: Setting, test_family: str, families: dict | None
                        ) -> float | None:
    """The trials' temperature of ``setting`` on the test side ``test_family`` (a folder
    name): None = the config's (or the prepared file's); a number as given; a families choice
    from the summary ``families`` with ``test_family`` held out, whose descriptor must be the
    setting's (``feature``) with no representation."""
    t = setting.temperature
    if not t or t == SIM_CHOICE:
        return None
    if t not in FAMILY_CHOICES:
        return float(t)
    if families is None:
        raise InputError(f"setting {setting.label!r}: temperature {t!r} needs --families "
                         "(summary.json of tactex experiment families)")
    held = families.get("held_out", {})
    if test_family not in held:
        raise InputError(f"--families: no run with {test_family!r} held out (has "
                         f"{', '.join(held) or 'none'})")
    feature = families.get("feature", "frame")
    if setting.feature != feature or setting.prepare.kind != "none":
        raise InputError(f"setting {setting.label!r}: feature {setting.feature!r}, kind "
                         f"{setting.prepare.kind!r}, but the families were calibrated on "
                         f"{feature!r} with no representation (kind none)")
    return float(held[test_family]["settings"][t]["temperature"])


def prepare_setting(setting: Setting, library: dict[str, np.ndarray], seed: int = 0
                    ) -> representation.Representation | None:
    """What ``tactex prepare`` builds from ``library`` for ``setting`` (``preparation.prepare``
    with the shipped learner settings; None: nothing to prepare)."""
    p = setting.prepare
    if p.kind == "none" and p.calibration == "off":
        return None
    return preparation.prepare(library, p, preset("descriptor"), seed=seed)


def scene_curves(setting: Setting, rep: representation.Representation | None,
                 cache: dict[str, np.ndarray], scenes: list[list[str]], seed: int,
                 budget: int, temperature: float | None = None) -> list[BeliefCurve]:
    """Belief curves (``experiment real``'s ``curve``) of ``scenes`` on the cached test presses;
    scene i runs with seed ``seed + i``, as ``experiment real``. ``temperature``: the learner's
    ``match_temperature`` (None: the preset's)."""
    from tactex_ros.core.engine import TrialSpec, run_trial
    from tactex_ros.sources.replay import ReplayTrial
    src = CachedPresses(FEATURES[setting.feature](cache), cache["cls"],
                        None if "contact_ok" not in cache else ~cache["contact_ok"])
    cfg = preset("descriptor", guards=False,
                 **({} if temperature is None else {"match_temperature": temperature}))
    tcfg = TrialConfig(strategy="infogain", rounds=budget, stop_confidence=0.0)
    out = []
    for i, plat in enumerate(scenes):
        truth = plat[1:].index(plat[0]) + 1
        spec = TrialSpec(len(plat) - 1, cfg, tcfg, seed=seed + i, representation=rep)
        res = run_trial(spec, ReplayTrial(src, plat, seed + i), truth=truth)
        out.append(curve(res.rounds + [res.final], truth, classes=plat))
    return out


def nearest_mean_accuracy(x: np.ndarray, cls: np.ndarray,
                          rep: representation.Representation | None, per: int = 1,
                          scenes: int = 3000, seed: int = 0) -> float:
    """Screening proxy (no trial): share of random 1 + 4 scenes of the classes ``cls`` in which
    the comparison whose mean of ``per`` presses lies nearest to the mean of ``per`` reference
    presses, in the belief's scene units (``core/match.py``), is the match. ``per`` = 1 is the
    belief after the baseline."""
    return float(metric_screen.scene_hits(x, cls, rep, per, scenes, seed).mean())


SCREEN = ([("frame", "none", 0, 1.0)] + [("frame", "whiten", 0, s) for s in (0.3, 1.0, 3.0)]
          + [("frame", "lda", k, s) for k in (8, 16, 24, 32, 48) for s in (0.3, 1.0, 3.0)]
          + [(f, kind, k, 1.0) for f in ("frames4", "growth", "regions", "frame_regstd")
             for kind, k in (("none", 0), ("whiten", 0), ("lda", 24))])


def screen(a: dict[str, np.ndarray], b: dict[str, np.ndarray]) -> list[dict]:
    """Every (feature, kind, dims, shrink) of ``SCREEN`` fitted on one cache and scored with
    ``nearest_mean_accuracy`` (1 and 2 presses per platform) on the other, both directions."""
    rows = []
    for name, test, lib in (("a_with_b", a, b), ("b_with_a", b, a)):
        for f, kind, k, shrink in SCREEN:
            x = FEATURES[f](test)
            rep = (None if kind == "none" else
                   representation.fit(by_class(library_view(lib), f), shrink=shrink,
                                      kind=kind, dims=k))
            rows.append({"direction": name, "feature": f, "kind": kind, "dims": k,
                         "shrink": shrink,
                         "acc_1": nearest_mean_accuracy(x, test["cls"], rep, 1),
                         "acc_2": nearest_mean_accuracy(x, test["cls"], rep, 2)})
            print("  ".join(f"{v}" if not isinstance(v, float) else f"{v:.3f}"
                            for v in rows[-1].values()), flush=True)
    return rows


UNSEEN_SETTINGS = ("default=feature:frame", "whiten=feature:frame,kind:whiten",
                   "whiten_cal=feature:frame,kind:whiten,calibration:stop",
                   "whiten_cal_f4=feature:frames4,kind:whiten,calibration:stop")


def run_direction(settings: list[Setting], test: dict[str, np.ndarray],
                  library: dict[str, np.ndarray], args: argparse.Namespace,
                  test_family: str = "", families: dict | None = None) -> dict:
    """One direction: prepare every setting on ``library``, then ``experiment real``'s
    protocol on the ``test`` presses (``test_family``: its folder name, for the temperatures
    of ``families``, ``setting_temperature``). Returns the summary (``prepared``: what each
    setting's preparation measured and took)."""
    reps, prepared, temps = {}, {}, {}
    for s in settings:
        t0 = time.perf_counter()
        reps[s.label] = prepare_setting(s, by_class(library_view(library), s.feature),
                                        seed=args.seed)
        temps[s.label] = setting_temperature(s, test_family, families)
        r = reps[s.label]
        sim_cal = None
        if s.temperature == SIM_CHOICE:
            if "sim" not in library:
                raise InputError(f"setting {s.label!r}: temperature {SIM_CHOICE} needs "
                                 "--sim-family (and --cnn-seed)")
            temps[s.label], sim_cal = sim_temperature(s, r, library["sim"], args.seed)
            print(f"{s.label}: temperature {temps[s.label]:.4g} chosen on the sim family",
                  flush=True)
        prepared[s.label] = {"seconds": time.perf_counter() - t0, "setting": s.to_dict(),
                             "dims": None if r is None else r.dims,
                             "temperature": (temps[s.label] if r is None
                                             or temps[s.label] is not None else r.temperature),
                             "calibration": None if r is None else r.calibration,
                             **({"sim_calibration": sim_cal} if sim_cal else {})}

    def runner(scenes: list[list[str]], tag: str) -> dict[str, list[BeliefCurve]]:
        return {s.label: scene_curves(s, reps[s.label], test, scenes, args.seed, args.budget,
                                      temps[s.label])
                for s in settings}

    classes = sorted(set(test["cls"].tolist()))
    summary = protocol(classes, [s.label for s in settings], runner, args)
    summary["prepared"] = prepared
    return summary


def read_families(paths: list[str]) -> dict:
    """The ``summary.json`` files of ``tactex experiment families`` runs (e.g. one per
    ``--held-out`` family) as one summary: their held-out families together, one descriptor."""
    import json
    merged: dict = {"held_out": {}}
    for p in map(Path, paths):
        if not p.is_file():
            raise InputError(f"--families {p}: not a file (summary.json of tactex experiment "
                             "families)")
        s = json.loads(p.read_text())
        feature = s.get("feature", "frame")
        if merged.setdefault("feature", feature) != feature:
            raise InputError(f"--families: {p} is of descriptor {feature!r}, another of "
                             f"{merged['feature']!r}")
        for held, r in s.get("held_out", {}).items():
            if held in merged["held_out"]:
                raise InputError(f"--families: {held!r} held out in more than one file")
            merged["held_out"][held] = r
    return merged


def run_unseen(args: argparse.Namespace) -> dict:
    """Both directions (A tested with B as the library, and B with A)."""
    settings = [Setting.parse(t) for t in args.setting or UNSEEN_SETTINGS]
    labels = [s.label for s in settings]
    if len(set(labels)) != len(labels):
        raise InputError(f"--setting labels must be unique, got {labels}")
    caches = {name: cached(root, args.cache_dir, args.candidates, rebuild=args.build_cache)
              for name, root in (("a", args.a), ("b", args.b))}
    if args.sim_family and args.cnn_seed is None:
        raise InputError("--sim-family needs --cnn-seed (the networks that embed it)")
    if args.sim_family and args.cnn_train in ("sim", "shipped"):
        raise InputError("--sim-family with --cnn-train sim: the simulator's fabrics are that "
                         "network's training set, not a held-out family")
    if args.scattering or args.cnn_seed is not None or args.cnn_train == "shipped":
        from tactex_lab.analysis import learned_features
        sim = (learned_features.sim_family(args.cache_dir) if args.sim_family else None)
        learned_features.add_to_caches(caches, {"a": args.a, "b": args.b}, args.cache_dir,
                                       scattering=args.scattering, cnn_seed=args.cnn_seed,
                                       cnn_steps=args.cnn_steps, sim=sim,
                                       cnn_train=args.cnn_train, cnn_norm=args.cnn_norm,
                                       cnn_variants=args.cnn_variants, cnn_aug=args.cnn_aug)
    wanted = set(args.features) if args.screen_features else {s.feature for s in settings}
    for f in sorted(wanted):
        try:
            FEATURES[f](caches["a"])
        except KeyError as exc:
            raise InputError(f"feature {f!r} needs the cache array {exc} "
                             f"({'add' if not args.candidates else 'drop'} --candidates)") from None
    out = results_dir(args.out, "unseen", {k: v for k, v in vars(args).items() if k != "func"})
    if args.screen:
        rows = screen(caches["a"], caches["b"])
        write_json(out / "screen.json", rows)
        return {"screen": rows}
    if args.screen_features:
        rows = metric_screen.feature_screen(caches["a"], caches["b"],
                                            {f: FEATURES[f] for f in args.features})
        from tactex_lab.analysis.press_features import touch_costs
        costs = touch_costs(args.a)
        print("per-touch cost [ms]: " + ", ".join(f"{k} {v['median_ms']:.1f}"
                                                  for k, v in costs.items()))
        write_json(out / "feature_screen.json", {"rows": rows, "touch_costs_ms": costs})
        return {"feature_screen": rows, "touch_costs_ms": costs}
    if args.screen_mlp:
        grid = tuple(itertools.product(args.mlp_losses, args.mlp_hidden, args.mlp_decays))
        rows = metric_screen.screen(caches["a"], caches["b"], {f: FEATURES[f] for f in
                                    args.mlp_features}, grid, steps=args.mlp_steps,
                                    seeds=tuple(args.mlp_seeds))
        write_json(out / "metric_screen.json", rows)
        return {"metric_screen": rows}
    families = read_families(args.families) if args.families else None
    if args.contact_guard == "on":
        for name, root in (("a", args.a), ("b", args.b)):
            add_contact_verdicts(caches[name], root, args.cache_dir)
            off = caches[name]["path"][~caches[name]["contact_ok"]]
            print(f"{root}: {len(off)} of {len(caches[name]['path'])} presses without contact "
                  f"(the contact guard; re-pressed in a trial, not in the library): "
                  f"{', '.join(off.tolist()) or 'none'}", flush=True)
    both = {}
    for test, lib in (("a", "b"), ("b", "a")):
        name = f"{Path(getattr(args, test)).name}_with_{Path(getattr(args, lib)).name}"
        d = out / name
        d.mkdir(parents=True, exist_ok=True)
        summary = run_direction(settings, caches[test], caches[lib], args,
                                Path(getattr(args, test)).name, families)
        summary.update(test=getattr(args, test), library=getattr(args, lib),
                       contact_rejected={getattr(args, side): caches[side]["path"][~caches[side]["contact_ok"]]
                                         .tolist() for side in (test, lib)
                                         if "contact_ok" in caches[side]},
                       settings={s.label: s.to_dict() for s in settings})
        print(f"== test {getattr(args, test)}, library {getattr(args, lib)}")
        write_outputs(d, summary, labels, args)
        both[name] = summary
    return both


def register(esub: argparse._SubParsersAction) -> None:
    p = esub.add_parser("unseen", help="prepared representations on unseen classes, "
                                       "class-disjoint in both directions")
    p.add_argument("--a", required=True, help="replay folder A (tested with B as the library)")
    p.add_argument("--b", required=True, help="replay folder B (tested with A as the library)")
    p.add_argument("--cache-dir", required=True,
                   help="where the per-press descriptors are cached, e.g. under /tmp (never the "
                        "repository: they are descriptors of ../shared's presses)")
    p.add_argument("--build-cache", action="store_true", help="re-describe every press")
    p.add_argument("--candidates", action="store_true",
                   help="a cache with issue 33's candidate features (press_cache.build_cache "
                        "candidates=True; file <library>_candidates.npz): needed by "
                        "--screen-features and by settings on those features")
    p.add_argument("--screen", action="store_true",
                   help="only the screening proxy (nearest mean, no trials) of every feature x "
                        "metric of SCREEN, both directions; writes screen.json")
    p.add_argument("--screen-mlp", action="store_true",
                   help="only the screening of a small numpy MLP metric (analysis/mlp_metric) "
                        "against the whitening, both directions; writes metric_screen.json")
    p.add_argument("--scattering", action="store_true",
                   help="add kymatio's wavelet scattering of every press to the caches (features "
                        "scat, frame_hm_scat; analysis/learned_features.py)")
    p.add_argument("--cnn-seed", type=int, default=None,
                   help="train the small CNN on each library with this seed and add the "
                        "embeddings to the caches (features cnn, cnn4, frame_hm_cnn, "
                        "frame_hm_cnn4, frames4_hm_cnn4; the test side is embedded by the other library's "
                        "network); cached under --cache-dir per seed and steps")
    p.add_argument("--sim-family", action="store_true",
                   help="with --cnn-seed: embed the simulator's fabrics (6 presses each) with "
                        "each library's network, for settings with temperature:sim_target")
    p.add_argument("--cnn-steps", type=int, default=800,
                   help="training steps of the small CNN (--cnn-seed)")
    p.add_argument("--cnn-train", choices=("other", "sim", "shipped"), default="other",
                   help="with --cnn-seed: what the small CNN is trained on: each library's "
                        "network embeds the other (other), or one network trained on the "
                        "simulator's fabrics embeds both (sim: weights a product may carry); "
                        "shipped (no --cnn-seed): the product's shipped network embeds both, as "
                        "the default learner does")
    p.add_argument("--cnn-norm", choices=("global", "image"), default="global",
                   help="with --cnn-seed: the CNN's input scale: the training set's standard "
                        "deviation (global) or each frame's own (image)")
    p.add_argument("--cnn-aug", choices=AUGS, default="geometric",
                   help="with --cnn-seed: the CNN's training augmentation: crops turned and "
                        "mirrored (geometric), and their look varied too (photometric: "
                        "contrast, channel gains, blur, noise)")
    p.add_argument("--cnn-variants", type=int, default=SIM_VARIANTS,
                   help="with --cnn-train sim: simulated fabrics drawn beside the 25 catalogue "
                        "ones for the training set")
    p.add_argument("--screen-features", action="store_true",
                   help="only the screening proxy of per-press features (--features), with no "
                        "metric and whitened, both directions, exact McNemar against the frame "
                        "and the whitened frame on the same scenes; writes feature_screen.json")
    p.add_argument("--features", nargs="+", default=list(metric_screen.CANDIDATES),
                   choices=list(FEATURES),
                   help="per-press features (--screen-features)")
    p.add_argument("--mlp-steps", type=int, default=600, help="Adam steps per MLP (--screen-mlp)")
    p.add_argument("--mlp-seeds", type=int, nargs="+", default=[0],
                   help="MLP training seeds (--screen-mlp)")
    p.add_argument("--mlp-losses", nargs="+", default=["episode", "triplet"],
                   choices=["episode", "triplet"], help="MLP losses screened (--screen-mlp)")
    p.add_argument("--mlp-hidden", type=int, nargs="+", default=[64],
                   help="MLP hidden units screened (--screen-mlp)")
    p.add_argument("--mlp-decays", type=float, nargs="+", default=[1e-3, 1e-2, 1e-1],
                   help="MLP weight decays (toward the whitening) screened (--screen-mlp)")
    p.add_argument("--mlp-features", nargs="+", default=["frame", "frames4"],
                   choices=["frame", "frames4"], help="per-press features (--screen-mlp)")
    p.add_argument("--setting", action="append",
                   help="label=feature:F,kind:K,dims:N,calibration:C,temperature:T (repeat); "
                        "default: "
                        + " ".join(UNSEEN_SETTINGS))
    p.add_argument("--families", metavar="SUMMARY", nargs="+",
                   help="summary.json of tactex experiment families (several: one per "
                        "--held-out run): the temperatures of settings with temperature:"
                   + "|".join(FAMILY_CHOICES))
    p.add_argument("--contact-guard", choices=("on", "off"), default="on",
                   help="on: a press the product's contact guard rejects (no contact against its "
                        "own no-contact frame) is re-pressed in a trial and left out of the "
                        "library, as on the robot; off: every press counts (the figures before "
                        "this option)")
    p.add_argument("--comparisons", type=int, default=4)
    p.add_argument("--scenes", type=int, default=40, help="scenes per fold and set")
    p.add_argument("--budget", type=int, default=15, help="touches after the baseline")
    p.add_argument("--folds", type=int, default=3)
    p.add_argument("--thresholds", type=float, nargs="+", help=THRESHOLD_HELP)
    p.add_argument("--target-touches", type=float, default=3.0)
    p.add_argument("--report-only", action="store_true")
    p.add_argument("--paired-against", nargs="+", metavar="LABEL")
    p.add_argument("--press-time", metavar="FILE|DIR", help=PRESS_TIME_HELP)
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--out")

    def func(args: argparse.Namespace) -> int:
        check_options(args)
        for name in ("comparisons", "scenes", "budget", "folds", "mlp_steps"):
            if getattr(args, name) < (2 if name in ("comparisons", "folds") else 1):
                raise InputError(f"--{name} too small: {getattr(args, name)}")
        Path(args.cache_dir).mkdir(parents=True, exist_ok=True)
        run_unseen(args)
        return 0

    p.set_defaults(func=func)
