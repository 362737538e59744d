"""The one job runner of the experiments: a job is plain data, run in parallel with joblib,
on this machine or on a Ray cluster, results in job order.

``run_parallel(fn, items, backend)`` runs ``fn(item)`` for every item and returns the results in
item order, with one progress display (``common.progress``). ``Backend`` says where:

- ``joblib`` (default): ``workers`` processes on this machine (joblib's loky backend; 0 = one per
  core); ``workers=1`` runs in this process.
- ``ray``: joblib's Ray backend (``ray.util.joblib``) on the cluster at ``address`` (e.g.
  ``auto`` or ``ray://head:10001``; none = a local Ray instance is started), ``workers``
  parallel tasks (0 = every CPU of the cluster). Ray is imported only when this backend is
  asked for. Every node of the cluster needs this package installed (same versions), since a
  job names its function by module path. A job's result does not depend on where it runs.

A ``TrialJob`` is everything one trial needs as plain data (so it pickles into a worker):
the source spec (``sim[:q]`` or ``replay:DIR``), the scene (explicit platform classes, or drawn
from the seed), learner preset + overrides, the product's trial settings (``TrialConfig``, no
defaults of the job's own), the seed, and an optional
``perturb`` dict that experiments use to degrade touches (see ``apply_perturbation``).
``run_jobs`` returns one ``TrialResult`` per job in job order: the job, its scene, the engine's
typed ``TrialOutcome`` (platform indices: 0 = the reference, 1..C the comparisons) or, when the
trial failed, the decisions recorded before it. ``TrialResult.to_dict`` is the JSON form (platform
names, ``job`` as a dict, ``decision_s`` per decision, ``wall_s``), only for files.

Each trial runs with ``threads`` torch threads (default 1), so timings within one run are
comparable.
"""

from __future__ import annotations

import argparse
import copy
import dataclasses
import functools
import os
import time
from dataclasses import dataclass, field, replace
from typing import Any, TypeVar
from collections.abc import Callable, Iterator, Sequence

import numpy as np

from tactex_ros.core.config import TrialConfig
from tactex_ros.core.engine import RoundRecord, TrialOutcome, TrialSpec, default_platform_ids
from tactex_ros.core.errors import InputError
from tactex_ros.core.touch import Touch, as_touch
from tactex_ros.sources.perturb import noise_image
from tactex_ros.sources.base import TouchSource
from tactex_lab.experiments.common import progress

T = TypeVar("T")
R = TypeVar("R")
BACKENDS = ("joblib", "ray")
RAY_CHUNK = 4     # jobs per Ray worker between two progress updates


@dataclass(frozen=True)
class Backend:
    """Where jobs run: ``name`` joblib|ray, ``workers`` (0 = every core / every cluster CPU),
    ``address`` of an existing Ray cluster (ray only; None = start a local instance)."""

    name: str = "joblib"
    workers: int = 1
    address: str | None = None

    def __post_init__(self) -> None:
        if self.name not in BACKENDS:
            raise InputError(f"--backend {self.name!r}: choose one of {', '.join(BACKENDS)}")
        if self.workers < 0:
            raise InputError(f"--workers must be >= 0 (0 = all), got {self.workers}")
        if self.address is not None and self.name != "ray":
            raise InputError("--address names a Ray cluster: it needs --backend ray")

    def resolved(self) -> Backend:
        """This backend with ``workers`` 0 made explicit on this machine (joblib: the number of
        cores); a Ray backend keeps 0 (every CPU of the cluster)."""
        if self.name == "joblib" and self.workers == 0:
            return replace(self, workers=default_workers())
        return self


def default_workers() -> int:
    """Worker processes on this machine: one per core."""
    return max(1, os.cpu_count() or 1)


