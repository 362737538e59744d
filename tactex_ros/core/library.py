"""The fabric library: labelled descriptors of the named fabrics a robot has touched, and the
part of the match belief that uses them (docs/research/fabric_library.md).

A lab places the same fabrics again and again. Every press of a trial whose placement is known
(a session's trial file) joins the library under its fabric's name (``trial/library.py``), and
later trials ask it which known fabric each platform holds.

The model. Each platform p holds one fabric z_p: one of the library's F fabrics or a fabric the
library does not know ("new"). Prior: P(z = f) = 1 / (F + alpha), P(z = new) = alpha / (F + alpha)
(``new_weight`` = alpha). In the library's units (every dimension divided by the spread of all
library presses), fabric f's presses are x ~ N(m_f, diag(s^2)): m_f its mean over n_f presses,
s^2 the pooled within-fabric variance shrunk toward 1 with ``prior_strength`` pseudo-presses.
A new fabric's mean is a draw from N(g, diag(B)): g and B the mean and the variance of the
library's fabric means (B at least s^2; B = 1 with fewer than 2 fabrics). Platform p's mean
xbar_p of k_p touches then has the density
    known f:  N(xbar_p; m_f, s^2 (1/k_p + 1/n_f))       new:  N(xbar_p; g, B + s^2/k_p),
tempered by the match belief's ``temperature`` (descriptor dimensions are correlated, as in
``core/match.py``), giving each platform's posterior q_p over {1..F, new}.

Hypothesis h (the reference holds comparison h's fabric): the library's evidence for it is how
much more likely the two share a fabric given their classifications than a priori,
    K_h = P(z_0 = z_h | x) / P(z_0 = z_h) = sum_f q_0(f) q_h(f) / P(f) + q_0(new) q_h(new) / P(new),
the known fabrics marginalised, plus the unknown-fabric component. The scene's own evidence
(today's belief b, ``MatchModel.belief``: how close the reference's touches lie to comparison
h's) holds whether the shared fabric is known or not, so the belief is b_h K_h^w normalised
(w = ``EVIDENCE_WEIGHT``: both classify the same touches, so their evidence overlaps). A
library that tells nothing (q = the prior: K = 1), an empty library and platforms all classified
new (K_h = 1 / P(new) for every h) give today's belief exactly; a reference classified as a
known fabric moves the belief toward the comparison classified as the same one, and away from
comparisons classified as other fabrics.

The file: a numpy ``.npz`` (read with ``allow_pickle=False``) of the raw descriptors (N, D)
before any representation (lossless: a representation is applied when a trial uses it), the
fabric name and the source (which touch of which trial) of each, written whole and atomically
(``core.outputs.write_bytes``).
"""

from __future__ import annotations

import hashlib
import io
from dataclasses import dataclass, field
from pathlib import Path
from collections.abc import Callable, Iterable

import numpy as np

from .errors import InputError
from .match import softmax
from .outputs import read_npz, write_bytes

FORMAT = "tactex-fabric-library-1"
#: The library's file name in the lab's records folder (``record_dir``).
LIBRARY_FILE = "fabric_library.npz"


