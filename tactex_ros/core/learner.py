"""The online learner: stores augmented touches, trains across rounds, scores with MC dropout.

Classes are the C comparison platforms. Each stored touch becomes ``augment`` rotated views,
converted to a tensor once when added (never again on the per-round path). Training uses
cross-entropy weighted by the number of views per class, w_c = N / (C * n_c), and continues from
the previous round's weights and optimiser state.

Two training schedules:

- ``epochs`` (thesis): E full shuffled passes over all N stored views; cost grows with N.
- ``steps``: S minibatches drawn uniformly from the stored views; cost is constant in N.

Determinism: every random draw comes from generators seeded by ``seed`` (model init, view
angles, minibatch order, dropout masks in training and scoring), never from global state that
other code could have advanced.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np
import torch
import torch.nn.functional as F

from .config import LearnerConfig, validate
from .errors import TactexError
from .models import build_model
from .preprocess import augment, to_tensor, validate_frame, view
from .uncertainty import mc_probs


@dataclass
class TrainStats:
    seconds: float
    steps: int
    mean_loss: float


def class_weights(labels: np.ndarray, num_classes: int) -> np.ndarray:
    """(N,) int labels -> (C,) weights N / (C * n_c); 0 for classes without samples."""
    labels = np.asarray(labels)
    counts = np.bincount(labels, minlength=num_classes).astype(np.float64)
    w = np.zeros(num_classes)
    present = counts > 0
    w[present] = labels.size / (num_classes * counts[present])
    return w


class OnlineLearner:
    """Model + stored views + optimiser for one trial (or one classification run)."""

    def __init__(self, num_classes: int, cfg: LearnerConfig, seed: int = 0,
                 model_name: str | None = None) -> None:
        self.cfg = validate(cfg)
        self.num_classes = num_classes
        self.seed = int(seed)
        name = model_name or cfg.model
        if name == "auto":
            raise TactexError("model 'auto' is resolved by the trial engine, not the learner")
        if cfg.threads:
            torch.set_num_threads(cfg.threads)
        with torch.random.fork_rng(devices=[]):
            torch.manual_seed(self.seed)
            self.model, self.load_report = build_model(
                name, num_classes, dropout=cfg.dropout, block_dropout=cfg.block_dropout,
                aux_logits=cfg.aux_logits, weights=cfg.weights or None)
        self.model_name = name
        self.opt = torch.optim.Adam(self.model.parameters(), lr=cfg.lr,
                                    weight_decay=cfg.weight_decay)
        self._rng = np.random.default_rng([self.seed, 1])
        self._gen = torch.Generator().manual_seed(self.seed + 2)
        self._x_parts: list[torch.Tensor] = []
        self._y_parts: list[np.ndarray] = []
        self._x: torch.Tensor | None = None
        self._y: torch.Tensor | None = None
        self.rounds_trained = 0

    # ------------------------------------------------------------------ data
    @property
    def n_views(self) -> int:
        return int(sum(len(y) for y in self._y_parts))

    def labels(self) -> np.ndarray:
        return np.concatenate(self._y_parts) if self._y_parts else np.zeros(0, dtype=np.int64)

    def add_touch(self, img: np.ndarray, label: int) -> None:
        """Store ``augment`` random rotations of a (240, 320, 3) uint8 frame under ``label``."""
        if not 0 <= label < self.num_classes:
            raise TactexError(f"label {label} outside 0..{self.num_classes - 1}")
        img = validate_frame(img, f"touch of platform {label}")
        views = augment(img, self.cfg.augment, self.cfg.input_size, self._rng)
        self._x_parts.append(to_tensor(views, self.cfg.fourier))
        self._y_parts.append(np.full(len(views), label, dtype=np.int64))
        self._x = self._y = None

    def test_tensor(self, img: np.ndarray) -> torch.Tensor:
        """Reference views for scoring: (V, 3, S, S); V = test_views, the first unrotated."""
        img = validate_frame(img, "reference touch")
        if self.cfg.test_views == 1:
            views = view(img, 0.0, self.cfg.input_size)[None]
        else:
            views = augment(img, self.cfg.test_views, self.cfg.input_size,
                            np.random.default_rng([self.seed, 3]), include_identity=True)
        return to_tensor(views, self.cfg.fourier)

    def _dataset(self) -> tuple[torch.Tensor, torch.Tensor]:
        if self._x is None:
            if not self._x_parts:
                raise TactexError("no touches stored: nothing to train on")
            self._x = torch.cat(self._x_parts)
            self._y = torch.from_numpy(np.concatenate(self._y_parts))
        return self._x, self._y  # type: ignore[return-value]

    # ------------------------------------------------------------------ training
    def train_round(self) -> TrainStats:
        """One round of training (epochs or steps schedule); returns time and mean loss."""
        t0 = time.perf_counter()
        x, y = self._dataset()
        n = x.shape[0]
        weights = torch.from_numpy(class_weights(y.numpy(), self.num_classes)).float()
        bs = min(self.cfg.batch_size, n)
        if self.cfg.steps > 0:
            batches = [torch.randint(0, n, (bs,), generator=self._gen)
                       for _ in range(self.cfg.steps)]
        else:
            batches = []
            for _ in range(self.cfg.epochs):
                perm = torch.randperm(n, generator=self._gen)
                batches += [perm[i:i + bs] for i in range(0, n, bs)]
        self.model.train()
        losses = []
        with torch.random.fork_rng(devices=[]):
            torch.manual_seed(int(torch.randint(0, 2**62, (1,), generator=self._gen)))
            for idx in batches:
                if idx.numel() < 2:  # batch norm needs two samples in training mode
                    continue
                logits, aux = self.model.forward_train(x[idx])
                loss = F.cross_entropy(logits, y[idx], weight=weights)
                if aux is not None:
                    loss = loss + 0.4 * F.cross_entropy(aux, y[idx], weight=weights)
                if not torch.isfinite(loss):
                    raise FloatingPointError(f"training loss became {loss.item()}")
                self.opt.zero_grad(set_to_none=True)
                loss.backward()
                self.opt.step()
                losses.append(float(loss.detach()))
        if self.cfg.bn_recalibrate:
            self._recalibrate_bn(x)
        self.rounds_trained += 1
        return TrainStats(time.perf_counter() - t0, len(losses),
                          float(np.mean(losses)) if losses else float("nan"))

    @torch.no_grad()
    def _recalibrate_bn(self, x: torch.Tensor) -> None:
        """Re-estimate batch-norm running statistics on a random subset of the stored views.

        After a few optimiser steps the exponential running averages still lag far behind the
        weights, and every eval-mode pass (MC scoring, prediction) would use stale statistics.
        A cumulative average over up to ``bn_recalibrate`` views under the current weights fixes
        that at the cost of one forward pass, without touching the weights.
        """
        n = min(x.shape[0], self.cfg.bn_recalibrate)
        idx = torch.randperm(x.shape[0], generator=self._gen)[:n]
        bns = [m for m in self.model.modules() if isinstance(m, torch.nn.BatchNorm2d)]
        saved = [m.momentum for m in bns]
        for m in bns:
            m.reset_running_stats()
            m.momentum = None  # cumulative moving average
        self.model.train()
        bs = max(2, self.cfg.batch_size)
        for i in range(0, n, bs):
            chunk = idx[i:i + bs]
            if chunk.numel() >= 2:
                self.model(x[chunk])
        for m, mom in zip(bns, saved):
            m.momentum = mom

    # ------------------------------------------------------------------ scoring
    def mc_probs(self, x_test: torch.Tensor, passes: int | None = None) -> np.ndarray:
        """(T, C) float64 softmax of the reference views over T stochastic passes."""
        return mc_probs(self.model, x_test, passes or self.cfg.mc_passes,
                        generator=self._gen).double().numpy()

    @torch.no_grad()
    def predict_proba(self, x: torch.Tensor, batch: int = 256) -> np.ndarray:
        """Deterministic (eval-mode) softmax for (N, 3, S, S) inputs -> (N, C)."""
        self.model.eval()
        out = [torch.softmax(self.model(x[i:i + batch]), 1) for i in range(0, len(x), batch)]
        return torch.cat(out).double().numpy()