def add_runner_args(p: argparse.ArgumentParser, threads: bool = True) -> None:
    """The runner's options of an experiment command: --workers, --threads, --backend,
    --address, --quiet (read back with ``backend_of``)."""
    p.add_argument("--workers", type=int, default=0,
                   help="parallel jobs (default 0: one per core; with ray: every cluster CPU)")
    if threads:
        p.add_argument("--threads", type=int, default=1, help="torch threads per job")
    p.add_argument("--backend", default="joblib", choices=BACKENDS,
                   help="joblib: processes on this machine; ray: a Ray cluster (--address)")
    p.add_argument("--address", help="Ray cluster address (e.g. auto, ray://head:10001); "
                                     "default: start a local Ray instance")
    p.add_argument("--quiet", action="store_true", help="no progress display")


def backend_of(args: argparse.Namespace) -> Backend:
    """The ``Backend`` of parsed ``add_runner_args`` options."""
    return Backend(args.backend, args.workers, args.address)


def _ray_ready(address: str | None) -> None:
    try:
        import ray
        from ray.util.joblib import register_ray
    except ImportError as exc:
        raise InputError(f"--backend ray needs the ray package ({exc}); pip install "
                         "-r requirements.txt") from None
    if not ray.is_initialized():
        if address:     # an existing cluster: its own settings hold
            ray.init(address=address)
        else:           # a local instance for this run: no dashboard, quiet workers
            ray.init(include_dashboard=False, log_to_driver=False)
    register_ray()


def run_parallel(fn: Callable[[T], R], items: Sequence[T], backend: Backend = Backend(),
                 description: str = "jobs", quiet: bool = False) -> list[R]:
    """``[fn(item) for item in items]`` on ``backend``, in item order, with a progress display.

    ``fn`` must be picklable (a module-level function or a ``functools.partial`` of one) unless
    it runs in this process (joblib with one worker or one item)."""
    import joblib
    items = list(items)
    if backend.name == "joblib":
        n = backend.workers or default_workers()
        if n == 1 or len(items) <= 1:
            return [fn(it) for it in progress(items, description, len(items), quiet)]
        config = dict(backend="loky", n_jobs=min(n, len(items)))
    else:
        _ray_ready(backend.address)
        config = dict(backend="ray", n_jobs=backend.workers or -1)
    with joblib.parallel_config(**config):
        if backend.name == "joblib":   # results stream back in item order as they finish
            results: Iterator[R] = joblib.Parallel(return_as="generator")(
                joblib.delayed(fn)(it) for it in items)
        else:   # joblib's Ray backend returns whole lists: chunks keep the progress moving
            results = _chunks(fn, items, RAY_CHUNK * (backend.workers or 8))
        return list(progress(results, description, len(items), quiet))


def _chunks(fn: Callable[[T], R], items: list[T], size: int) -> Iterator[R]:
    import joblib
    for i in range(0, len(items), size):
        yield from joblib.Parallel()(joblib.delayed(fn)(it) for it in items[i:i + size])


#: The trial settings a job's file form names always, in this order (the rest of
#: ``TrialConfig`` only when it differs from the product's default, so older files stay as they were).
JOB_TRIAL_FIELDS = ("strategy", "rounds", "max_touches", "stop_confidence")


@dataclass
class TrialJob:
    """One trial as plain data. ``trial`` is the product's ``TrialConfig`` and ``preset`` a
    learner preset of ``core/config.PRESETS`` (with ``overrides`` on top): a job has no
    trial defaults of its own, so an experiment that wants another than the shipped method
    (e.g. variance touches, no stop) says so where it makes the job."""

    source: str                                   # "sim:0.5", "replay:/path"
    seed: int
    trial: TrialConfig
    preset: str
    overrides: dict[str, Any] = field(default_factory=dict)
    platform_classes: list[str] | None = None     # [reference, comp 1..C]; None = draw
    comparisons: int = 4                          # used when drawing the scene
    trial_id: str = ""
    perturb: dict[str, Any] = field(default_factory=dict)
    tags: dict[str, Any] = field(default_factory=dict)   # free labels carried to the result
    catch_errors: bool = False    # a trial that raises gives a result with "error" (not a crash)
    no_contact_reference: bool = True   # give the engine a no-contact frame when the source can
    # judge every touch with the contact guard against its own no-contact frame, as on the
    # robot (a recorded press without contact fails and is pressed again; core.guards)
    contact_guard: bool = False

    def to_dict(self) -> dict[str, Any]:
        """The file form (results, caches): the job's fields with its trial settings in their
        place, ``JOB_TRIAL_FIELDS`` always and any other ``TrialConfig`` field that is not the
        default; ``contact_guard`` only when on (a file of an earlier job reads the same)."""
        given, shipped = self.trial.model_dump(), TrialConfig().model_dump()
        out: dict[str, Any] = {}
        for f in dataclasses.fields(self):
            if f.name == "trial":
                out.update({k: given[k] for k in JOB_TRIAL_FIELDS})
                out.update({k: v for k, v in given.items()
                            if k not in JOB_TRIAL_FIELDS and v != shipped[k]})
            elif f.name != "contact_guard" or self.contact_guard:   # new: named when on
                out[f.name] = copy.deepcopy(getattr(self, f.name))
        return out