@dataclass
class FabricLibrary:
    """Labelled raw descriptors: ``descriptors`` (N, D), ``names`` (N,) fabric names,
    ``sources`` (N,) where each came from (unique; e.g. ``session/trial/touch 3``)."""

    descriptors: np.ndarray = field(default_factory=lambda: np.zeros((0, 0)))
    names: list[str] = field(default_factory=list)
    sources: list[str] = field(default_factory=list)

    @property
    def presses(self) -> int:
        return len(self.names)

    @property
    def fabrics(self) -> list[str]:
        """The known fabric names, sorted."""
        return sorted(set(self.names))

    def add(self, name: str, descriptors: np.ndarray, sources: list[str]) -> FabricLibrary:
        """A new library with ``descriptors`` (n, D) of fabric ``name`` added; a source the
        library holds already is skipped (the same press is never counted twice)."""
        x = np.asarray(descriptors, dtype=np.float64).reshape(len(sources), -1)
        if not np.all(np.isfinite(x)):
            raise InputError(f"fabric library: descriptors of {name!r} are not finite")
        if self.presses and x.shape[1] != self.descriptors.shape[1]:
            raise InputError(f"fabric library: descriptors of size {x.shape[1]} differ from "
                             f"the library's {self.descriptors.shape[1]}")
        held = set(self.sources)
        keep = [i for i, s in enumerate(sources) if s not in held]
        if not keep:
            return self
        old = self.descriptors if self.presses else np.zeros((0, x.shape[1]))
        return FabricLibrary(np.concatenate([old, x[keep]]), self.names + [name] * len(keep),
                             self.sources + [sources[i] for i in keep])

    def without(self, sources: Iterable[str]) -> FabricLibrary:
        """The library less the entries of ``sources``."""
        drop = set(sources)
        keep = [i for i, s in enumerate(self.sources) if s not in drop]
        if len(keep) == self.presses:
            return self
        return FabricLibrary(self.descriptors[keep], [self.names[i] for i in keep],
                             [self.sources[i] for i in keep])

    def sha256(self) -> str:
        """SHA-256 (hex) of the content (names, sources, descriptor bytes)."""
        h = hashlib.sha256()
        for part in ("\n".join(self.names), "\n".join(self.sources)):
            h.update(part.encode())
            h.update(b"\0")
        h.update(np.ascontiguousarray(self.descriptors, dtype="<f8").tobytes())
        return h.hexdigest()

    def state(self) -> dict:
        """What a trial's record keeps of the library it saw: fabrics, presses, hash."""
        return {"fabrics": len(self.fabrics), "presses": self.presses,
                "sha256": self.sha256()[:16]}


def save(lib: FabricLibrary, path: str | Path) -> Path:
    """Write ``lib`` whole and atomically at ``path`` (the previous file stays on a failure)."""
    buf = io.BytesIO()
    np.savez(buf, format=np.array(FORMAT), descriptors=np.asarray(lib.descriptors, "<f8"),
             names=np.array(lib.names, dtype=str), sources=np.array(lib.sources, dtype=str))
    return write_bytes(path, buf.getvalue())


def load(path: str | Path, missing_ok: bool = False) -> FabricLibrary:
    """Read a library file; an empty library when it is absent and ``missing_ok``. InputError
    naming the file and what is wrong (torn, foreign, inconsistent)."""
    p = Path(path)
    if missing_ok and not p.exists():
        return FabricLibrary()
    d = read_npz(p, "fabric library file", FORMAT, "move it away to start an empty library")
    try:
        x, names, sources = d["descriptors"], d["names"], d["sources"]
    except KeyError as exc:
        raise InputError(f"fabric library file {p}: missing {exc}") from None
    if (x.dtype.kind != "f" or x.ndim != 2 or names.shape != (len(x),)
            or sources.shape != (len(x),) or not np.all(np.isfinite(x))):
        raise InputError(f"fabric library file {p}: descriptors {x.shape} {x.dtype}, names "
                         f"{names.shape}, sources {sources.shape} do not fit together")
    if len(set(sources.tolist())) != len(sources):
        raise InputError(f"fabric library file {p}: a source appears twice")
    return FabricLibrary(x.astype(np.float64), [str(n) for n in names],
                         [str(s) for s in sources])


#: The weight of the library's evidence, as the exponent of K (log K times it): the library
#: classifies the very touches the scene belief compares, so the two overlap; at full weight the
#: product stopped wrongly more often. 0.25: the largest of 0.25 / 0.5 / 1 whose wrong stops on
#: octopi-objects' replayed sessions did not exceed learning off's; octopi-dev the check
#: (docs/research/fabric_library.md).
EVIDENCE_WEIGHT = 0.25


