"""The CNN's uncertainty: a (T, C) table of the reference, and per-platform scores from it.

Shapes: ``probs`` is (T, C): T softmax vectors of the reference sample over the C comparison
platforms, from one of three sources (``learner.uncertainty``):

- ``mc_dropout`` (``mc_probs``): T stochastic passes with dropout active (the thesis's method);
- ``ensemble`` (``ensemble_probs``): one row per member of an ensemble of K heads over the
  shared stem (T = K), deterministic;
- ``laplace`` (``LastLayerLaplace``): a Laplace approximation of the posterior of the last
  layer (the linear classifier) around its trained weights: full generalised Gauss-Newton
  precision ``H + lambda I``, the prior precision lambda chosen by the marginal likelihood on a
  grid (or fixed); rows are softmax vectors of T weight draws from that posterior (GLM
  predictive), deterministic for a seeded generator.

The scores over the table (``expected_variance``, ``entropy_contribution``,
``bald_contribution``, ``predictive_entropy``) are numpy-only and live with the strategies in the
product (``tactex_ros/core/strategies.py``); they apply to every source (they read only the
table), so "disagreement" is the
variance / mutual information over passes, members or posterior draws alike. All scores are
(C,) float64 arrays, higher = more uncertain.

- ``expected_variance``: Var_t[p_t,i] (thesis: "variance").
- ``entropy_contribution``: -pbar_i log pbar_i with pbar = mean_t p_t (thesis: "entropy").
- ``bald_contribution``: -pbar_i log pbar_i + mean_t p_t,i log p_t,i; the terms are >= 0 and sum
  to the mutual information between the prediction and the weights (BALD).
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import numpy as np
import torch

from tactex_lab.cnn.device import rng_devices
from tactex_lab.cnn.models import TactileInception



@torch.no_grad()
def mc_probs(model: TactileInception, x: torch.Tensor, passes: int,
             generator: torch.Generator | None = None) -> torch.Tensor:
    """T stochastic softmax passes in one batched forward.

    ``x``: (V, 3, S, S) views of the reference (V >= 1; probabilities are averaged over views).
    Returns (T, C) float32. The deterministic prefix runs once in eval mode (batch norm uses its
    running statistics); the stochastic suffix runs once on a (T*V)-batch with dropout active.
    ``generator`` seeds the dropout masks (the global torch RNG is used when None); on a GPU
    the masks come from its generator, seeded from ``generator`` (the same stream as on the
    CPU, other masks).
    """
    if passes < 1:
        raise ValueError(f"passes must be >= 1, got {passes}")
    was_training = model.training
    model.eval()
    try:
        h = model.prefix(x)                               # (V, ...)
        hb = h.repeat((passes,) + (1,) * (h.dim() - 1))   # (T*V, ...), pass-major
        _enable_dropout(model)
        if generator is not None:
            with torch.random.fork_rng(devices=rng_devices(x.device)):
                torch.manual_seed(int(torch.randint(0, 2**62, (1,), generator=generator)))
                logits = model.suffix(hb)
        else:
            logits = model.suffix(hb)
    finally:
        model.train(was_training)
    p = torch.softmax(logits.float(), dim=1).view(passes, x.shape[0], -1)
    return p.mean(dim=1)


def _enable_dropout(model: torch.nn.Module) -> None:
    for m in model.modules():
        if isinstance(m, torch.nn.Dropout):
            m.train()


# ----------------------------------------------------------------------------- ensemble
@torch.no_grad()
def ensemble_probs(model: TactileInception, x: torch.Tensor) -> torch.Tensor:
    """(K, C) float32 softmax of each of the model's K heads, averaged over the V views of
    ``x`` (V, 3, S, S); eval mode (no dropout), deterministic."""
    was_training = model.training
    model.eval()
    try:
        logits = model.member_logits(x)                   # (V, K, C)
    finally:
        model.train(was_training)
    return member_table(logits)


def member_table(logits: torch.Tensor) -> torch.Tensor:
    """(V, K, C) member logits of V views -> (K, C) float32 member softmax, mean over views."""
    return torch.softmax(logits.float(), dim=2).mean(dim=0)


# ----------------------------------------------------------------------------- last-layer Laplace
#: Prior precisions tried by the marginal likelihood (``laplace_prior_precision == 0``).
PRIOR_GRID = tuple(float(v) for v in np.logspace(-4, 4, 33))


def with_bias(features: torch.Tensor) -> torch.Tensor:
    """(N, F) -> (N, D = F + 1): a constant 1 appended (the bias as a weight)."""
    return torch.cat([features, torch.ones_like(features[:, :1])], dim=1)


def softmax_ggn(phi: torch.Tensor, probs: torch.Tensor) -> torch.Tensor:
    """Generalised Gauss-Newton of the summed cross-entropy of a linear softmax layer.

    ``phi``: (N, D) inputs of the layer (bias column included); ``probs``: (N, C) its softmax
    outputs. Parameters are the weight matrix (C, D) flattened row-major (index c * D + d).
    Returns (C*D, C*D) float64: sum_n (diag(p_n) - p_n p_n^T) kron phi_n phi_n^T.
    """
    phi, p = phi.double(), probs.double()
    lam = torch.diag_embed(p) - p.unsqueeze(2) * p.unsqueeze(1)          # (N, C, C)
    n_c, n_d = p.shape[1], phi.shape[1]
    h = torch.einsum("nij,nk,nl->ikjl", lam, phi, phi)                   # (C, D, C, D)
    return h.reshape(n_c * n_d, n_c * n_d)


def log_marginal_likelihood(loglik: float, theta_sq: float, eig: np.ndarray,
                            prior_precision: float) -> float:
    """Laplace log evidence (up to a constant) of an isotropic Gaussian prior with precision
    ``prior_precision`` on P weights: log p(D|theta) - lambda/2 |theta|^2 + P/2 log lambda
    - 1/2 sum_i log(e_i + lambda), ``eig`` (P,) the eigenvalues of the GGN."""
    lam = float(prior_precision)
    e = np.maximum(np.asarray(eig, dtype=np.float64), 0.0)
    return float(loglik - 0.5 * lam * theta_sq + 0.5 * e.size * np.log(lam)
                 - 0.5 * np.log(e + lam).sum())


def marglik_prior_precision(loglik: float, theta_sq: float, eig: np.ndarray,
                            grid: tuple[float, ...] = PRIOR_GRID) -> float:
    """The value of ``grid`` with the highest ``log_marginal_likelihood`` (first on ties)."""
    return max(grid, key=lambda v: log_marginal_likelihood(loglik, theta_sq, eig, v))


@dataclass
class LastLayerLaplace:
    """Gaussian posterior N(theta, precision^-1) over a linear softmax layer's weights.

    ``theta``: (C, D) trained weights with the bias as last column; ``precision``: (C*D, C*D)
    GGN + lambda I; ``prior_precision``: lambda. Build it with ``fit``.
    """

    theta: torch.Tensor
    precision: torch.Tensor
    prior_precision: float

    @classmethod
    def fit(cls, weight: torch.Tensor, bias: torch.Tensor, features: torch.Tensor,
            labels: torch.Tensor, prior_precision: float = 0.0) -> LastLayerLaplace:
        """Fit around the trained layer ``weight`` (C, F), ``bias`` (C,) on its inputs
        ``features`` (N, F) with integer ``labels`` (N,). ``prior_precision`` > 0 is used as
        given; 0 picks the grid value (``PRIOR_GRID``) of highest marginal likelihood."""
        if prior_precision < 0:
            raise ValueError(f"prior_precision must be >= 0, got {prior_precision}")
        theta = torch.cat([weight.detach(), bias.detach()[:, None]], dim=1).double()  # (C, D)
        phi = with_bias(features.detach().double())                                   # (N, D)
        logits = phi @ theta.T
        probs = torch.softmax(logits, dim=1)
        ggn = softmax_ggn(phi, probs)
        lam = float(prior_precision)
        if lam == 0.0:
            loglik = float(torch.log_softmax(logits, 1).gather(1, labels.long()[:, None]).sum())
            eig = torch.linalg.eigvalsh(ggn).numpy()
            sq = float((theta ** 2).sum())
            lam = marglik_prior_precision(loglik, sq, eig)
        prec = ggn + lam * torch.eye(ggn.shape[0], dtype=torch.float64)
        return cls(theta, prec, lam)

    @cached_property
    def chol(self) -> torch.Tensor:
        """(C*D, C*D) lower Cholesky factor L of the precision (L L^T), factored once per fit
        and shared by every draw and covariance of this posterior."""
        return torch.linalg.cholesky(self.precision)

    def logit_cov(self, features: torch.Tensor) -> torch.Tensor:
        """(V, F) layer inputs -> (V, C, C) covariance of the logits (J Sigma J^T)."""
        phi = with_bias(features.detach().double())
        n_c, n_d = self.theta.shape
        sigma = torch.cholesky_inverse(self.chol)
        s4 = sigma.view(n_c, n_d, n_c, n_d)
        return torch.einsum("vk,ikjl,vl->vij", phi, s4, phi)

    def sample_probs(self, features: torch.Tensor, samples: int,
                     generator: torch.Generator | None = None) -> torch.Tensor:
        """(T, C) float64: softmax of the layer under T weight draws from the posterior,
        averaged over the V rows of ``features`` (V, F) (one draw serves every view)."""
        if samples < 1:
            raise ValueError(f"samples must be >= 1, got {samples}")
        phi = with_bias(features.detach().double())                      # (V, D)
        n_c, n_d = self.theta.shape
        chol = self.chol                                                 # precision = L L^T
        z = torch.randn(n_c * n_d, samples, generator=generator, dtype=torch.float64)
        # theta + L^-T z has covariance (L L^T)^-1 = precision^-1
        eps = torch.linalg.solve_triangular(chol.T, z, upper=True).T     # (T, C*D)
        w = self.theta.unsqueeze(0) + eps.view(samples, n_c, n_d)        # (T, C, D)
        logits = torch.einsum("vd,tcd->tvc", phi, w)
        return torch.softmax(logits, dim=2).mean(dim=1)
