"""A real GelSight sensor's optical calibration, read from the installed ``taxim`` package.

PyPI's ``taxim`` (MIT licence, pinned in requirements.txt) ships the calibration of a GelSight
Mini recorded by pressing a ball into the gel (``taxim/calib/gelsight_mini``, 640x480 px at
0.0295 mm/px):

- ``polycalib.npz``: for every bin of surface slope (``num_bins`` bins of the slope angle
  atan|grad z| over [0, pi/2]) and of slope direction (``num_bins`` bins of atan2 over
  [-pi, pi]), per colour channel, six coefficients of a quadratic in the pixel position
  (x^2, y^2, xy, x, y, 1) giving the channel's intensity [grey levels];
- ``dataPack.npz``: the recorded frames; ``f0`` is the sensor without contact (BGR, uint8);
- ``params.json``: the sensor's resolution and the number of bins;
- ``shadowTable.npz`` (shadows at the edge of tall objects) and ``gelmap.npy`` (the gel's
  shape; flat for the Mini) are not used here: fabric relief is below 1 mm and the shadow
  table is stored as pickled object arrays, which this loader does not unpickle.

Conventions (as the package's own renderer reads these files): the files' ``grad_r`` and
``grad_b`` are swapped (``grad_b`` drives the red channel); the slope direction is
atan2(dz/drow, dz/dcol) of the gel's indentation. Nothing is downloaded: a missing package or
file is an error naming it.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path

import cv2
import numpy as np

from ..core.errors import InputError

SENSORS = ("gelsight_mini", "gelsight")


def calibration_dir(sensor: str = "gelsight_mini") -> Path:
    """Folder of a sensor's calibration inside the installed ``taxim`` package."""
    if sensor not in SENSORS:
        raise InputError(f"sensor calibration {sensor!r}: choose one of {', '.join(SENSORS)}")
    try:
        from taxim.calibration import CALIB_ROOT
    except ImportError as exc:
        raise InputError("the simulator's optics need the 'taxim' package (pinned in "
                         "requirements.txt): pip install -r requirements.txt") from exc
    folder = Path(CALIB_ROOT) / sensor
    for name in ("polycalib.npz", "dataPack.npz", "params.json"):
        if not (folder / name).is_file():
            raise InputError(f"taxim calibration file missing: {folder / name}")
    return folder


@dataclass(frozen=True)
class OpticalCalibration:
    """Calibration resampled to an output frame of (H, W) pixels.

    ``background``: (H, W, 3) float32 RGB, the sensor without contact [grey levels].
    ``table``: (num_bins * num_bins, 3, 6) float32 polynomial coefficients, row = slope bin *
    num_bins + direction bin.
    ``features``: (H * W, 6) float32 (x^2, y^2, xy, x, y, 1) at the output pixels, in the
    calibration's pixel coordinates.
    ``flat``: (H * W, 3) float32 the polynomial's value for a flat gel (slope bin 0); a contact
    adds ``poly - flat`` to the background.
    ``num_bins``: bins per axis of the table; ``calib_mm_per_px``, ``calib_shape`` of the source.
    """

    background: np.ndarray
    table: np.ndarray
    features: np.ndarray
    flat: np.ndarray
    num_bins: int
    calib_mm_per_px: float
    calib_shape: tuple[int, int]
    source: str


@lru_cache(maxsize=4)
def load_calibration(sensor: str = "gelsight_mini", shape: tuple[int, int] = (240, 320)
                     ) -> OpticalCalibration:
    """Read a taxim calibration and resample it to frames of ``shape`` = (H, W) pixels."""
    folder = calibration_dir(sensor)
    try:
        params = json.loads((folder / "params.json").read_text())["sensor"]
        ch, cw, nb = int(params["h"]), int(params["w"]), int(params["num_bins"])
        pixmm = float(params["pixmm"])
        with np.load(folder / "polycalib.npz", allow_pickle=False) as poly:
            # red <- grad_b, blue <- grad_r (see the module docstring)
            table = np.stack([poly["grad_b"], poly["grad_g"], poly["grad_r"]], axis=2)
        with np.load(folder / "dataPack.npz", allow_pickle=False) as pack:
            f0 = np.asarray(pack["f0"])
    except (OSError, KeyError, ValueError, json.JSONDecodeError) as exc:
        raise InputError(f"taxim calibration in {folder} unreadable: {exc}") from exc
    if table.shape != (nb, nb, 3, 6) or f0.shape != (ch, cw, 3):
        raise InputError(f"taxim calibration in {folder}: unexpected shapes {table.shape}, "
                         f"{f0.shape} for {nb} bins and {cw}x{ch} px")
    # Slope bin 0 holds slopes below 0.7 deg, where the direction is meaningless: its rows
    # differ by direction by ~1.5 grey levels (fit noise), which would paint a flat gel with
    # direction noise. They are replaced by their mean over directions (= the flat gel).
    table = table.copy()
    table[0] = table[0].mean(axis=0, keepdims=True)
    h, w = shape
    bg = cv2.resize(f0[..., ::-1].astype(np.float32), (w, h), interpolation=cv2.INTER_AREA)
    ys = (np.arange(h, dtype=np.float64) + 0.5) * ch / h - 0.5
    xs = (np.arange(w, dtype=np.float64) + 0.5) * cw / w - 0.5
    yy, xx = np.meshgrid(ys, xs, indexing="ij")
    feats = np.stack([xx * xx, yy * yy, xx * yy, xx, yy, np.ones_like(xx)], -1).reshape(-1, 6)
    flat = np.einsum("nk,ck->nc", feats, table[0, 0])
    return OpticalCalibration(
        background=np.ascontiguousarray(bg, np.float32),
        table=np.ascontiguousarray(table.reshape(nb * nb, 3, 6), np.float32),
        features=np.ascontiguousarray(feats, np.float32), flat=flat.astype(np.float32),
        num_bins=nb, calib_mm_per_px=pixmm, calib_shape=(ch, cw), source=str(folder))
