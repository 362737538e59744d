"""The online learner: stores augmented touches, trains across rounds, scores its uncertainty.

Classes are the C comparison platforms. Each stored touch becomes ``augment`` rotated views,
converted to a tensor once when added (never again on the per-round path). Training uses
cross-entropy weighted by the number of views per class, w_c = N / (C * n_c), and continues from
the previous round's weights and optimiser state.

Two training schedules:

- ``epochs`` (thesis): E full shuffled passes over all N stored views; cost grows with N.
- ``steps``: S minibatches drawn uniformly from the stored views; cost is constant in N.

Uncertainty (``uncertainty``, ``cnn/uncertainty.py``): ``mc_dropout`` (the thesis), ``ensemble``
(K heads over the shared stem, trained on the same minibatches with their own init and dropout
masks, each with its own cross-entropy; the (K, C) table of the members) or ``laplace`` (after
each round a last-layer Laplace posterior is fitted on the stored views' features; the table
holds ``mc_passes`` posterior draws).

Determinism: every random draw comes from generators seeded by ``seed`` (model init, view
angles, minibatch order, dropout masks in training and scoring), never from global state that
other code could have advanced.

Device (``device``, ``cnn/device.py``): the model, the optimiser's state, the stored views and
labels, the reference views, the class weights and the MC passes live on it; the model is
initialised on the CPU (same weights on every device) and moved once. Every seeded draw that is
not a dropout mask (view angles, minibatch order, batch-norm subsets) is made by the CPU
generators as before and moved to the device once per round (one (steps, batch) index tensor),
so the CPU path is bit for bit today's and a CUDA trial sees the same minibatches; dropout masks
on a GPU come from its own generator, seeded from the same stream (equal in distribution, not
bit for bit). Per step only the finiteness of loss and gradient norm is read back (the guards);
the Laplace posterior is fitted and sampled on the CPU in float64 from the features.
"""

from __future__ import annotations

import copy
import io
import json
import time

import numpy as np
import torch
import torch.nn.functional as F

from tactex_lab.cnn.device import configure, resolve_device, rng_devices, to_cpu
from tactex_lab.cnn.models import build_model
from tactex_lab.cnn.preprocess import augment, safe_crop_side, to_tensor, view
from tactex_lab.cnn.uncertainty import LastLayerLaplace, ensemble_probs, mc_probs
from tactex_ros.core.config import CNN_MODELS, CnnSettings, learner_class
from tactex_ros.core.errors import InputError
from tactex_ros.core.learners import TrainStats
from tactex_ros.core.touch import Touch, as_touch, validate_frame


