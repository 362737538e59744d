"""A nonlinear metric on texture descriptors: a small numpy MLP on top of the whitening (issue 23).

The screening of ``experiment unseen`` found that every *linear* projection learnt on the
library's classes (LDA, NCA) lost to the plain within-class whitening on unseen classes. This
module tries a nonlinear one, regularised toward the whitening so that it can only improve on
it where the library says so:

    z = ((x - mean) / std) @ W^T                 the whitening (``core.representation.fit``)
    f(x) = z + relu(z @ W1^T + b1) @ W2^T         a residual branch, W2 = 0 at the start

trained on the library with one of two losses over the library's presses, both on squared
Euclidean distances d(a, b) = |f(a) - f(b)|^2:

- ``episode`` (softmax): scenes like a trial's, 1 anchor press + ``comparisons`` candidates
  (another press of the anchor's class and presses of other classes); cross-entropy of
  softmax(-d(anchor, candidate) / tau) on the true candidate (tau: the median distance of the
  whitening on the training scenes, fixed);
- ``triplet``: mean of max(0, margin * tau + d(a, p) - d(a, n)).

Plus ``decay`` x (|W1|^2 + |W2|^2) / 2 (toward the whitening). Adam, full-batch embeddings (the
library is a few hundred presses), numpy only, seconds on CPU. ``MLPMetric.apply`` has the
``Representation.apply`` signature, so the screening proxy and the trials use it unchanged.
Trained on ``../shared`` only at run time; nothing is written to the repository.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from tactex_ros.core import representation
from tactex_ros.core.errors import InputError

LOSSES = ("episode", "triplet")


@dataclass
class MLPMetric:
    """The whitening (``base``) plus a residual ReLU branch: W1 (H, k), b1 (H,), W2 (k, H)."""

    base: representation.Representation
    w1: np.ndarray
    b1: np.ndarray
    w2: np.ndarray
    temperature: float = float("nan")      # the belief's; NaN = the config's

    @property
    def dims(self) -> int:
        """Output dimensions (the whitening's)."""
        return self.base.dims

    def forward(self, z: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Whitened (N, k) -> (embedding (N, k), pre-activation (N, H))."""
        a = z @ self.w1.T + self.b1
        return z + np.maximum(a, 0.0) @ self.w2.T, a

    def apply(self, x: np.ndarray) -> np.ndarray:
        """(..., D) descriptors -> (..., k) embedding."""
        x = np.asarray(x, dtype=np.float64)
        shape = x.shape
        z = self.base.apply(x.reshape(-1, shape[-1]))
        return self.forward(z)[0].reshape(*shape[:-1], -1)


def backward(m: MLPMetric, z: np.ndarray, a: np.ndarray, grad_f: np.ndarray
             ) -> dict[str, np.ndarray]:
    """Gradients of a loss w.r.t. W1, b1, W2 given dLoss/df (N, k) at the inputs z (N, k) whose
    forward pre-activations are a (N, H)."""
    h = np.maximum(a, 0.0)
    dh = (grad_f @ m.w2) * (a > 0)
    return {"w1": dh.T @ z, "b1": dh.sum(axis=0), "w2": grad_f.T @ h}


def episodes(cls: np.ndarray, n: int, comparisons: int, rng: np.random.Generator
             ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``n`` training scenes over press labels ``cls`` (N,): anchor rows (n,), candidate rows
    (n, comparisons), the true candidate's column (n,). Anchors come from classes with >= 2
    presses; the true candidate is another press of the anchor's class, the others one press
    each of distinct other classes."""
    names, inv = np.unique(cls, return_inverse=True)
    order = np.argsort(inv, kind="stable")                        # rows grouped by class
    count = np.bincount(inv, minlength=len(names))
    start = np.concatenate([[0], np.cumsum(count)[:-1]])
    multi = np.flatnonzero(count >= 2)
    if len(multi) < 1 or len(names) < comparisons:
        raise InputError(f"MLP metric: {len(names)} classes ({len(multi)} with 2+ presses) "
                         f"cannot make scenes of {comparisons} comparisons")
    c = multi[rng.integers(len(multi), size=n)]
    ia = rng.integers(count[c])
    ip = (ia + 1 + rng.integers(count[c] - 1)) % count[c]          # another press of c
    keys = rng.random((n, len(names)))
    keys[np.arange(n), c] = np.inf                                 # never the anchor's class
    negc = np.argsort(keys, axis=1)[:, :comparisons - 1]           # distinct other classes
    negr = order[start[negc] + (rng.random(negc.shape) * count[negc]).astype(np.int64)]
    true = rng.integers(comparisons, size=n)
    cand = np.empty((n, comparisons), dtype=np.int64)
    mask = np.arange(comparisons)[None, :] == true[:, None]
    cand[mask] = order[start[c] + ip]
    cand[~mask] = negr.reshape(-1)
    return order[start[c] + ia], cand, true


def loss_and_grad(f: np.ndarray, anchor: np.ndarray, cand: np.ndarray, true: np.ndarray,
                  tau: float, loss: str = "episode", margin: float = 0.5
                  ) -> tuple[float, np.ndarray]:
    """Mean loss over the scenes and dLoss/df (N, k) for embeddings f (N, k)."""
    diff = f[anchor][:, None, :] - f[cand]                       # (n, C, k)
    d = np.sum(diff ** 2, axis=-1)                               # (n, C)
    n = len(anchor)
    if loss == "episode":
        logits = -d / tau
        logits -= logits.max(axis=1, keepdims=True)
        p = np.exp(logits)
        p /= p.sum(axis=1, keepdims=True)
        value = float(-np.mean(np.log(p[np.arange(n), true] + 1e-300)))
        onehot = np.zeros_like(p)
        onehot[np.arange(n), true] = 1.0
        g_d = (onehot - p) / tau / n                              # dL/dd
    elif loss == "triplet":
        dp = d[np.arange(n), true]
        viol = margin * tau + dp[:, None] - d                    # (n, C), the true column = m
        viol[np.arange(n), true] = 0.0
        active = viol > 0
        negs = cand.shape[1] - 1
        value = float(np.sum(np.where(active, viol, 0.0)) / (n * negs))
        g_d = -active.astype(np.float64) / (n * negs)
        g_d[np.arange(n), true] = active.sum(axis=1) / (n * negs)
    else:
        raise InputError(f"MLP metric loss {loss!r}: one of {', '.join(LOSSES)}")
    g_diff = 2.0 * g_d[..., None] * diff                         # dL/d(diff) (n, C, k)
    rows = np.concatenate([anchor, cand.reshape(-1)])
    vals = np.concatenate([g_diff.sum(axis=1), -g_diff.reshape(-1, f.shape[1])])
    k = f.shape[1]                                               # scatter-add by row
    flat = (rows[:, None] * k + np.arange(k)).reshape(-1)
    grad = np.bincount(flat, weights=vals.reshape(-1), minlength=f.size).reshape(f.shape)
    return value, grad


def fit(descriptors: dict[str, np.ndarray], hidden: int = 64, loss: str = "episode",
        decay: float = 1e-2, steps: int = 600, scenes: int = 256, lr: float = 1e-3,
        comparisons: int = 4, seed: int = 0, shrink: float = 1.0) -> tuple[MLPMetric, dict]:
    """Train on ``{class: (n_c, D) descriptors}``: the whitening first, then the residual
    branch for ``steps`` Adam steps of ``scenes`` fresh training scenes each. Returns the metric
    and a log (loss per 50 steps, seconds)."""
    import time
    if loss not in LOSSES:
        raise InputError(f"MLP metric loss {loss!r}: one of {', '.join(LOSSES)}")
    if hidden < 1 or steps < 0 or decay < 0:
        raise InputError(f"MLP metric: hidden {hidden}, steps {steps}, decay {decay}")
    t0 = time.perf_counter()
    base = representation.fit(descriptors, shrink=shrink, kind="whiten")
    names = list(descriptors)
    x = np.concatenate([np.asarray(descriptors[c], dtype=np.float64) for c in names])
    cls = np.concatenate([[c] * len(descriptors[c]) for c in names])
    z = base.apply(x)
    rng = np.random.default_rng([seed, 23])
    k = z.shape[1]
    m = MLPMetric(base, rng.normal(0.0, 1.0 / np.sqrt(k), (hidden, k)), np.zeros(hidden),
                  np.zeros((k, hidden)))
    a0, c0, _ = episodes(cls, 512, comparisons, rng)
    tau = float(np.median(np.sum((z[a0][:, None] - z[c0]) ** 2, axis=-1)))
    params = ("w1", "b1", "w2")
    mom = {p: np.zeros_like(getattr(m, p)) for p in params}
    var = {p: np.zeros_like(getattr(m, p)) for p in params}
    log = []
    for step in range(1, steps + 1):
        anchor, cand, true = episodes(cls, scenes, comparisons, rng)
        f, a = m.forward(z)
        value, gf = loss_and_grad(f, anchor, cand, true, tau, loss)
        grads = backward(m, z, a, gf)
        for p in params:
            g = grads[p] + (decay * getattr(m, p) if p != "b1" else 0.0)
            mom[p] = 0.9 * mom[p] + 0.1 * g
            var[p] = 0.999 * var[p] + 0.001 * g * g
            mh, vh = mom[p] / (1 - 0.9 ** step), var[p] / (1 - 0.999 ** step)
            setattr(m, p, getattr(m, p) - lr * mh / (np.sqrt(vh) + 1e-8))
        if step % 50 == 0 or step == 1:
            log.append({"step": step, "loss": value})
    return m, {"tau": tau, "loss": log, "seconds": time.perf_counter() - t0}