_SOURCES: dict[str, TouchSource] = {}


def cached_source(spec: str) -> TouchSource:
    """The touch source of ``spec``, opened once per process (jobs of a sweep share it)."""
    if spec not in _SOURCES:
        from tactex_ros.sources import open_source
        _SOURCES[spec] = open_source(spec)
    return _SOURCES[spec]


def scene(job: TrialJob) -> tuple[list[str], int]:
    """Platform classes [reference, comparisons...] and the true match (1..C) of a job."""
    if job.platform_classes is not None:
        comps = list(job.platform_classes[1:])
        ref = job.platform_classes[0]
        if ref not in comps:
            raise InputError(f"trial {job.trial_id!r}: reference {ref!r} is not among the "
                             f"comparisons {comps}")
        return [ref] + comps, comps.index(ref) + 1
    from tactex_ros.sources import trial_scene
    return trial_scene(cached_source(job.source), job.comparisons, job.seed)


def apply_perturbation(img: np.ndarray, perturb: dict[str, Any],
                       rng: np.random.Generator) -> np.ndarray:
    """Degrade one (240, 320, 3) uint8 touch.

    Keys (all optional): ``noise`` extra Gaussian sensor noise std [grey levels];
    ``drift`` lighting drift, a random per-channel offset with this std [grey levels];
    ``blank`` probability that the touch is a flat no-contact frame (mean colour of the image).
    (The perturbations of whole touches on a severity axis are ``perturb["touch"]``, see
    ``_touch_fn`` and ``tactex_ros.sources.perturb``.)
    """
    out = img.astype(np.float32)
    if perturb.get("blank", 0.0) and rng.random() < perturb["blank"]:
        out[:] = out.reshape(-1, 3).mean(axis=0)
        out += rng.normal(0.0, 1.0, out.shape)
    if perturb.get("drift", 0.0):
        out += rng.normal(0.0, perturb["drift"], 3).astype(np.float32)
    if perturb.get("noise", 0.0):
        out = noise_image(out, perturb["noise"], rng)
    return np.clip(out, 0, 255).astype(np.uint8)


def _touch_fn(job: TrialJob, classes: list[str]) -> Callable[[int], Touch]:
    """The job's touch function: its source's, perturbed as ``job.perturb`` says, and with
    ``job.contact_guard`` refused (``TouchFailed``: the engine presses again) where the
    learner's contact guard finds no contact against the touch's own no-contact frame. Keys:
    ``depth_spread`` (the source's), ``touch`` = [kind, severity] (every touch of the trial
    through ``sources.perturb.Perturbation``, seeded by the job's seed), and the frame
    perturbations of ``apply_perturbation``."""
    base = cached_source(job.source).trial(classes, job.seed, job.perturb.get("depth_spread"))
    whole: Callable[[int], Touch] = base
    if job.perturb.get("touch"):
        from tactex_ros.sources.perturb import Perturbation
        kind, severity = job.perturb["touch"]
        per = Perturbation(kind, severity, job.seed)

        def whole(p: int) -> Touch:
            return per(as_touch(base(p)))
    keys = {k for k, v in job.perturb.items() if k not in ("depth_spread", "touch") and v}
    out = whole
    if keys:
        rng = np.random.default_rng([job.seed, 31])

        def out(p: int) -> Touch:
            t = as_touch(whole(p))
            return replace(t, frame=apply_perturbation(t.frame, job.perturb, rng))
    if not job.contact_guard:
        return out
    from tactex_ros.core.config import preset
    from tactex_ros.core.engine import refusing_no_contact
    return refusing_no_contact(out, preset(job.preset, **job.overrides))


