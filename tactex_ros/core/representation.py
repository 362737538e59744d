"""A tactile representation prepared before a trial: a metric on texture descriptors learnt from
a library of recorded (or simulated) presses of *other* materials, and the temperature of the
belief calibrated on that library with classes left out.

The descriptor model (``core/descriptor.py``) needs no training, but not every descriptor
direction is equally reliable: some vary as much between two presses of one material as between
materials. A library of presses of other materials shows which. ``fit`` standardises the
descriptors (library mean and std) and learns a linear map W (k x D) of one of these kinds:

- ``none`` (k = D): the identity (mean 0, std 1): the descriptor as it is, a file that only
  carries a calibrated temperature.
- ``whiten`` (k = D): W = (S_w + ``shrink`` I)^(-1/2), S_w the pooled within-class covariance;
  distances counted in units of "how much presses of one material differ".
- ``lda`` (k = ``dims`` < D): the whitening followed by the projection on the k directions along
  which the library's class means spread most (Fisher's discriminant directions); the other
  D - k directions, where materials of the library did not differ more than presses of one
  material, are dropped.

Applied to a trial's descriptors (``apply``), the belief still divides every output dimension by
the scene's own spread (``core/match.py``), so only the subspace and its orientation matter.

The belief's temperature depends on the number of dimensions and on the materials: ``prepare``
calibrates it on the library itself with classes left out (``core/calibration.py``), and the
file keeps it (``temperature``; NaN when not calibrated). The file (``save`` / ``load``) is a
numpy ``.npz`` archive read with ``allow_pickle=False`` (no torch on the shipped path): mean
(D,), std (D,), the map (k, D) (key ``whiten``), the descriptor's size D (``descriptor_dim``:
``texture.DIM`` without the height map, ``texture.DIM_HEIGHT_MAP`` with it), the kind, the
temperature, what the calibration measured (JSON), the library's size and the contact frames
per press it was prepared from (``descriptor_frames``; 0 or absent: not recorded, an older
file), the identity of the learned embedding its descriptors carry (``descriptor_embedding``,
``core/embedding.py``; '' or absent: none) and the frames per press averaged into that
embedding (``embedding_frames``; absent: ``descriptor_frames``, as before the setting
existed); no frames or descriptors of the library. A file without kind or temperature is a
whitening without calibration; one without ``descriptor_dim`` holds the size of its mean.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .errors import InputError
from .texture import DIM, DIM_HEIGHT_MAP, descriptor_dim

FORMAT = "tactex-representation-2"
KINDS = ("none", "whiten", "lda")


@dataclass
class Representation:
    mean: np.ndarray       # (D,) library mean of the descriptors
    std: np.ndarray        # (D,) library std
    whiten: np.ndarray     # (k, D) the linear map of the standardised descriptors
    classes: int           # library classes it was fitted on
    presses: int           # library presses it was fitted on
    shrink: float
    kind: str = "whiten"
    temperature: float = float("nan")   # calibrated belief temperature, NaN = not calibrated
    calibration: dict = field(default_factory=dict)   # what the calibration measured
    frames: int = 0        # contact frames per press it was prepared from; 0 = not recorded
    embedding: str = ""    # identity of the learned embedding in its descriptors ('' = none)
    embedding_frames: int = 0   # frames per press averaged into that embedding; 0 = as frames
    evidence: dict = field(default_factory=dict)   # the e-value stop's model in this space

    @property
    def descriptor_dim(self) -> int:
        """D, the size of the descriptors it takes."""
        return int(self.mean.shape[0])

    def check_descriptor(self, height_map: bool, where: str, frames: int | None = None,
                         embedding: str = "", embedding_dim: int = 0,
                         embedding_frames: int | None = None) -> None:
        """InputError unless it takes the descriptors ``learner.descriptor_height_map =
        height_map`` makes, with the learned embedding of identity ``embedding`` (size
        ``embedding_dim``; '' = none: ``core/embedding.py``), and (when the file records it and
        ``frames`` is given) was prepared from as many contact frames per press as
        ``learner.descriptor_frames = frames``, and (with an embedding, ``embedding_frames``
        given) with as many frames per press averaged into the embedding as
        ``learner.descriptor_embedding_frames`` (``where``: the file, for the message)."""
        if self.embedding != embedding:
            raise InputError(
                f"representation {where} was prepared "
                f"{'with the embedding ' + self.embedding if self.embedding else 'without an embedding'}"
                f"; this learner describes touches "
                f"{'with the embedding ' + embedding if embedding else 'without one'} "
                "(learner.descriptor_embedding): prepare the file again with the learner's "
                "setting (`tactex prepare --embedding`)")
        want = descriptor_dim(height_map) + embedding_dim
        if self.descriptor_dim != want:
            made = ("with" if self.descriptor_dim - embedding_dim == DIM_HEIGHT_MAP
                    else "without")
            raise InputError(
                f"representation {where} was prepared on descriptors of size "
                f"{self.descriptor_dim} ({made} the height map); this learner describes touches "
                f"with size {want} (learner.descriptor_height_map={str(height_map).lower()}): "
                f"set learner.descriptor_height_map={str(not height_map).lower()} or prepare "
                f"the file again (`tactex prepare --height-map "
                f"{'on' if height_map else 'off'}`)")
        if frames is not None and self.frames and self.frames != frames:
            raise InputError(
                f"representation {where} was prepared from {self.frames} contact frame(s) per "
                f"press; this learner describes touches from {frames} "
                f"(learner.descriptor_frames={frames}): set learner.descriptor_frames="
                f"{self.frames} or prepare the file again (`tactex prepare --frames {frames}`)")
        made = self.embedding_frames or self.frames
        if embedding and embedding_frames is not None and made and made != embedding_frames:
            raise InputError(
                f"representation {where} was prepared with the embedding averaged over {made} "
                f"contact frame(s) per press; this learner averages {embedding_frames} "
                f"(learner.descriptor_embedding_frames={embedding_frames}): set "
                f"learner.descriptor_embedding_frames={made} or prepare the file again "
                f"(`tactex prepare --embedding-frames {embedding_frames}`)")

    @property
    def dims(self) -> int:
        """k, the number of output dimensions."""
        return int(self.whiten.shape[0])

    def apply(self, x: np.ndarray) -> np.ndarray:
        """(..., D) descriptors -> (..., k) coordinates."""
        x = np.asarray(x, dtype=np.float64)
        if x.shape[-1] != self.mean.shape[0]:
            raise InputError(f"representation expects descriptors of size {self.mean.shape[0]}, "
                             f"got {x.shape[-1]}")
        return ((x - self.mean) / self.std) @ self.whiten.T


def _within(groups: list[np.ndarray], std: np.ndarray) -> np.ndarray:
    """Pooled within-class covariance (D, D) of the standardised descriptors."""
    resid = np.concatenate([(g - g.mean(axis=0)) / std for g in groups])
    dof = sum(len(g) - 1 for g in groups)
    return resid.T @ resid / dof


def fit(descriptors: dict[str, np.ndarray], shrink: float = 1.0, kind: str = "whiten",
        dims: int = 0) -> Representation:
    """Fit the metric on ``{class: (n_c, D) descriptors}`` (classes with >= 2 presses count for
    the within-class covariance; at least 2 such classes). ``kind``: ``whiten`` or ``lda``
    (``dims`` output dimensions, 1 <= dims < D; at most classes - 1 are kept)."""
    if not shrink > 0:
        raise InputError(f"shrink must be > 0, got {shrink}")
    if kind not in KINDS:
        raise InputError(f"representation kind {kind!r}: one of {', '.join(KINDS)}")
    groups = [np.asarray(v, dtype=np.float64) for v in descriptors.values()]
    usable = [g for g in groups if g.ndim == 2 and len(g) >= 2]
    if len(usable) < 2:
        raise InputError("a representation needs at least 2 library classes with 2 or more "
                         f"presses each; got {len(usable)}")
    allx = np.concatenate(groups)
    if kind == "none":
        d = allx.shape[1]
        return Representation(np.zeros(d), np.ones(d), np.eye(d), classes=len(groups),
                              presses=len(allx), shrink=float(shrink), kind=kind)
    mean, std = allx.mean(axis=0), allx.std(axis=0) + 1e-9
    sw = _within(usable, std)
    vals, vecs = np.linalg.eigh(sw + shrink * np.eye(sw.shape[0]))
    whiten = (vecs / np.sqrt(vals)) @ vecs.T
    if kind == "lda":
        if not 1 <= dims < allx.shape[1]:
            raise InputError(f"lda dims must be in 1..{allx.shape[1] - 1}, got {dims}")
        dims = min(dims, len(groups) - 1)         # the class means span at most classes - 1
        cm = np.stack([((g.mean(axis=0) - mean) / std) @ whiten.T for g in groups])
        w = np.array([len(g) for g in groups], dtype=np.float64)
        cm = cm - (w[:, None] * cm).sum(axis=0) / w.sum()
        sb = (cm * w[:, None]).T @ cm / w.sum()
        bvals, bvecs = np.linalg.eigh(sb)
        top = bvecs[:, np.argsort(bvals)[::-1][:dims]]          # (D, k)
        whiten = top.T @ whiten
    return Representation(mean, std, whiten, classes=len(groups), presses=len(allx),
                          shrink=float(shrink), kind=kind)


def save(rep: Representation, path: str | Path) -> Path:
    """Write ``rep`` as a numpy ``.npz`` archive of arrays at ``path`` (no pickled objects)."""
    import json
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    with path.open("wb") as f:                    # exactly that name (savez adds no suffix)
        np.savez(f, format=np.array(FORMAT), mean=rep.mean, std=rep.std, whiten=rep.whiten,
                 kind=np.array(rep.kind), classes=np.array(rep.classes),
                 presses=np.array(rep.presses), shrink=np.array(rep.shrink),
                 descriptor_dim=np.array(rep.descriptor_dim),
                 descriptor_frames=np.array(rep.frames),
                 descriptor_embedding=np.array(rep.embedding),
                 embedding_frames=np.array(rep.embedding_frames),
                 temperature=np.array(rep.temperature),
                 calibration=np.array(json.dumps(rep.calibration)),
                 evidence=np.array(json.dumps(rep.evidence)))
    return path


def load(path: str | Path) -> Representation:
    """Read a representation file; InputError naming the file and what is wrong."""
    import json
    from .outputs import read_npz
    p = Path(path)
    d = read_npz(p, "representation file", FORMAT, "make it with `tactex prepare`")
    def number(key: str, default: float) -> float:
        """A numeric scalar field; InputError naming the file and the field otherwise."""
        v = d.get(key)
        if v is None:
            return default
        if v.shape != () or v.dtype.kind not in "biuf":
            raise InputError(f"representation file {p}: field {key!r} must be a number, got "
                             f"{v.dtype} of shape {v.shape}")
        return float(v)

    try:
        arrays = [d[k] for k in ("mean", "std", "whiten")]
    except KeyError as exc:
        raise InputError(f"representation file {p}: missing {exc}") from None
    for k, v in zip(("mean", "std", "whiten"), arrays, strict=True):
        if v.dtype.kind not in "biuf":
            raise InputError(f"representation file {p}: field {k!r} must hold numbers, got "
                             f"{v.dtype}")
    mean, std, w = (np.asarray(v, dtype=np.float64) for v in arrays)
    dim = int(number("descriptor_dim", mean.shape[0] if mean.ndim == 1 else -1))
    embedding = str(d.get("descriptor_embedding", ""))
    if (dim not in (DIM, DIM_HEIGHT_MAP)) if not embedding else dim <= DIM_HEIGHT_MAP:
        raise InputError(f"representation file {p}: shapes {mean.shape}, {std.shape}, "
                         f"{w.shape} do not fit a descriptor of size {DIM} (without the height "
                         f"map) or {DIM_HEIGHT_MAP} (with it)"
                         f"{', plus an embedding' if embedding else ''}")
    if (mean.shape != (dim,) or std.shape != (dim,) or w.ndim != 2 or w.shape[1] != dim
            or not 1 <= w.shape[0] <= dim):
        raise InputError(f"representation file {p}: shapes {mean.shape}, {std.shape}, "
                          f"{w.shape} do not fit the descriptor of size {dim}")
    if not (np.all(np.isfinite(w)) and np.all(std > 0) and np.all(np.isfinite(mean))):
        raise InputError(f"representation file {p}: non-finite map or mean, or std <= 0")
    temp = number("temperature", float("nan"))
    if not np.isnan(temp) and not (np.isfinite(temp) and temp > 0):    # NaN: not calibrated
        raise InputError(f"representation file {p}: temperature {temp} must be > 0 and "
                         "finite (or NaN: not calibrated)")
    kind = str(d.get("kind", "whiten"))
    if kind not in KINDS:
        raise InputError(f"representation file {p}: unknown kind {kind!r}")
    try:
        calib = json.loads(str(d.get("calibration", "{}")))
    except ValueError:
        raise InputError(f"representation file {p}: calibration is not JSON") from None
    if not isinstance(calib, dict):
        raise InputError(f"representation file {p}: field 'calibration' must be a JSON "
                         f"object, got {type(calib).__name__}")
    try:
        evidence = json.loads(str(d.get("evidence", "{}")))
    except ValueError:
        raise InputError(f"representation file {p}: evidence is not JSON") from None
    if not isinstance(evidence, dict):
        raise InputError(f"representation file {p}: field 'evidence' must be a JSON object, got "
                         f"{type(evidence).__name__}")
    if evidence:
        from .evidence import EvidenceModel
        EvidenceModel.from_dict(evidence, f"representation file {p} (its evidence model)")
    frames = number("descriptor_frames", 0)
    if frames != int(frames) or frames < 0:
        raise InputError(f"representation file {p}: field 'descriptor_frames' must be a whole "
                         f"number >= 0 (0: not recorded), got {frames}")
    eframes = number("embedding_frames", 0)
    if eframes != int(eframes) or eframes < 0:
        raise InputError(f"representation file {p}: field 'embedding_frames' must be a whole "
                         f"number >= 0 (0: as descriptor_frames), got {eframes}")
    return Representation(mean, std, w, int(number("classes", 0)), int(number("presses", 0)),
                          number("shrink", 0.0), kind, temp, calib, int(frames), embedding,
                          int(eframes), evidence)
