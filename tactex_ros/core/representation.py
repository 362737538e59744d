"""A tactile representation prepared before a trial: a metric on texture descriptors learnt from
a library of recorded (or simulated) presses of *other* materials.

The descriptor model (``core/descriptor.py``) needs no training, but not every descriptor
dimension is equally reliable: some vary as much between two presses of one material as between
materials. A library of presses of other materials shows which: ``fit`` computes, on the
standardised descriptors (library mean and std), the pooled within-class covariance S_w, shrinks
it toward its diagonal, and keeps the whitening W = (S_w + ``shrink`` I)^(-1/2). Applied to a
trial's descriptors, distances are then counted in units of "how much presses of one material
differ", learnt on materials the trial does not contain (class-disjoint by construction).

The file is a numpy ``.npz`` archive of arrays (``save`` / ``load``, read with
``allow_pickle=False``, so no torch on the shipped path); it holds no frames or descriptors of
the library, only the (D,) mean, (D,) std and (D, D) whitening, and the library's size. (Files
of the earlier torch format are refused with the command that remakes them.) Without a file the product
works as before (scene units, ``core/match.py``).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .errors import InputError
from .texture import DIM

FORMAT = "tactex-representation-2"


@dataclass
class Representation:
    mean: np.ndarray       # (D,)
    std: np.ndarray        # (D,)
    whiten: np.ndarray     # (D, D)
    classes: int           # library classes it was fitted on
    presses: int           # library presses it was fitted on
    shrink: float

    def apply(self, x: np.ndarray) -> np.ndarray:
        """(..., D) descriptors -> (..., D) whitened coordinates."""
        x = np.asarray(x, dtype=np.float64)
        if x.shape[-1] != self.mean.shape[0]:
            raise InputError(f"representation expects descriptors of size {self.mean.shape[0]}, "
                             f"got {x.shape[-1]}")
        return ((x - self.mean) / self.std) @ self.whiten.T


def fit(descriptors: dict[str, np.ndarray], shrink: float = 1.0) -> Representation:
    """Fit the metric on ``{class: (n_c, D) descriptors}`` (classes with >= 2 presses count for
    the within-class covariance; at least 2 such classes)."""
    if not shrink > 0:
        raise InputError(f"shrink must be > 0, got {shrink}")
    groups = [np.asarray(v, dtype=np.float64) for v in descriptors.values()]
    usable = [g for g in groups if g.ndim == 2 and len(g) >= 2]
    if len(usable) < 2:
        raise InputError("a representation needs at least 2 library classes with 2 or more "
                         f"presses each; got {len(usable)}")
    allx = np.concatenate(groups)
    mean, std = allx.mean(axis=0), allx.std(axis=0) + 1e-9
    resid = np.concatenate([(g - g.mean(axis=0)) / std for g in usable])
    dof = sum(len(g) - 1 for g in usable)
    sw = resid.T @ resid / dof
    vals, vecs = np.linalg.eigh(sw + shrink * np.eye(sw.shape[0]))
    whiten = (vecs / np.sqrt(vals)) @ vecs.T
    return Representation(mean, std, whiten, classes=len(groups), presses=len(allx),
                          shrink=float(shrink))


def save(rep: Representation, path: str | Path) -> Path:
    """Write ``rep`` as an ``.npz`` archive of arrays at ``path`` (exactly that name)."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    with path.open("wb") as f:
        np.savez(f, format=np.array(FORMAT), mean=rep.mean, std=rep.std, whiten=rep.whiten,
                 classes=np.array(rep.classes), presses=np.array(rep.presses),
                 shrink=np.array(rep.shrink))
    return path


def load(path: str | Path) -> Representation:
    """Read a representation file; InputError naming the file and what is wrong."""
    p = Path(path)
    if not p.is_file():
        raise InputError(f"representation file not found: {p}")
    try:
        with np.load(p, allow_pickle=False) as z:
            d = {k: z[k] for k in z.files}
    except Exception as exc:  # numpy raises several types for a corrupt or foreign file
        raise InputError(f"representation file {p} is not loadable ({exc}); make it with "
                         "`tactex prepare`") from None
    if str(d.get("format", "")) != FORMAT:
        raise InputError(f"representation file {p}: not a {FORMAT} file; make it with "
                         "`tactex prepare`")
    try:
        mean, std, w = (np.asarray(d[k], dtype=np.float64) for k in ("mean", "std", "whiten"))
    except KeyError as exc:
        raise InputError(f"representation file {p}: missing {exc}") from None
    if mean.shape != (DIM,) or std.shape != (DIM,) or w.shape != (DIM, DIM):
        raise InputError(f"representation file {p}: shapes {mean.shape}, {std.shape}, "
                         f"{w.shape} do not fit the descriptor of size {DIM}")
    if not (np.all(np.isfinite(w)) and np.all(std > 0)):
        raise InputError(f"representation file {p}: non-finite whitening or std <= 0")
    return Representation(mean, std, w, int(d.get("classes", 0)), int(d.get("presses", 0)),
                          float(d.get("shrink", 0.0)))
