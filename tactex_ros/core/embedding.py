"""A learned texture embedding of a touch, computed with numpy alone (no torch on the shipped
path).

The network is a small CNN (the lab's ``tactex_lab/analysis/learned_features.py`` trains it):
four convolutions (3 -> 32, 5 x 5, stride 2; 32 -> 64, 3 x 3, stride 2; 64 -> 96, 3 x 3, stride
2; 96 -> 128, 3 x 3, stride 1), each followed by its batch normalisation and a ReLU, then the
global average over the image: a ``EMBED``-number embedding of each contact frame. The network
sees the contact difference (``texture.contact_difference``) subsampled by 2 (area), scaled as
it was trained (``norm``: the training set's standard deviation ``scale``, or each frame's own).

A weights file (``save`` / ``load``) is a numpy ``.npz`` archive read with
``allow_pickle=False``: per convolution ``conv<i>/weight`` (O, C, k, k) and ``conv<i>/bias``
(O,) with the batch normalisation folded in, its ``stride``, the input ``scale`` and ``norm``,
``format`` and what it was trained on (``trained_on``, JSON text).
"""

from __future__ import annotations

import hashlib
import json
from dataclasses import dataclass, field
from pathlib import Path

import cv2
import numpy as np
from numpy.lib.stride_tricks import sliding_window_view

from .errors import InputError
from .texture import contact_differences
from .touch import Touch

FORMAT = "tactex-embedding-1"
EMBED = 128
HALF = 2
NORMS = ("global", "image")
#: The network trained on the simulator's fabrics only (nothing recorded), shipped with the
#: product: ``learner.descriptor_embedding = "sim"`` (the lab's ``experiment sim-embedding``
#: makes it again).
SHIPPED = Path(__file__).resolve().parent / "data" / "embedding_sim.npz"


@dataclass
class Layer:
    """One convolution with its batch normalisation folded in, followed by a ReLU."""

    weight: np.ndarray     # (O, C, k, k) float32, the batch normalisation folded in
    bias: np.ndarray       # (O,) float32
    stride: int


