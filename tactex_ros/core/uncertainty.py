"""Monte-Carlo dropout: batched stochastic passes and per-platform uncertainty scores.

Shapes: ``probs`` is (T, C): T stochastic softmax vectors of the reference sample over the C
comparison platforms. All scores are (C,) float64 arrays, higher = more uncertain.

- ``expected_variance``: Var_t[p_t,i] (thesis: "variance").
- ``entropy_contribution``: -pbar_i log pbar_i with pbar = mean_t p_t (thesis: "entropy").
- ``bald_contribution``: -pbar_i log pbar_i + mean_t p_t,i log p_t,i; the terms are >= 0 and sum
  to the mutual information between the prediction and the weights (BALD).
"""

from __future__ import annotations

import numpy as np
import torch

from .models import TactileInception

_EPS = 1e-12


@torch.no_grad()
def mc_probs(model: TactileInception, x: torch.Tensor, passes: int,
             generator: torch.Generator | None = None) -> torch.Tensor:
    """T stochastic softmax passes in one batched forward.

    ``x``: (V, 3, S, S) views of the reference (V >= 1; probabilities are averaged over views).
    Returns (T, C) float32. The deterministic prefix runs once in eval mode (batch norm uses its
    running statistics); the stochastic suffix runs once on a (T*V)-batch with dropout active.
    ``generator`` seeds the dropout masks (the global torch RNG is used when None).
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
            with torch.random.fork_rng(devices=[]):
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


def expected_variance(probs: np.ndarray) -> np.ndarray:
    """(T, C) -> (C,) variance over passes of each class probability."""
    return np.asarray(probs, dtype=np.float64).var(axis=0)


def entropy_contribution(probs: np.ndarray) -> np.ndarray:
    """(T, C) -> (C,) -pbar_i log pbar_i, pbar = mean over passes (nats)."""
    pbar = np.asarray(probs, dtype=np.float64).mean(axis=0)
    return -pbar * np.log(pbar + _EPS)


def bald_contribution(probs: np.ndarray) -> np.ndarray:
    """(T, C) -> (C,) per-class terms of the mutual information (nats); they sum to BALD."""
    p = np.asarray(probs, dtype=np.float64)
    pbar = p.mean(axis=0)
    term = -pbar * np.log(pbar + _EPS) + (p * np.log(p + _EPS)).mean(axis=0)
    return np.maximum(term, 0.0)


def predictive_entropy(probs: np.ndarray) -> float:
    """(T, C) -> entropy of the mean softmax (nats)."""
    return float(entropy_contribution(probs).sum())
