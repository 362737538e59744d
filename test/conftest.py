"""Shared test helpers: where the shared fixtures and recordings live (never copied in-repo), and
the lanes: every test under ``test/lab/`` is marked ``lab`` (the thesis lab: CNN training, Ray),
every test under ``test/ros/`` and ``test/launch/`` ``ros`` (real processes), so
``make test-fast`` (``-m "not slow and not ros and not lab"`` over ``test/unit``) runs the
product's pure tests and ``make test`` runs everything but the ``soak`` tests (``make
test-soak``: long property and cluster runs).

``make test`` runs three workers (on two cores), a file per worker at a time: the files of real processes (the
longest) are handed out first, so that the many short files fill the end of the run instead of
one worker finishing a long graph test while the others wait (``--no-loadscope-reorder``)."""

from __future__ import annotations

import os
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]

# One OpenMP / BLAS thread per process, set before torch or numpy load their thread pools:
# `make test` runs three workers on two cores beside the graph tests' node processes (which
# inherit it), and a pool of a thread per core spins against them (measured: the CNN ladder
# test took 117 s beside a graph test, 5 s alone). An exported value is kept.
for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")


def _shared(rel: str) -> Path | None:
    """First existing of $TACTEX_SHARED/rel, <repo>/../shared/rel, /work/shared/rel."""
    roots = [os.environ.get("TACTEX_SHARED"), REPO.parent / "shared", "/work/shared"]
    for r in roots:
        if r and (Path(r) / rel).exists():
            return Path(r) / rel
    return None


@pytest.fixture(scope="session")
def octopi_dir() -> Path:
    p = _shared("datasets/octopi-dev")
    if p is None:
        pytest.skip("octopi-dev recordings not found (set TACTEX_SHARED)")
    return p


@pytest.fixture(scope="session")
def keys_fixture() -> Path:
    p = _shared("fixtures/inception_v3_torchvision_keys.json")
    if p is None:
        pytest.skip("inception_v3_torchvision_keys.json not found (set TACTEX_SHARED)")
    return p


_LANES = {"lab": "lab", "ros": "ros", "launch": "ros"}
#: the order the lanes are run in (the longest tests first; see the module doc)
_FIRST = {"ros": 0, "lab": 1}


def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    """Mark each test by the folder below ``test/`` it lives in (``_LANES``) and put the
    lanes in ``_FIRST`` order (stable: the files' own order is kept within a lane)."""
    lane: dict[int, int] = {}
    for item in items:
        rel = Path(str(item.fspath)).resolve().relative_to(REPO / "test")
        marker = _LANES.get(rel.parts[0]) if len(rel.parts) > 1 else None
        if marker is not None:
            item.add_marker(marker)
        lane[id(item)] = _FIRST.get(marker or "", len(_FIRST))
    items.sort(key=lambda it: lane[id(it)])


@pytest.fixture(scope="session")
def octopi_press(octopi_dir):
    """``octopi_press(material, index=0)``: the frames of one recorded octopi-dev press
    (``material/index.mov``), sensor-sized RGB uint8 (F, 240, 320, 3), read in place (never
    copied into the repository)."""
    from tactex_ros.sources.replay import read_video

    def load(material: str, index: int = 0):
        path = octopi_dir / material / f"{index}.mov"
        if not path.is_file():
            pytest.skip(f"octopi-dev press {material}/{index}.mov not found")
        return read_video(path)[..., ::-1].copy()
    return load


@pytest.fixture(scope="session")
def held_press(octopi_dir):
    """``held_press(path, material)``: write a press video without contact at ``path`` (.avi):
    the first frame of ``material``'s first octopi-dev press, held for 9 frames."""
    import cv2

    from tactex_ros.sources.replay import read_video

    def write(path: Path, material: str) -> Path:
        first = read_video(sorted((octopi_dir / material).glob("*.mov"))[0])[0]
        w = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*"MJPG"), 25, (320, 240))
        for _ in range(9):
            w.write(first)
        w.release()
        return path
    return write


@pytest.fixture(scope="session")
def _trial_record_root(tmp_path_factory) -> Path:
    return tmp_path_factory.mktemp("trial_records")


@pytest.fixture(autouse=True)
def _trial_records_in_tmp(monkeypatch, _trial_record_root):
    """``tactex trial`` without ``--record-dir`` records under runs/trials of the working
    folder (the checkout, in a test run): a test's records go to a temporary folder instead."""
    import tactex_ros.cli.main as cli
    monkeypatch.setattr(cli, "DEFAULT_RECORD_DIR", str(_trial_record_root))