@dataclass
class Embedding:
    """The network: its convolutions in order, its input scale and what it was trained on;
    called on (F, H, W, 3) contact differences it returns (F, ``dim``) embeddings."""

    layers: list[Layer]
    scale: float           # the training set's standard deviation of the input (norm "global")
    norm: str = "global"
    trained_on: dict = field(default_factory=dict)
    identity: str = ""     # the first 16 hex digits of the file's sha256 (``load``)

    @property
    def dim(self) -> int:
        """The embedding's size (the last convolution's outputs)."""
        return int(self.layers[-1].weight.shape[0])

    def prepare(self, differences: np.ndarray) -> np.ndarray:
        """(F, H, W, 3) contact differences -> (F, H/2, W/2, 3) float32 network input."""
        d = np.asarray(differences, dtype=np.float32)
        if d.ndim != 4 or d.shape[-1] != 3:
            raise InputError(f"embedding input: expected (frames, H, W, 3), got {d.shape}")
        x = np.stack([cv2.resize(f, (f.shape[1] // HALF, f.shape[0] // HALF),
                                 interpolation=cv2.INTER_AREA) for f in d])
        if self.norm == "image":
            return x / (x.std(axis=(1, 2, 3), keepdims=True) + 1e-6)
        return x / self.scale

    def forward(self, x: np.ndarray) -> np.ndarray:
        """(F, h, w, 3) float32 network input (``prepare``) -> (F, dim) float32 embeddings.
        The matrix products run on one BLAS thread: the same numbers in every process, however
        many threads its BLAS was given (a worker of a parallel sweep, a ROS node)."""
        with _one_blas_thread():
            for layer in self.layers:
                x = _conv_relu(x, layer)
        return x.mean(axis=(1, 2))

    def __call__(self, differences: np.ndarray) -> np.ndarray:
        """(F, H, W, 3) contact differences -> (F, dim) embeddings."""
        return self.forward(self.prepare(differences))

    def save(self, path: str | Path) -> None:
        """Write the weights file ``path`` (the module's format; ``load`` reads it)."""
        arrays = {}
        for i, layer in enumerate(self.layers):
            arrays[f"conv{i}/weight"] = layer.weight
            arrays[f"conv{i}/bias"] = layer.bias
            arrays[f"conv{i}/stride"] = np.array(layer.stride)
        np.savez_compressed(path, format=np.array(FORMAT), scale=np.array(self.scale),
                            norm=np.array(self.norm),
                            trained_on=np.array(json.dumps(self.trained_on)), **arrays)


_CONTROLLER = None


def _one_blas_thread():
    """A context in which numpy's BLAS uses one thread (threadpoolctl): a float32 matrix
    product's sums then run in one order, whatever the process's thread count."""
    global _CONTROLLER
    if _CONTROLLER is None:
        from threadpoolctl import ThreadpoolController
        _CONTROLLER = ThreadpoolController()
    return _CONTROLLER.limit(limits=1, user_api="blas")


def _conv_relu(x: np.ndarray, layer: Layer) -> np.ndarray:
    """(F, H, W, C) -> (F, H', W', O): the convolution (padding k // 2) and a ReLU."""
    o, c, k, _ = layer.weight.shape
    p = k // 2
    xp = np.pad(x, ((0, 0), (p, p), (p, p), (0, 0)))
    win = sliding_window_view(xp, (k, k), axis=(1, 2))[:, ::layer.stride, ::layer.stride]
    # win: (F, H', W', C, k, k) -> one contiguous (F H' W', k k C) copy (the channels last, as
    # in memory: half the time of a product over the strided view), times (k k C, O)
    f, h, w = win.shape[:3]
    cols = np.ascontiguousarray(win.transpose(0, 1, 2, 4, 5, 3)).reshape(f * h * w, k * k * c)
    y = (cols @ layer.weight.transpose(2, 3, 1, 0).reshape(k * k * c, o)).reshape(f, h, w, o)
    y += layer.bias
    return np.maximum(y, 0.0, out=y)


def resolve(name: str) -> Path:
    """The weights file of ``learner.descriptor_embedding = name``: ``SHIPPED``'s file for
    "sim", else ``name`` itself (a file the lab exported)."""
    return SHIPPED if name == "sim" else Path(name)


_LOADED: dict[str, Embedding] = {}


def load(path: str | Path) -> Embedding:
    """Read a weights file (loaded once per process and path); InputError naming the file when
    it is not one."""
    from .outputs import read_npz
    key = str(Path(path).resolve())
    if key in _LOADED:
        return _LOADED[key]
    remedy = "use learner.descriptor_embedding=sim or a file the lab exported"
    z = read_npz(path, "embedding file", FORMAT, remedy)
    layers = []
    try:
        while f"conv{len(layers)}/weight" in z:
            i = len(layers)
            w, b = z[f"conv{i}/weight"].astype(np.float32), z[f"conv{i}/bias"].astype(np.float32)
            if w.ndim != 4 or b.shape != (w.shape[0],) or (
                    layers and w.shape[1] != layers[-1].weight.shape[0]):
                raise ValueError(f"conv{i} shapes {w.shape}, {b.shape}")
            layers.append(Layer(w, b, int(z[f"conv{i}/stride"])))
        norm = str(z["norm"])
        emb = Embedding(layers, float(z["scale"]), norm, json.loads(str(z["trained_on"])))
    except (ValueError, KeyError, TypeError) as exc:
        raise InputError(f"embedding file {path}: unreadable ({exc}); {remedy}") from None
    if not layers or layers[0].weight.shape[1] != 3:
        raise InputError(f"embedding file {path}: no convolution of the 3 colour channels")
    if norm not in NORMS:
        raise InputError(f"embedding file {path}: norm {norm!r} is not one of {NORMS}")
    emb.identity = hashlib.sha256(Path(path).read_bytes()).hexdigest()[:16]
    _LOADED[key] = emb
    return emb


def embed_touch(touch: Touch, max_frames: int, emb: Embedding,
                no_contact: bool = True) -> np.ndarray:
    """(dim,) the mean embedding over up to ``max_frames`` contact frames of ``touch`` (the
    strongest and ``Touch.extra``), each on its contact difference (``no_contact`` False: against
    the frame's own blur, as ``learner.descriptor_no_contact = false``)."""
    nc = touch.no_contact if no_contact else None
    frames = [touch.frame] + (list(touch.extra[:max_frames - 1])
                              if touch.extra is not None and max_frames > 1 else [])
    d = contact_differences(frames, nc)
    return emb(d).mean(axis=0).astype(np.float64)


def from_torch(state: dict[str, np.ndarray], strides: tuple[int, ...], scale: float,
               norm: str, trained_on: dict, eps: float = 1e-5) -> Embedding:
    """An ``Embedding`` from the lab network's state dict (numpy arrays of an
    ``nn.Sequential`` of (Conv2d without bias, BatchNorm2d, ReLU) blocks): each batch
    normalisation folded into its convolution."""
    convs = sorted({k.split(".")[0] for k in state if state[k].ndim == 4}, key=int)
    if len(convs) != len(strides):
        raise InputError(f"{len(convs)} convolutions but {len(strides)} strides")
    layers = []
    for c, stride in zip(convs, strides, strict=True):
        bn = str(int(c) + 1)
        g = state[f"{bn}.weight"] / np.sqrt(state[f"{bn}.running_var"] + eps)
        w = state[f"{c}.weight"] * g[:, None, None, None]
        b = state[f"{bn}.bias"] - state[f"{bn}.running_mean"] * g
        layers.append(Layer(w.astype(np.float32), b.astype(np.float32), int(stride)))
    return Embedding(layers, float(scale), norm, dict(trained_on))
