"""``tactex experiment embedding-search``: the simulator-trained network's hyperparameters,
chosen class-disjoint on real presses (issue 33).

Every network of the grid (training augmentation x simulated training fabrics x steps) is
trained on the simulator's fabrics only (``learned_features.add_to_caches`` with
``cnn_train="sim"``, cached per setting and seed under ``--cache-dir``) and embeds both real
libraries. Each is scored by the screening proxy (``metric_screen.scene_hits``: 1 press and the
mean of 2, the same seeded scenes for every network) on the shipped feature
(``frame_hm_cnn4``: the 129-number descriptor and the embedding of the 4-frame burst, no
metric), in both directions (A tested with B as the library, and B with A). Neither library
is seen in training, so the choice is made on one direction and reported on the other: the
network picked on A's scenes is judged on B's, and the other way round. Paired against the
first setting of the grid (exact McNemar on the scenes pooled over seeds).
"""

from __future__ import annotations

import argparse
import itertools
from pathlib import Path

import numpy as np

from tactex_ros.core import representation
from tactex_ros.core.errors import InputError
from tactex_lab.analysis import learned_features as lf
from tactex_lab.analysis.learned_features import library_view
from tactex_lab.analysis.metric_screen import scene_hits
from tactex_lab.analysis.stats import mcnemar_exact
from tactex_lab.experiments.common import results_dir, write_json
from tactex_lab.experiments.press_cache import FEATURES, cached

FEATURE = "frame_hm_cnn4"


def _hits(test: dict, lib: dict, kind: str, scenes: int,
          extra: tuple[np.ndarray, np.ndarray] | None = None) -> dict[int, np.ndarray]:
    """``scene_hits`` of ``FEATURE`` at 1 and 2 presses (``kind`` "none" or "whiten": fitted
    on the library); ``extra`` (test, library) columns are appended to it (an ensemble's other
    networks' embeddings)."""
    x, xl = FEATURES[FEATURE](test), FEATURES[FEATURE](library_view(lib))
    if extra is not None:
        x, xl = np.concatenate([x, extra[0]], 1), np.concatenate([xl, extra[1]], 1)
    rep = None
    if kind == "whiten":
        libd = {c: xl[lib["cls"] == c] for c in sorted(set(lib["cls"].tolist()))}
        rep = representation.fit(libd, kind="whiten")
    return {per: scene_hits(x, test["cls"], rep, per, scenes) for per in (1, 2)}


def _ensembles(grid: list, args: argparse.Namespace, nets: dict, hits: dict,
               directions: dict) -> list[dict]:
    """Per setting, the ensemble of its seeds' networks: ``FEATURE`` of the first seed with
    the other seeds' 4-frame embeddings appended (129 + 128 x seeds numbers), on the same
    scenes; paired against the first seed's network of the first setting (``vs_first``)."""
    rows = []
    for setting in grid:
        first = nets[setting, args.seed[0]]
        for test, lib in (("a", "b"), ("b", "a")):
            extra = tuple(np.concatenate([view(nets[setting, s][side])["cnn4"]
                                          for s in args.seed[1:]], 1)
                          for side, view in ((test, dict), (lib, library_view)))
            for kind in args.kinds:
                h = _hits(first[test], first[lib], kind, args.scenes, extra)
                base = hits[grid[0], args.seed[0], test, kind]
                row = {"aug": setting[0], "variants": setting[1], "steps": setting[2],
                       "direction": directions[test], "metric": kind,
                       "seeds": list(args.seed), "ensemble": True}
                for per in (1, 2):
                    row[f"acc_{per}"] = float(h[per].mean())
                    row[f"vs_first_{per}"] = mcnemar_exact(h[per], base[per])
                rows.append(row)
    return rows


def pick(rows: list[dict], chosen_on: str, judged_on: str, kind: str) -> dict:
    """The setting with the best 1-press + 2-press accuracy on direction ``chosen_on`` (the
    first of equals, in ``rows``' order), with its figures on direction ``judged_on``."""
    def key(r: dict) -> tuple:
        return r["aug"], r["variants"], r["steps"]
    rows = [r for r in rows if not r.get("ensemble")]
    mine = [r for r in rows if r["direction"] == chosen_on and r["metric"] == kind]
    if not mine:
        raise InputError(f"no rows of direction {chosen_on!r} and metric {kind!r}")
    best = key(max(mine, key=lambda r: r["acc_1"] + r["acc_2"]))
    judged = next(r for r in rows if key(r) == best and r["direction"] == judged_on
                  and r["metric"] == kind)
    return {"setting": dict(zip(("aug", "variants", "steps"), best, strict=True)), "judged_on": judged_on,
            "acc_1": judged["acc_1"], "acc_2": judged["acc_2"],
            "vs_first": {p: judged[f"vs_first_{p}"] for p in (1, 2)}}


