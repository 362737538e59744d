"""Run many trials, in parallel worker processes, reproducibly.

A ``TrialJob`` is everything one trial needs as plain data (so it pickles into a worker):
the source spec (``sim[:q]`` or ``replay:DIR``), the scene (explicit platform classes, or drawn
from the seed), learner preset + overrides, trial settings, the seed, and an optional
``perturb`` dict that experiments use to degrade touches (see ``apply_perturbation``).
``run_jobs`` returns one result dict per job in job order: the engine's ``TrialResult.to_dict``
plus ``job`` (the job as a dict), ``decision_s`` per decision and ``wall_s``.

Workers are separate processes with ``threads`` torch threads each (default 1), so timings
within one run are comparable; ``workers=1`` runs in this process.
"""

from __future__ import annotations

import dataclasses
import os
import time
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass, field, replace
from typing import Any, Callable

import numpy as np

from ..core.engine import TrialConfig, TrialEngine
from ..core.errors import TactexError
from ..core.touch import Touch, as_touch
from .common import progress


@dataclass
class TrialJob:
    source: str                                   # "sim:0.5", "replay:/path"
    seed: int
    strategy: str = "variance"
    rounds: int = 20
    max_touches: int = 0
    stop_confidence: float = 0.0
    preset: str = "cnn"
    overrides: dict[str, Any] = field(default_factory=dict)
    platform_classes: list[str] | None = None     # [reference, comp 1..C]; None = draw
    comparisons: int = 4                          # used when drawing the scene
    trial_id: str = ""
    perturb: dict[str, Any] = field(default_factory=dict)
    tags: dict[str, Any] = field(default_factory=dict)   # free labels carried to the result
    catch_errors: bool = False    # a trial that raises gives a result with "error" (not a crash)
    no_contact_reference: bool = True   # give the engine a no-contact frame when the source can


_SOURCES: dict[str, Any] = {}


def _source(spec: str):
    if spec not in _SOURCES:
        from ..sources import open_source
        _SOURCES[spec] = open_source(spec)
    return _SOURCES[spec]


def scene(job: TrialJob) -> tuple[list[str], int]:
    """Platform classes [reference, comparisons...] and the true match (1..C) of a job."""
    from ..cli import assign_platforms
    src = _source(job.source)
    if job.platform_classes is not None:
        comps = list(job.platform_classes[1:])
        ref = job.platform_classes[0]
        if ref not in comps:
            raise TactexError(f"trial {job.trial_id!r}: reference {ref!r} is not among the "
                              f"comparisons {comps}")
        return [ref] + comps, comps.index(ref) + 1
    chosen = (src.draw_scene(job.comparisons, job.seed) if hasattr(src, "draw_scene")
              else None)
    classes = list(getattr(src, "fabrics", src.classes))
    return assign_platforms(classes, job.comparisons, chosen, None, job.seed)


def apply_perturbation(img: np.ndarray, perturb: dict[str, Any],
                       rng: np.random.Generator) -> np.ndarray:
    """Degrade one (240, 320, 3) uint8 touch.

    Keys (all optional): ``noise`` extra Gaussian sensor noise std [grey levels];
    ``drift`` lighting drift, a random per-channel offset with this std [grey levels];
    ``blank`` probability that the touch is a flat no-contact frame (mean colour of the image).
    """
    out = img.astype(np.float32)
    if perturb.get("blank", 0.0) and rng.random() < perturb["blank"]:
        out[:] = out.reshape(-1, 3).mean(axis=0)
        out += rng.normal(0.0, 1.0, out.shape)
    if perturb.get("drift", 0.0):
        out += rng.normal(0.0, perturb["drift"], 3).astype(np.float32)
    if perturb.get("noise", 0.0):
        out += rng.normal(0.0, perturb["noise"], out.shape).astype(np.float32)
    return np.clip(out, 0, 255).astype(np.uint8)


