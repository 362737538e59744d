"""Shared experiment plumbing: results folder, reproducibility record, progress display, the
``--set`` parser and the accuracy-at-budget reader."""

from __future__ import annotations

import platform
import sys
import time
from pathlib import Path
from typing import Any, TypeVar
from collections.abc import Iterable, Iterator, Sequence

import numpy as np

T = TypeVar("T")


def versions() -> dict[str, str]:
    """Versions of the libraries that change results."""
    import scipy
    import sklearn
    import torch
    return {"python": platform.python_version(), "torch": torch.__version__,
            "numpy": np.__version__, "scipy": scipy.__version__, "sklearn": sklearn.__version__,
            "machine": platform.machine()}


def write_json(path: Path, obj: Any) -> Path:
    """Write ``obj`` as strict indented JSON, atomically (numpy values converted, NaN ->
    null: ``core.outputs``); returns ``path``."""
    from tactex_ros.core.outputs import write_json as _write
    return _write(path, obj)


def git_commit() -> str | None:
    """Commit of the source tree the code runs from ('+dirty' if modified), None if unknown."""
    import subprocess
    root = Path(__file__).resolve().parents[2]
    try:
        head = subprocess.run(["git", "-C", str(root), "rev-parse", "HEAD"], capture_output=True,
                              text=True, timeout=10)
        dirty = subprocess.run(["git", "-C", str(root), "status", "--porcelain",
                                "--untracked-files=no"], capture_output=True, text=True,
                               timeout=10)
    except (OSError, subprocess.SubprocessError):
        return None
    if head.returncode != 0:
        return None
    return head.stdout.strip() + ("+dirty" if dirty.stdout.strip() else "")


def parse_set(items: list[str] | None, option: str = "--set",
              trial: tuple[str, ...] = ()) -> dict[str, Any]:
    """``learner.PATH=VALUE`` items (the product's one override syntax,
    ``tactex_ros.core.schema.overrides``) -> nested overrides ``{"learner": {...}}``, plus
    ``{"trial": {...}}`` for the trial settings named in ``trial`` (those the experiment
    uses). Another ``trial.*`` path is refused, naming ``option``."""
    from tactex_ros.core.config import TrialSettings
    from tactex_ros.core.schema import overrides
    from tactex_ros.core.errors import InputError
    out = overrides(TrialSettings, items, option)
    extra = sorted(set(out) - {"learner", "trial"}) + sorted(
        f"trial.{k}" for k in out.get("trial", {}) if k not in trial)
    if extra:
        raise InputError(f"{option} {', '.join(extra)}: not taken here (learner.* settings"
                         + (f" and {', '.join('trial.' + t for t in trial)}" if trial else "")
                         + " are)")
    return out


def learner_set(items: list[str] | None, option: str = "--set") -> dict[str, Any]:
    """``parse_set`` for an experiment that takes learner settings only: the learner's
    overrides as keyword arguments of ``preset``."""
    return parse_set(items, option).get("learner", {})


def results_dir(out: str | None, name: str, config: dict) -> Path:
    """Create the results folder and record the run's configuration and library versions."""
    from tactex_ros.core.outputs import check_dir
    d = check_dir(Path(out) if out else Path("results") / name, "--out")
    d.mkdir(parents=True, exist_ok=True)
    write_json(d / "config.json", {"experiment": name, "argv": sys.argv, "config": config,
                                   "versions": versions(), "git_commit": git_commit(),
                                   "started": time.strftime("%Y-%m-%dT%H:%M:%S%z")})
    return d


def progress(items: Iterable[T], description: str, total: int | None = None,
             quiet: bool = False) -> Iterator[T]:
    """Iterate with a rich progress bar on stderr (plain iteration when ``quiet``)."""
    if quiet:
        yield from items
        return
    if not sys.stderr.isatty():  # logs and pipes: a plain line every 10 s instead of a bar
        n = total if total is not None else (len(items) if hasattr(items, "__len__") else None)
        t0 = last = time.monotonic()
        for k, it in enumerate(items, 1):
            yield it
            now = time.monotonic()
            if now - last >= 10.0 or k == n:
                last = now
                print(f"{description}: {k}/{n if n is not None else '?'} done, "
                      f"{now - t0:.0f} s", file=sys.stderr, flush=True)
        return
    from rich.console import Console
    from rich.progress import (BarColumn, MofNCompleteColumn, Progress, TextColumn,
                               TimeElapsedColumn, TimeRemainingColumn)
    cols = (TextColumn("{task.description}"), BarColumn(), MofNCompleteColumn(),
            TimeElapsedColumn(), TimeRemainingColumn())
    with Progress(*cols, console=Console(stderr=True), transient=False) as bar:
        task = bar.add_task(description, total=total if total is not None else
                            (len(items) if hasattr(items, "__len__") else None))
        for it in items:
            yield it
            bar.advance(task)


def budget_index(counts: Sequence[int], k: int) -> int:
    """Which decision a run capped at ``k`` touches ends with, from the touch counts at which the
    full run made its decisions (non-decreasing): the first made with ``>= k`` touches, or the
    last one when the run ended first. -1 for no decisions.

    A capped run is, touch for touch, the full run until it reaches ``k`` touches, where it
    makes its final decision."""
    for i, n in enumerate(counts):
        if n >= k:
            return i
    return len(counts) - 1


def decision_at_budget(decisions: Sequence[dict], k: int) -> dict:
    """The decision (``{"total": touches, ...}``) a run capped at ``k`` total touches ends with
    (see ``budget_index``); ``decisions`` must not be empty."""
    if not decisions:
        raise ValueError("no decisions to read a budget from")
    return decisions[budget_index([d["total"] for d in decisions], k)]


def correct_at(decisions: Sequence[dict], truth: int, k: int) -> bool:
    """Was the decision a run capped at ``k`` total touches ends with right (argmax of its
    ``probs`` is comparison ``truth``, 1..C)? False for no decisions."""
    if not decisions:
        return False
    return int(np.argmax(decision_at_budget(decisions, k)["probs"])) + 1 == truth