@dataclass
class TrialResult:
    """One job's trial: ``classes`` [reference, comparisons...], ``truth`` (1..C), every
    decision (``RoundRecord``, the final one last; platform indices), the engine's ``outcome``
    (None when the trial failed: ``error`` says why and ``decisions`` holds what was decided
    before), failed touches, total touches and wall time [s]."""

    job: TrialJob
    classes: list[str]
    truth: int
    decisions: list[RoundRecord]
    outcome: TrialOutcome | None
    failed_touches: list[dict]
    touches: int
    wall_s: float
    error: str | None = None

    @property
    def correct(self) -> bool:
        return self.outcome is not None and bool(self.outcome.correct)

    @property
    def prediction(self) -> int | None:
        """The predicted comparison (1..C), None when the trial failed."""
        return None if self.outcome is None else self.outcome.prediction

    def to_dict(self) -> dict:
        """The JSON form (platform names) of result files and caches."""
        job = self.job.to_dict()
        decision_s = [r.decision_s for r in self.decisions]
        if self.outcome is None:
            return {"correct": False, "prediction": None,
                    "truth": default_platform_ids(len(self.classes) - 1)[self.truth], "touches": self.touches,
                    "rounds": [{**dataclasses.asdict(r), "decision_s": r.decision_s}
                               for r in self.decisions],
                    "final": None, "failed_touches": list(self.failed_touches),
                    "error": self.error, "job": job, "classes": self.classes,
                    "truth_index": self.truth, "prediction_index": None,
                    "decision_s": decision_s, "wall_s": self.wall_s}
        out = self.outcome.to_dict()
        out.update(job=job, classes=self.classes, truth_index=self.truth,
                   prediction_index=self.outcome.prediction, decision_s=decision_s,
                   wall_s=self.wall_s)
        return out


def run_job(job: TrialJob, threads: int = 1) -> TrialResult:
    """Run one trial; returns its ``TrialResult`` (a failed trial's: the decisions its engine
    recorded before it failed, when ``job.catch_errors``)."""
    import torch

    from tactex_ros.core.config import preset
    if threads:
        torch.set_num_threads(threads)
    classes, truth = scene(job)
    n = len(classes) - 1
    cfg = preset(job.preset, **job.overrides)
    src = cached_source(job.source)
    no_contact = src.no_contact(job.seed) if job.no_contact_reference else None
    spec = TrialSpec(n, cfg, job.trial, seed=job.seed, no_contact=no_contact)
    eng = spec.engine()
    t0 = time.perf_counter()
    try:
        res = eng.run(_touch_fn(job, classes), truth=truth)
    except (InputError, FloatingPointError, RuntimeError) as exc:
        if not job.catch_errors:
            raise
        return TrialResult(job, classes, truth, list(eng.records), None, list(eng.failed),
                           eng.total_touches, time.perf_counter() - t0,
                           error=f"{type(exc).__name__}: {exc}")
    return TrialResult(job, classes, truth, res.rounds + [res.final], res, res.failed_touches,
                       res.touches, time.perf_counter() - t0)


def run_jobs(jobs: list[TrialJob], backend: Backend = Backend(), threads: int = 1,
             description: str = "trials", quiet: bool = False) -> list[TrialResult]:
    """Run ``jobs`` on ``backend`` (``threads`` torch threads each), results in job order."""
    return run_parallel(functools.partial(run_job, threads=threads), jobs, backend,
                        description, quiet)