def _touch_fn(job: TrialJob, classes: list[str]) -> Callable[[int], "Touch | np.ndarray"]:
    src = _source(job.source)
    depth = job.perturb.get("depth_spread")
    if depth is not None and hasattr(src, "press"):
        # press depth drawn from a widened range around the sensor's nominal depth [mm]
        rng_d = np.random.default_rng([job.seed, 29])
        lo, hi = src.renderer.sensor.depth_mm
        mid = 0.5 * (lo + hi)
        rng_p = np.random.default_rng([job.seed, 23])

        def base(p: int) -> np.ndarray:
            d = float(np.clip(mid + rng_d.uniform(-depth, depth), 0.02, 2.0))
            return src.press(classes[p], rng_p, depth_mm=d)
    else:
        base = src.trial(classes, job.seed)
    keys = {k for k, v in job.perturb.items() if k != "depth_spread" and v}
    if not keys:
        return base
    rng = np.random.default_rng([job.seed, 31])

    def perturbed(p: int) -> Touch:
        t = as_touch(base(p))
        return replace(t, frame=apply_perturbation(t.frame, job.perturb, rng))

    return perturbed


def run_job(job: TrialJob, threads: int = 1,
            engine_hook: Callable[[TrialEngine], None] | None = None) -> dict:
    """Run one trial; returns the result dict (see module docstring)."""
    import torch

    from ..core.config import preset
    if threads:
        torch.set_num_threads(threads)
    classes, truth = scene(job)
    n = len(classes) - 1
    ids = ["reference"] + [f"c{i}" for i in range(1, n + 1)]
    cfg = preset(job.preset, **job.overrides)
    tcfg = TrialConfig(strategy=job.strategy, rounds=job.rounds, max_touches=job.max_touches,
                       stop_confidence=job.stop_confidence)
    eng = TrialEngine(n, cfg, tcfg, seed=job.seed, platform_ids=ids)
    src = _source(job.source)
    if job.no_contact_reference and hasattr(src, "renderer"):
        eng.set_no_contact_reference(src.renderer.no_contact(np.random.default_rng([job.seed, 37])))
    if engine_hook:
        engine_hook(eng)
    t0 = time.perf_counter()
    try:
        res = eng.run(_touch_fn(job, classes), truth=truth)
    except (TactexError, FloatingPointError, RuntimeError) as exc:
        if not job.catch_errors:
            raise
        recs = eng.records
        return {"correct": False, "prediction": None, "truth": ids[truth], "touches":
                eng.total_touches, "rounds": [dataclasses.asdict(r) for r in recs],
                "final": None, "failed_touches": list(eng.failed),
                "error": f"{type(exc).__name__}: {exc}", "job": dataclasses.asdict(job),
                "classes": classes, "truth_index": truth, "prediction_index": None,
                "decision_s": [r.decision_s for r in recs], "wall_s": time.perf_counter() - t0}
    out = res.to_dict()
    out.update(job=dataclasses.asdict(job), classes=classes, truth_index=truth,
               prediction_index=res.prediction,
               decision_s=[r.decision_s for r in res.rounds + [res.final]],
               wall_s=time.perf_counter() - t0)
    return out


def _run_job_worker(args: tuple[TrialJob, int]) -> dict:
    job, threads = args
    return run_job(job, threads)


def default_workers() -> int:
    """Worker processes: one per core."""
    return max(1, os.cpu_count() or 1)


def run_jobs(jobs: list[TrialJob], workers: int = 1, threads: int = 1,
             description: str = "trials", quiet: bool = False) -> list[dict]:
    """Run ``jobs`` (in ``workers`` processes, ``threads`` torch threads each), in job order."""
    if workers < 1:
        raise TactexError(f"workers must be >= 1, got {workers}")
    if workers == 1:
        return [run_job(j, threads) for j in progress(jobs, description, len(jobs), quiet)]
    import multiprocessing as mp
    ctx = mp.get_context("spawn")  # torch and fork do not mix
    with ProcessPoolExecutor(max_workers=workers, mp_context=ctx) as pool:
        it = pool.map(_run_job_worker, [(j, threads) for j in jobs])
        return list(progress(it, description, len(jobs), quiet))