def run(args: argparse.Namespace) -> dict:
    caches = {k: cached(root, args.cache_dir, candidates=True)
              for k, root in (("a", args.a), ("b", args.b))}
    grid = list(itertools.product(args.augs, args.variants, args.steps))
    directions = {"a": f"{Path(args.a).name}_with_{Path(args.b).name}",
                  "b": f"{Path(args.b).name}_with_{Path(args.a).name}"}
    hits: dict = {}     # (setting, seed, direction, kind) -> {per: hits}
    nets: dict = {}     # (setting, seed) -> the caches with that network's embeddings
    for (aug, variants, steps), seed in itertools.product(grid, args.seed):
        c = {k: dict(v) for k, v in caches.items()}
        lf.add_to_caches(c, {"a": args.a, "b": args.b}, args.cache_dir, cnn_seed=seed,
                         cnn_steps=steps, cnn_train="sim", cnn_aug=aug, cnn_variants=variants)
        nets[(aug, variants, steps), seed] = c
        for test, lib in (("a", "b"), ("b", "a")):
            for kind in args.kinds:
                hits[(aug, variants, steps), seed, test, kind] = _hits(c[test], c[lib], kind,
                                                                       args.scenes)
    rows = []
    for setting in grid:
        for test in ("a", "b"):
            for kind in args.kinds:
                per_seed = [hits[setting, s, test, kind] for s in args.seed]
                row = {"aug": setting[0], "variants": setting[1], "steps": setting[2],
                       "direction": directions[test], "metric": kind,
                       "seeds": list(args.seed)}
                for per in (1, 2):
                    accs = [float(h[per].mean()) for h in per_seed]
                    row[f"acc_{per}"] = float(np.mean(accs))
                    row[f"acc_{per}_range"] = [min(accs), max(accs)]
                    row[f"acc_{per}_seeds"] = accs
                    mine = np.concatenate([h[per] for h in per_seed])
                    base = np.concatenate([hits[grid[0], s, test, kind][per]
                                           for s in args.seed])
                    row[f"vs_first_{per}"] = mcnemar_exact(mine, base)
                rows.append(row)
    if args.ensemble:
        rows += _ensembles(grid, args, nets, hits, directions)
    picks = {f"{kind}: chosen on {directions[on]}": pick(rows, directions[on], directions[judge],
                                                          kind)
             for kind in args.kinds for on, judge in (("a", "b"), ("b", "a"))}
    for r in rows:
        print(f"{r['direction']:>36} {r['metric']:>6} {r['aug']:>11} v{r['variants']:<4} "
              f"{'ensemble ' if r.get('ensemble') else ''}"
              f"n{r['steps']:<5}: {r['acc_1']:.3f} / {r['acc_2']:.3f}  p vs first "
              f"{r['vs_first_1']['p']:.2g} {r['vs_first_2']['p']:.2g}"
              + ("" if "acc_1_seeds" not in r else "  per seed " + ", ".join(
                  f"{a:.3f} / {b:.3f}" for a, b in zip(r["acc_1_seeds"], r["acc_2_seeds"], strict=True))),
              flush=True)
    for name, p in picks.items():
        s = p["setting"]
        print(f"{name}: {s['aug']} v{s['variants']} n{s['steps']} -> on {p['judged_on']} "
              f"{p['acc_1']:.3f} / {p['acc_2']:.3f} (p vs first {p['vs_first'][1]['p']:.2g} "
              f"{p['vs_first'][2]['p']:.2g})", flush=True)
    out = results_dir(args.out, "embedding_search",
                      {k: v for k, v in vars(args).items() if k != "func"})
    result = {"feature": FEATURE, "rows": rows, "picks": picks}
    write_json(out / "embedding_search.json", result)
    return result


def register(esub: argparse._SubParsersAction) -> None:
    p = esub.add_parser("embedding-search",
                        help="the simulator-trained network's hyperparameters, chosen on one real "
                             "library and judged on the other")
    p.add_argument("--a", required=True, help="replay folder A")
    p.add_argument("--b", required=True, help="replay folder B")
    p.add_argument("--cache-dir", required=True,
                   help="where presses, training sets and networks are cached (under /tmp, "
                        "never the repository)")
    p.add_argument("--augs", nargs="+", choices=lf.AUGS, default=["geometric"],
                   help="training augmentations (the first setting is the reference)")
    p.add_argument("--variants", type=int, nargs="+", default=[lf.SIM_VARIANTS],
                   help="simulated fabrics beside the 25 catalogue ones")
    p.add_argument("--steps", type=int, nargs="+", default=[1500], help="training steps")
    p.add_argument("--seed", type=int, nargs="+", default=[0], help="network seeds")
    p.add_argument("--kinds", nargs="+", choices=("none", "whiten"), default=["none"],
                   help="no metric (the shipped default) and/or whitened on the library")
    p.add_argument("--scenes", type=int, default=3000, help="screening scenes per direction")
    p.add_argument("--ensemble", action="store_true",
                   help="also score each setting's seeds as one ensemble (their embeddings "
                        "concatenated; needs two or more --seed)")
    p.add_argument("--out")

    def func(args: argparse.Namespace) -> int:
        for name in ("variants", "steps", "seed"):
            bad = [v for v in getattr(args, name) if v < (1 if name == "steps" else 0)]
            if bad:
                raise InputError(f"--{name}: {bad} out of range (steps >= 1, others >= 0)")
        if args.ensemble and len(args.seed) < 2:
            raise InputError(f"--ensemble needs two or more --seed, got {args.seed}")
        if args.scenes < 1:
            raise InputError(f"--scenes must be >= 1, got {args.scenes}")
        run(args)
        return 0

    p.set_defaults(func=func)