class LibraryBelief:
    """The library's part of the match belief (module docstring): fitted on ``x`` (N, k), the
    library's descriptors in the trial's units (after its representation), with ``names``."""

    def __init__(self, x: np.ndarray, names: list[str], temperature: float,
                 new_weight: float = 1.0, prior_strength: float = 4.0,
                 weight: float = EVIDENCE_WEIGHT) -> None:
        for key, v in (("temperature", temperature), ("new_weight", new_weight),
                       ("prior_strength", prior_strength), ("weight", weight)):
            if not v > 0:
                raise InputError(f"LibraryBelief.{key} must be > 0, got {v}")
        x = np.asarray(x, dtype=np.float64)
        self.beta = float(temperature)
        self.weight = float(weight)
        self.fabric_names = sorted(set(names))
        F = len(self.fabric_names)
        self.F = F
        if F == 0:
            return
        self.scale = x.std(axis=0) + 1e-9 if len(x) > 1 else np.ones(x.shape[1])
        z = x / self.scale
        lab = np.array([self.fabric_names.index(n) for n in names])
        self.means = np.stack([z[lab == f].mean(axis=0) for f in range(F)])    # (F, k)
        self.n = np.bincount(lab, minlength=F).astype(np.float64)             # (F,)
        ss = ((z - self.means[lab]) ** 2).sum(axis=0)
        dof = len(z) - F
        self.s2 = (prior_strength * 1.0 + ss) / (prior_strength + dof)        # (k,)
        self.g = self.means.mean(axis=0)
        self.B = np.maximum(self.means.var(axis=0), self.s2) if F >= 2 else np.ones(z.shape[1])
        self.log_prior = np.log(np.append(np.ones(F), new_weight) / (F + new_weight))

    def posteriors(self, means: np.ndarray, counts: np.ndarray) -> np.ndarray:
        """(P, F + 1) each platform's fabric posterior (last column: new), from its mean
        descriptor ``means`` (P, k) in the trial's units over ``counts`` (P,) touches."""
        return np.exp(self._log_posteriors(means, counts))

    def _log_posteriors(self, means: np.ndarray, counts: np.ndarray) -> np.ndarray:
        xb = np.asarray(means, dtype=np.float64) / self.scale                 # (P, k)
        k = np.asarray(counts, dtype=np.float64)[:, None, None]              # (P, 1, 1)
        var = self.s2 * (1.0 / k + 1.0 / self.n[None, :, None])              # (P, F, k)
        ll = _log_normal(xb[:, None, :], self.means[None], var)               # (P, F)
        ll_new = _log_normal(xb, self.g, self.B + self.s2 / k[:, 0])           # (P,)
        logits = self.beta * np.concatenate([ll, ll_new[:, None]], axis=1) + self.log_prior
        return logits - _logsumexp(logits, axis=1)[:, None]

    def belief(self, means: np.ndarray, counts: np.ndarray, scene: np.ndarray) -> np.ndarray:
        """(C,) the belief: ``scene`` (C,) today's belief and the platforms' (C + 1, k)
        ``means`` over ``counts`` touches (0 = the reference) classified by the library."""
        scene = np.asarray(scene, dtype=np.float64)
        if self.F == 0:
            return scene
        lq = self._log_posteriors(means, counts)                               # (C+1, F+1)
        terms = lq[0][None, :] + lq[1:] - self.log_prior[None, :]              # (C, F+1)
        with np.errstate(divide="ignore"):
            return softmax(np.log(scene) + self.weight * _logsumexp(terms, axis=1))


def _logsumexp(a: np.ndarray, axis: int) -> np.ndarray:
    m = np.max(a, axis=axis, keepdims=True)
    m = np.where(np.isfinite(m), m, 0.0)
    with np.errstate(divide="ignore"):
        return (np.log(np.exp(a - m).sum(axis=axis, keepdims=True)) + m).squeeze(axis)


def _log_normal(x: np.ndarray, mu: np.ndarray, var: np.ndarray) -> np.ndarray:
    """Sum over the last axis of log N(x; mu, var) (diagonal)."""
    return -0.5 * (np.log(2 * np.pi * var) + (x - mu) ** 2 / var).sum(axis=-1)


def library_belief(lib: FabricLibrary, apply: Callable[[np.ndarray], np.ndarray] | None,
                   temperature: float, weight: float = EVIDENCE_WEIGHT) -> LibraryBelief:
    """The ``LibraryBelief`` of ``lib`` in a trial's units (``apply``: its representation)."""
    x = lib.descriptors if apply is None or not lib.presses else apply(lib.descriptors)
    return LibraryBelief(x, lib.names, temperature, weight=weight)
