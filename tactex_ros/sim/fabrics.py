"""Procedural fabric height maps (mm) from construction families with physical parameters.

Families: ``plain``, ``twill``, ``satin``, ``basket`` (woven; warp along y, weft along x, an
interlacing matrix of period ``repeat``), ``rib`` and ``jersey`` (knits: wales of loops),
``corduroy`` (cut-pile wales) and ``felt`` (random fibres). Parameters (``FabricParams``):

- ``pitch_mm``: yarn (or wale, or fibre) spacing [mm]
- ``yarn_width``: yarn width as a fraction of the pitch [0.2, 1.2]
- ``yarn_height_mm``: yarn relief [mm]
- ``twist``: strength of the diagonal fibre striation of twisted yarns [0, 1]
- ``irregularity``: random variation of yarn position, width and height [0, 1]
- ``fuzz``: hairiness: fine random fibres over the structure [0, 1]
- ``repeat``: weave repeat (twill >= 3, satin >= 5, basket = yarns per group) [1, 8]
- ``softness``: share of the relief a press flattens [0, 1] (0 = rigid weave, ~0.9 = fleece:
  it presses almost flat and leaves a faint contact image)

``height_tile`` renders a square tile at the sensor's scale (mm per pixel); the simulator caches
it per fabric and cuts every touch out of it at a random position and rotation.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Literal

import cv2
import numpy as np
from pydantic import create_model, model_validator

from ..core.schema import FieldError, Schema, param
from ..core.errors import InputError
from ..core.paths import read_yaml

FAMILIES = ("plain", "twill", "satin", "basket", "rib", "jersey", "corduroy", "felt")
WOVEN = ("plain", "twill", "satin", "basket")

# (lo, hi) of every numeric parameter; also the scale used for parameter distances.
RANGES: dict[str, tuple[float, float]] = {
    "pitch_mm": (0.1, 4.5),
    "yarn_width": (0.2, 1.2),
    "yarn_height_mm": (0.02, 1.0),
    "twist": (0.0, 1.0),
    "irregularity": (0.0, 1.0),
    "fuzz": (0.0, 1.0),
    "repeat": (1, 8),
    "softness": (0.0, 1.0),
}


@dataclass(frozen=True)
class FabricParams:
    family: str
    pitch_mm: float
    yarn_width: float = 0.8
    yarn_height_mm: float = 0.2
    twist: float = 0.3
    irregularity: float = 0.2
    fuzz: float = 0.1
    repeat: int = 1
    softness: float = 0.2

    def check(self, where: str = "fabric") -> FabricParams:
        """These parameters within their ranges and their family's rules; InputError names the
        field as ``where.field``."""
        if self.family not in FAMILIES:
            raise InputError(f"{where}.family: {self.family!r} is not one of "
                             f"{', '.join(FAMILIES)}")
        for name, (lo, hi) in RANGES.items():
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not np.isfinite(v):
                raise InputError(f"{where}.{name}: expected a number, got {v!r}")
            if not lo <= v <= hi:
                raise InputError(f"{where}.{name}: {v} outside [{lo}, {hi}]")
        if self.family == "twill" and self.repeat < 3:
            raise InputError(f"{where}.repeat: twill needs repeat >= 3, got {self.repeat}")
        if self.family == "satin" and self.repeat < 5:
            raise InputError(f"{where}.repeat: satin needs repeat >= 5, got {self.repeat}")
        return self

    def vector(self) -> np.ndarray:
        """Normalised numeric parameters in [0, 1] (log scale for pitch and height)."""
        out = []
        for name, (lo, hi) in RANGES.items():
            v = float(getattr(self, name))
            if name in ("pitch_mm", "yarn_height_mm"):
                out.append((np.log(v) - np.log(lo)) / (np.log(hi) - np.log(lo)))
            else:
                out.append((v - lo) / (hi - lo))
        return np.array(out)

    @staticmethod
    def from_vector(family: str, vec: np.ndarray) -> FabricParams:
        kw: dict[str, Any] = {}
        for (name, (lo, hi)), x in zip(RANGES.items(), np.clip(vec, 0, 1), strict=True):
            if name in ("pitch_mm", "yarn_height_mm"):
                kw[name] = float(np.exp(np.log(lo) + x * (np.log(hi) - np.log(lo))))
            elif name == "repeat":
                kw[name] = int(round(lo + x * (hi - lo)))
            else:
                kw[name] = float(lo + x * (hi - lo))
        if family == "twill":
            kw["repeat"] = max(3, kw["repeat"])
        if family == "satin":
            kw["repeat"] = max(5, kw["repeat"])
        return FabricParams(family=family, **kw)


# ------------------------------------------------------------------------------ catalogue

def _entry_schema() -> type[Schema]:
    """The schema of one catalogue entry: ``name``, optional ``number`` and ``note``, and the
    fields of ``FabricParams`` with their defaults and ``RANGES`` (one declaration of them)."""
    spec: dict[str, Any] = {
        "name": (str, param(..., "fabric name (unique)", min_length=1)),
        "number": (int | None, param(None, "number of the thesis's set", 1)),
        "note": (str, param("", "free text")),
        "family": (Literal[FAMILIES], param(..., "construction family")),
    }
    for f in dataclasses.fields(FabricParams):
        if f.name in RANGES:
            lo, hi = RANGES[f.name]
            kind = int if f.name == "repeat" else float
            default = ... if f.default is dataclasses.MISSING else f.default
            spec[f.name] = (kind, param(default, f.name, lo, hi, allow_inf_nan=False)
                            if kind is float else param(default, f.name, lo, hi))
    return create_model("FabricEntry", __base__=Schema, **spec)


FabricEntry = _entry_schema()


class Catalogue(Schema):
    """The catalogue file: ``fabrics``, a non-empty list of entries with unique names."""

    fabrics: list[FabricEntry] = param(..., "the fabrics", min_length=1)  # type: ignore[valid-type]

    @model_validator(mode="after")
    def _unique_and_consistent(self) -> Catalogue:
        seen: set[str] = set()
        for i, e in enumerate(self.fabrics):
            if e.name in seen:
                raise FieldError(f"fabrics.{i}.name", f"duplicate fabric name {e.name!r}")
            seen.add(e.name)
            try:
                _params(e).check("fabric")
            except InputError as exc:      # a family's own rule (twill / satin repeat)
                field, _, msg = str(exc).partition(": ")
                raise FieldError(f"fabrics.{i}.{field.rpartition('.')[2]}", msg) from None
        return self


def _params(entry: Any) -> FabricParams:
    return FabricParams(**entry.model_dump(exclude={"name", "number", "note"}))


def load_catalogue(path: str | Path) -> dict[str, FabricParams]:
    """Read the fabric catalogue YAML (list of {name, family, parameters...}); validate it
    (errors located like ``fabrics.2.pitch_mm``)."""
    p = Path(path)
    if not p.is_file():
        raise InputError(f"fabric catalogue not found: {p}")
    cat = Catalogue.check(read_yaml(p, "fabric catalogue"), f"fabric catalogue {p.name}")
    return {e.name: _params(e) for e in cat.fabrics}


# ------------------------------------------------------------------------------ height maps

def _profile(d: np.ndarray) -> np.ndarray:
    """Elliptical yarn cross-section: d = offset / half-width; 1 at the axis, 0 at the edge."""
    return np.sqrt(np.clip(1.0 - d * d, 0.0, 1.0))


def _smooth_noise(shape: tuple[int, int], sigma: float, rng: np.random.Generator) -> np.ndarray:
    """Zero-mean, unit-std Gaussian-filtered noise (periodic-free), sigma in px."""
    n = rng.standard_normal(shape).astype(np.float32)
    if sigma > 0.3:
        n = cv2.GaussianBlur(n, (0, 0), sigma, borderType=cv2.BORDER_REFLECT)
    return n / (n.std() + 1e-9)


def _weave_matrix(family: str, repeat: int) -> np.ndarray:
    """R x R matrix, 1 where the warp (vertical) yarn is on top."""
    if family == "plain":
        return np.array([[1, 0], [0, 1]])
    if family == "basket":
        g = max(2, repeat)
        base = np.array([[1, 0], [0, 1]])
        return np.kron(base, np.ones((g, g), dtype=int))
    r = max(3, repeat)
    m = np.zeros((r, r), dtype=int)
    step = 1 if family == "twill" else _satin_step(r)
    for j in range(r):
        m[j, (j * step) % r] = 1
        if family == "twill":  # 2/1, 2/2 ... twills: warp floats over half the repeat
            for k in range(1, r // 2):
                m[j, (j * step + k) % r] = 1
    return m


def _satin_step(r: int) -> int:
    for s in range(2, r - 1):
        if np.gcd(s, r) == 1:
            return s
    return 2


def height_tile(fab: FabricParams, size: int, mm_per_px: float, seed: int) -> np.ndarray:
    """(size, size) float32 height map in mm, max ~ relief; deterministic in ``seed``."""
    rng = np.random.default_rng(seed)
    pitch = fab.pitch_mm / mm_per_px                      # px per yarn
    yy, xx = np.mgrid[0:size, 0:size].astype(np.float32)
    irr = fab.irregularity
    # low-frequency warping of the yarn grid (irregularity)
    wx = _smooth_noise((size, size), 3 * pitch, rng) * irr * 0.25 * pitch
    wy = _smooth_noise((size, size), 3 * pitch, rng) * irr * 0.25 * pitch
    u = (xx + wx) / pitch
    v = (yy + wy) / pitch
    half_w = np.clip(fab.yarn_width, 0.2, 1.2) / 2.0
    h_rel = fab.yarn_height_mm
    height_var = 1.0 + irr * 0.3 * _smooth_noise((size, size), 2 * pitch, rng)

    if fab.family in WOVEN:
        m = _weave_matrix(fab.family, fab.repeat).astype(np.float32)
        r = m.shape[0]
        iu = np.floor(u).astype(np.int64)
        iv = np.floor(v).astype(np.int64)
        du = u - iu - 0.5
        dv = v - iv - 0.5
        # smooth undulation of warp/weft along their length between crossings
        top = m[iv % r, iu % r]
        top_next_v = m[(iv + np.where(dv > 0, 1, -1)) % r, iu % r]
        blend_v = np.abs(dv)  # 0 at the crossing centre, 0.5 at the boundary
        warp_lift = top * (1 - blend_v) + 0.5 * (top + top_next_v) * blend_v
        top_next_u = m[iv % r, (iu + np.where(du > 0, 1, -1)) % r]
        blend_u = np.abs(du)
        weft_lift = (1 - top) * (1 - blend_u) + 0.5 * ((1 - top) + (1 - top_next_u)) * blend_u
        warp = _profile(du / half_w) * (0.35 + 0.65 * warp_lift)
        weft = _profile(dv / half_w) * (0.35 + 0.65 * weft_lift)
        h = np.maximum(warp, weft)
        # twisted yarn striation (diagonal to the yarn axis)
        along_warp = v * 6.0 + du * 6.0 * (0.5 + fab.twist)
        along_weft = u * 6.0 + dv * 6.0 * (0.5 + fab.twist)
        stri = np.where(warp >= weft, np.sin(2 * np.pi * along_warp),
                        np.sin(2 * np.pi * along_weft))
        h = h * (1.0 + 0.25 * fab.twist * stri)
    elif fab.family in ("rib", "jersey"):
        # wales of V-shaped loops along y; rib: alternating raised / sunken wales
        iu = np.floor(u).astype(np.int64)
        du = u - iu - 0.5
        course = v * (1.0 if fab.family == "jersey" else 1.6)
        side = np.sign(du)
        # each half-wale is a leg of the V, slanted +-35 deg, with periodic loop heads
        leg = (np.abs(du) - 0.25) / 0.25
        phase = course + side * du * 0.7
        loop = 0.6 + 0.4 * np.cos(2 * np.pi * phase)
        h = _profile(leg / max(half_w, 0.3) * 1.2) * loop
        if fab.family == "rib":
            h = h * np.where(iu % 2 == 0, 1.0, 0.45)
        stri = np.sin(2 * np.pi * (phase * 5.0 + du * 4.0 * fab.twist))
        h = h * (1.0 + 0.2 * fab.twist * stri)
    elif fab.family == "corduroy":
        iu = np.floor(u).astype(np.int64)
        du = u - iu - 0.5
        h = _profile(du / max(half_w, 0.3)) ** 0.6
        pile = _smooth_noise((size, size), 0.8, rng)
        h = h * (1.0 + 0.15 * pile)
    else:  # felt: random fibres, overlapping strokes of length ~ 4 pitch
        h = np.zeros((size, size), np.float32)
        n_fibres = int(size * size / (pitch * pitch) * 1.5) + 20
        pts = rng.uniform(0, size, (n_fibres, 2))
        ang = rng.uniform(0, np.pi, n_fibres)
        length = pitch * rng.uniform(2.0, 6.0, n_fibres)
        thick = max(1, int(round(pitch * half_w * 0.5)))
        for (x0, y0), a, L in zip(pts, ang, length, strict=True):
            x1, y1 = x0 + L * np.cos(a), y0 + L * np.sin(a)
            cv2.line(h, (int(x0), int(y0)), (int(x1), int(y1)),
                     float(rng.uniform(0.5, 1.0)), thick, cv2.LINE_AA)
        h = cv2.GaussianBlur(h, (0, 0), max(0.6, thick * 0.6))
        h = h / (h.max() + 1e-9)

    h = h.astype(np.float32) * height_var
    if fab.fuzz > 0:
        fine = np.abs(_smooth_noise((size, size), 0.7, rng))
        fibres = np.zeros((size, size), np.float32)
        n_hairs = int(400 * fab.fuzz * (size / 512) ** 2)
        pts = rng.uniform(0, size, (n_hairs, 2))
        ang = rng.uniform(0, 2 * np.pi, n_hairs)
        for (x0, y0), a in zip(pts, ang, strict=True):
            L = rng.uniform(8, 30)
            cv2.line(fibres, (int(x0), int(y0)),
                     (int(x0 + L * np.cos(a)), int(y0 + L * np.sin(a))), 1.0, 1, cv2.LINE_AA)
        h = h + fab.fuzz * (0.25 * fine + 0.5 * fibres) * 0.5
    return (h * h_rel).astype(np.float32)