#: Largest last layer (weights incl. bias) given a full Laplace posterior: its (P, P) precision
#: is decomposed every round (P = 3000: 72 MB, about a second).
LAPLACE_MAX_WEIGHTS = 3000


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

    def __init__(self, num_classes: int, cfg: CnnSettings, seed: int = 0,
                 model_name: str | None = None) -> None:
        self.cfg = cfg
        self.num_classes = num_classes
        self.seed = int(seed)
        name = model_name or cfg.model
        if not learner_class(name).plugin:
            raise InputError(f"model {name!r} is not a CNN; choose one of "
                             f"{', '.join(CNN_MODELS)}")
        if cfg.threads:
            torch.set_num_threads(cfg.threads)
        self.device = resolve_device(cfg.device)
        configure(self.device, cfg.deterministic)
        with torch.random.fork_rng(devices=[]):
            torch.manual_seed(self.seed)
            self.model, self.load_report = build_model(
                name, num_classes, dropout=cfg.dropout, block_dropout=cfg.block_dropout,
                aux_logits=cfg.aux_logits, weights=cfg.weights or None,
                heads=cfg.ensemble_heads if cfg.uncertainty == "ensemble" else 1)
        self.model_name = name
        if cfg.sensor_crops and cfg.input_size > int(safe_crop_side()):
            raise InputError(f"sensor_crops: input_size {cfg.input_size} px does not fit the "
                             f"frame under rotation (at most {int(safe_crop_side())} px)")
        if cfg.uncertainty == "laplace":
            n_in = self.model.fc.in_features + 1
            if num_classes * n_in > LAPLACE_MAX_WEIGHTS:
                raise InputError(
                    f"uncertainty 'laplace' keeps a full posterior over the last layer's "
                    f"{num_classes * n_in} weights ({num_classes} platforms x {n_in} inputs of "
                    f"model {name}); at most {LAPLACE_MAX_WEIGHTS} are supported: with this "
                    f"model at most {LAPLACE_MAX_WEIGHTS // n_in} comparisons, or a model with "
                    f"a smaller last layer (small_inception), or uncertainty 'ensemble'")
        self._fmt = torch.channels_last if cfg.channels_last else torch.contiguous_format
        self.model = self.model.to(device=self.device, memory_format=self._fmt)
        self.opt = torch.optim.Adam(self.model.parameters(), lr=cfg.lr,
                                    weight_decay=cfg.weight_decay)
        self._rng = np.random.default_rng([self.seed, 1])
        self._gen = torch.Generator().manual_seed(self.seed + 2)
        self._x_parts: list[torch.Tensor] = []
        self._y_parts: list[np.ndarray] = []
        self._x: torch.Tensor | None = None
        self._y: torch.Tensor | None = None
        self._ref_parts: list[torch.Tensor] = []
        self.laplace: LastLayerLaplace | None = None
        self.rounds_trained = 0

    # ------------------------------------------------------------------ data
    @property
    def n_views(self) -> int:
        return int(sum(len(y) for y in self._y_parts))

    def labels(self) -> np.ndarray:
        return np.concatenate(self._y_parts) if self._y_parts else np.zeros(0, dtype=np.int64)

    def add_touch(self, img: Touch | np.ndarray, label: int) -> torch.Tensor:
        """Store ``augment`` random rotations of a (240, 320, 3) uint8 frame under ``label``.

        A ``Touch`` contributes its contact frame (the CNN sees frames as they are).

        Returns the stored views (augment, 3, S, S): until the next ``train_round`` the model
        has not seen them, so they can serve as a held-back check (``heldout_proba``).
        """
        if not 0 <= label < self.num_classes:
            raise InputError(f"label {label} outside 0..{self.num_classes - 1}")
        img = self._colour_norm(validate_frame(as_touch(img).frame, f"touch of platform {label}"))
        views = augment(img, self.cfg.augment, self.cfg.input_size, self._rng,
                        native=self.cfg.sensor_crops)
        x = self._on_device(to_tensor(views, self.cfg.fourier))
        self._x_parts.append(x)
        self._y_parts.append(np.full(len(views), label, dtype=np.int64))
        self._x = self._y = None
        return x

    def _colour_norm(self, img: np.ndarray) -> np.ndarray:
        """With ``drift_norm``: shift each channel so its frame mean is the catalogue-wide grey
        128 (a per-touch lighting offset then no longer reaches the model)."""
        if not self.cfg.drift_norm:
            return img
        m = img.reshape(-1, 3).mean(axis=0)
        return np.clip(img.astype(np.float32) - m + 128.0, 0, 255).astype(np.uint8)

    def add_reference(self, img: Touch | np.ndarray) -> None:
        """Store a reference touch's views; decisions average over every reference touch."""
        self._ref_parts.append(self.test_tensor(img))

    def reference_probs(self) -> np.ndarray:
        """(T, C) softmax table of the reference, averaged over all its touches' views: T MC
        dropout passes, K ensemble members or T Laplace posterior draws (``uncertainty``)."""
        if not self._ref_parts:
            raise InputError("no reference touch stored")
        return self.uncertainty_probs(torch.cat(self._ref_parts))

    def uncertainty_probs(self, x: torch.Tensor) -> np.ndarray:
        """(T, C) float64 table for the views ``x`` (V, 3, S, S) from the configured source."""
        x = x.to(self.device)
        kind = self.cfg.uncertainty
        if kind == "ensemble":
            return ensemble_probs(self.model, x).double().cpu().numpy()
        if kind == "laplace":
            if self.laplace is None:
                raise InputError("uncertainty 'laplace': no posterior before the first "
                                 "training round")
            with torch.no_grad():
                self.model.eval()
                feats = self.model.features(x).cpu()
            return self.laplace.sample_probs(feats, self.cfg.mc_passes, self._gen).numpy()
        return self.mc_probs(x)

    def belief(self, probs: np.ndarray) -> np.ndarray:
        """(C,) mean softmax over the table's rows: the CNN's belief over the matching
        platform."""
        return np.asarray(probs, dtype=np.float64).mean(axis=0)

    def test_tensor(self, img: Touch | np.ndarray) -> torch.Tensor:
        """Reference views for scoring: (V, 3, S, S); V = test_views, the first unrotated."""
        img = self._colour_norm(validate_frame(as_touch(img).frame, "reference touch"))
        if self.cfg.test_views == 1:
            views = view(img, 0.0, self.cfg.input_size, native=self.cfg.sensor_crops)[None]
        else:
            views = augment(img, self.cfg.test_views, self.cfg.input_size,
                            np.random.default_rng([self.seed, 3]), include_identity=True,
                            native=self.cfg.sensor_crops)
        return self._on_device(to_tensor(views, self.cfg.fourier))

    def _on_device(self, x: torch.Tensor) -> torch.Tensor:
        """(V, 3, S, S) CPU views -> on the learner's device in its memory format (one copy)."""
        if self.device.type == "cpu":
            return x.contiguous(memory_format=self._fmt)
        return x.to(device=self.device, memory_format=self._fmt)

    def _fork_rng(self):
        """A block whose global torch random state (CPU and, on a GPU, the device's) is
        restored on exit: the seeded dropout masks never disturb other code's draws."""
        return torch.random.fork_rng(devices=rng_devices(self.device))

    def _dataset(self) -> tuple[torch.Tensor, torch.Tensor]:
        if self._x is None:
            if not self._x_parts:
                raise InputError("no touches stored: nothing to train on")
            self._x = torch.cat(self._x_parts).contiguous(memory_format=self._fmt)
            self._y = torch.from_numpy(np.concatenate(self._y_parts)).to(self.device)
        return self._x, self._y  # type: ignore[return-value]

    # ------------------------------------------------------------------ training
    def train_round(self) -> TrainStats:
        """One round of training (epochs or steps schedule); returns time and mean loss.

        With ``guards`` (default): gradients are clipped to ``grad_clip``; a step whose loss or
        gradient is not finite is skipped; when more than half the steps of a round were bad (or
        the weights went non-finite) the round is rolled back to its starting weights and
        optimiser state and the learning rate is halved. Without guards a non-finite loss
        raises FloatingPointError (the trial fails).
        """
        t0 = time.perf_counter()
        x, y = self._dataset()
        n = x.shape[0]
        weights = torch.from_numpy(class_weights(self.labels(), self.num_classes)).float()
        bs = min(self.cfg.batch_size, n)
        if self.cfg.steps > 0:
            batches = [torch.randint(0, n, (bs,), generator=self._gen)
                       for _ in range(self.cfg.steps)]
        else:
            batches = []
            for _ in range(self.cfg.epochs):
                perm = torch.randperm(n, generator=self._gen)
                batches += [perm[i:i + bs] for i in range(0, n, bs)]
        if self.device.type != "cpu":       # drawn on the CPU as always, moved once per round
            weights = weights.to(self.device)
            batches = _to_device(batches, self.device)
        guards = self.cfg.guards
        clip = self.cfg.grad_clip if guards else 0.0
        snapshot = None
        if guards:
            snapshot = ({k: v.detach().clone() for k, v in self.model.state_dict().items()},
                        copy.deepcopy(self.opt.state_dict()))
        params = [p for p in self.model.parameters() if p.requires_grad]
        self.model.train()
        losses, norms, skipped = [], [], 0
        with self._fork_rng():
            torch.manual_seed(int(torch.randint(0, 2**62, (1,), generator=self._gen)))
            for idx in batches:
                if idx.numel() < 2:  # batch norm needs two samples in training mode
                    continue
                logits, aux = self.model.forward_train(x[idx])
                target = y[idx]
                if logits.dim() == 3:           # ensemble (B, K, C): every member's loss
                    target = target.repeat_interleave(logits.shape[1])
                    logits = logits.reshape(-1, logits.shape[2])
                loss = F.cross_entropy(logits, target, weight=weights)
                if aux is not None:
                    loss = loss + 0.4 * F.cross_entropy(aux, y[idx], weight=weights)
                if not torch.isfinite(loss):
                    if not guards:
                        raise FloatingPointError(f"training loss became {loss.item()}")
                    skipped += 1
                    continue
                self.opt.zero_grad(set_to_none=True)
                loss.backward()
                if guards:
                    gn = torch.nn.utils.clip_grad_norm_(params, clip if clip > 0 else float("inf"))
                    if not torch.isfinite(gn):
                        skipped += 1
                        self.opt.zero_grad(set_to_none=True)
                        continue
                    norms.append(gn.detach())
                self.opt.step()
                losses.append(loss.detach())
        losses = torch.stack(losses).tolist() if losses else []
        norms = torch.stack(norms).tolist() if norms else []
        restored = False
        if guards and snapshot is not None and batches and (
                skipped > len(batches) // 2 or
                not all(bool(torch.isfinite(p).all()) for p in params)):
            self.model.load_state_dict(snapshot[0])
            self.opt.load_state_dict(snapshot[1])
            for g in self.opt.param_groups:
                g["lr"] *= 0.5
            restored = True
        if self.cfg.bn_recalibrate:
            self._recalibrate_bn(x)
        if self.cfg.uncertainty == "laplace":
            self._fit_laplace(x, y)
        self.rounds_trained += 1
        return TrainStats(time.perf_counter() - t0, len(losses),
                          float(np.mean(losses)) if losses else float("nan"), skipped,
                          float(np.median(norms)) if norms else float("nan"), restored)

    def transfer_from(self, other: OnlineLearner) -> int:
        """Start from ``other``'s weights where names and shapes match; returns tensors copied.

        Same variant (e.g. a larger input for ``small_inception``): everything, classifier too.
        ``small_inception`` -> ``inception_v3*``: the stem (its keys are a subset).
        """
        from tactex_lab.cnn.models import load_weights
        rep = load_weights(self.model, other.model.state_dict(),
                           keep_head=other.model_name == self.model_name)
        self.model.to(memory_format=self._fmt)
        return len(rep.loaded)

    # ------------------------------------------------------------------ checkpoint
    def _identity(self) -> dict:
        """What a saved state must match: model, classes, seed, every learner setting but where
        it runs (``device``, ``deterministic``: a state saved on a GPU continues on the CPU and
        back)."""
        cfg = self.cfg.model_dump(exclude={"device", "deterministic"})
        return {"model": self.model_name, "classes": self.num_classes, "seed": self.seed,
                "cfg": json.dumps(cfg, sort_keys=True, default=str)}

    def save_state(self) -> bytes:
        """The learner's state after a round (``StatefulLearner``): weights, optimiser
        (learning rate included), the generators of training and scoring, the Laplace
        posterior, and what checks the stored views on load (their count, the view-angle
        generator's state). The views themselves are not written: ``load_state`` expects the
        same touches added again, which rebuilds them bit for bit. Tensors are written on the
        CPU whatever the device."""
        lap = self.laplace
        state = {"identity": self._identity(), "rounds_trained": self.rounds_trained,
                 "model": self.model.state_dict(), "opt": self.opt.state_dict(),
                 "gen": self._gen.get_state(),
                 "rng": json.dumps(self._rng.bit_generator.state),
                 "views": self.n_views, "references": len(self._ref_parts),
                 "laplace": None if lap is None else
                 {"theta": lap.theta, "precision": lap.precision,
                  "prior_precision": lap.prior_precision}}
        if self.device.type != "cpu":       # written device-free: it loads on any machine
            state = to_cpu(state)
        buf = io.BytesIO()
        torch.save(state, buf)
        return buf.getvalue()

    def load_state(self, data: bytes) -> None:
        """Continue from ``save_state``'s bytes; InputError (named) when they are not a state
        of this learner (other model, settings or seed) or the touches added since it was
        built are not the ones it was saved with."""
        try:
            st = torch.load(io.BytesIO(data), map_location="cpu", weights_only=True)
        except Exception as exc:  # noqa: BLE001 - torch raises many kinds for bad bytes
            raise InputError(f"learner state unreadable ({type(exc).__name__}: {exc})") \
                from None
        if not isinstance(st, dict) or st.get("identity") != self._identity():
            raise InputError("learner state of another model, setting or seed")
        if st.get("views") != self.n_views or st.get("references") != len(self._ref_parts) \
                or st.get("rng") != json.dumps(self._rng.bit_generator.state):
            raise InputError(f"learner state saved with {st.get('views')} views and "
                             f"{st.get('references')} reference touches, the touches added "
                             f"again give {self.n_views} and {len(self._ref_parts)} (or "
                             "other views)")
        try:
            self.model.load_state_dict(st["model"])
            self.opt.load_state_dict(st["opt"])
            self._gen.set_state(st["gen"].cpu())
        except (KeyError, RuntimeError, ValueError) as exc:
            raise InputError(f"learner state does not fit the model ({exc})") from None
        self.model.to(memory_format=self._fmt)
        lap = st.get("laplace")
        self.laplace = None if lap is None else LastLayerLaplace(
            lap["theta"].cpu(), lap["precision"].cpu(), float(lap["prior_precision"]))
        self.rounds_trained = int(st["rounds_trained"])

    @torch.no_grad()
    def heldout_proba(self, x: torch.Tensor) -> np.ndarray:
        """(C,) eval-mode softmax averaged over the views of one not-yet-trained-on touch."""
        return self.predict_proba(x).mean(axis=0)

    @torch.no_grad()
    def _fit_laplace(self, x: torch.Tensor, y: torch.Tensor, batch: int = 256) -> None:
        """Last-layer Laplace posterior around the trained classifier, on the features of every
        stored view (eval mode)."""
        self.model.eval()
        feats = torch.cat([self.model.features(x[i:i + batch]) for i in range(0, len(x), batch)])
        fc = self.model.fc
        self.laplace = LastLayerLaplace.fit(fc.weight.cpu(), fc.bias.cpu(), feats.cpu(), y.cpu(),
                                            self.cfg.laplace_prior_precision)

    @torch.no_grad()
    def _recalibrate_bn(self, x: torch.Tensor) -> None:
        """Re-estimate batch-norm running statistics on a random subset of the stored views.

        After a few optimiser steps the exponential running averages still lag far behind the
        weights, and every eval-mode pass (MC scoring, prediction) would use stale statistics.
        A cumulative average over up to ``bn_recalibrate`` views under the current weights fixes
        that at the cost of one forward pass, without touching the weights.
        """
        n = min(x.shape[0], self.cfg.bn_recalibrate)
        idx = torch.randperm(x.shape[0], generator=self._gen)[:n].to(self.device)
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
        for m, mom in zip(bns, saved, strict=True):
            m.momentum = mom

    # ------------------------------------------------------------------ scoring
    def mc_probs(self, x_test: torch.Tensor, passes: int | None = None) -> np.ndarray:
        """(T, C) float64 softmax of the reference views over T stochastic passes."""
        return mc_probs(self.model, x_test.to(self.device), passes or self.cfg.mc_passes,
                        generator=self._gen).double().cpu().numpy()

    @torch.inference_mode()
    def predict_proba(self, x: torch.Tensor, batch: int = 256) -> np.ndarray:
        """Deterministic (eval-mode) softmax for (N, 3, S, S) inputs -> (N, C)."""
        self.model.eval()
        x = x.to(self.device)
        out = [torch.softmax(self.model(x[i:i + batch]), 1) for i in range(0, len(x), batch)]
        return torch.cat(out).double().cpu().numpy()


def _to_device(batches: list[torch.Tensor], device: torch.device) -> list[torch.Tensor]:
    """A round's minibatch index tensors (drawn on the CPU) on ``device`` in one copy."""
    if not batches:
        return batches
    sizes = [len(b) for b in batches]
    return list(torch.cat(batches).to(device).split(sizes))
