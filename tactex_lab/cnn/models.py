"""Inception v3 family in plain torch, with torchvision's parameter names and shapes.

Variants (``build_model``):

- ``inception_v3``: the full network; a torchvision checkpoint (``inception_v3(aux_logits=True)``
  state_dict, e.g. the ImageNet ``.pth`` a lab already has) loads tensor by tensor; ``fc`` (and
  ``AuxLogits.fc``) are re-created for the number of platforms.
- ``inception_v3_random``: the same network, randomly initialised (torchvision's init).
- ``small_inception``: the thesis's small network: stem ``Conv2d_1a_3x3`` .. ``Conv2d_4a_3x3`` and
  its max pool, then average pool, dropout, fully connected (192 -> classes). Its keys are a
  subset of the full network's, so the stem of an ImageNet checkpoint loads into it too.

MC dropout: ``dropout`` before the classifier (rate ``p``) and, when ``block_dropout > 0``,
``nn.Dropout2d``-free element dropout after the stem and after every Inception block. Dropout
modules hold no parameters, so they never change the state_dict keys.

Every model splits into ``prefix`` (deterministic part up to the first dropout) and ``suffix``
(the rest), so Monte-Carlo passes can run the prefix once and only the stochastic suffix T times.
Input: float tensor (B, 3, H, W), ImageNet-normalised RGB. Output: logits (B, classes).

Ensemble of heads (``heads`` K > 1): ``fc`` holds K linear heads over the shared features
(weight (K*C, F), rows k*C..k*C+C-1 for member k, each drawn by the same init), each behind its
own dropout mask. ``member_logits`` gives (B, K, C); ``forward`` returns the log of the members'
mean softmax, so ``softmax(forward(x))`` is the ensemble's prediction.
"""

from __future__ import annotations

import math
from collections import OrderedDict
from pathlib import Path

import torch
import torch.nn.functional as F
from torch import nn

from tactex_ros.core.errors import InputError
from tactex_ros.core.config import CNN_MODELS as MODEL_NAMES


class BasicConv2d(nn.Module):
    """conv (no bias) -> batch norm (eps 1e-3) -> ReLU, named ``conv`` and ``bn``."""

    def __init__(self, in_ch: int, out_ch: int, **kwargs) -> None:
        super().__init__()
        self.conv = nn.Conv2d(in_ch, out_ch, bias=False, **kwargs)
        self.bn = nn.BatchNorm2d(out_ch, eps=0.001)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        return F.relu(self.bn(self.conv(x)), inplace=True)


class InceptionA(nn.Module):
    def __init__(self, in_ch: int, pool_features: int) -> None:
        super().__init__()
        self.branch1x1 = BasicConv2d(in_ch, 64, kernel_size=1)
        self.branch5x5_1 = BasicConv2d(in_ch, 48, kernel_size=1)
        self.branch5x5_2 = BasicConv2d(48, 64, kernel_size=5, padding=2)
        self.branch3x3dbl_1 = BasicConv2d(in_ch, 64, kernel_size=1)
        self.branch3x3dbl_2 = BasicConv2d(64, 96, kernel_size=3, padding=1)
        self.branch3x3dbl_3 = BasicConv2d(96, 96, kernel_size=3, padding=1)
        self.branch_pool = BasicConv2d(in_ch, pool_features, kernel_size=1)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        b1 = self.branch1x1(x)
        b5 = self.branch5x5_2(self.branch5x5_1(x))
        b3 = self.branch3x3dbl_3(self.branch3x3dbl_2(self.branch3x3dbl_1(x)))
        bp = self.branch_pool(F.avg_pool2d(x, kernel_size=3, stride=1, padding=1))
        return torch.cat([b1, b5, b3, bp], 1)


class InceptionB(nn.Module):
    def __init__(self, in_ch: int) -> None:
        super().__init__()
        self.branch3x3 = BasicConv2d(in_ch, 384, kernel_size=3, stride=2)
        self.branch3x3dbl_1 = BasicConv2d(in_ch, 64, kernel_size=1)
        self.branch3x3dbl_2 = BasicConv2d(64, 96, kernel_size=3, padding=1)
        self.branch3x3dbl_3 = BasicConv2d(96, 96, kernel_size=3, stride=2)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        b3 = self.branch3x3(x)
        bd = self.branch3x3dbl_3(self.branch3x3dbl_2(self.branch3x3dbl_1(x)))
        bp = F.max_pool2d(x, kernel_size=3, stride=2)
        return torch.cat([b3, bd, bp], 1)


class InceptionC(nn.Module):
    def __init__(self, in_ch: int, channels_7x7: int) -> None:
        super().__init__()
        c7 = channels_7x7
        self.branch1x1 = BasicConv2d(in_ch, 192, kernel_size=1)
        self.branch7x7_1 = BasicConv2d(in_ch, c7, kernel_size=1)
        self.branch7x7_2 = BasicConv2d(c7, c7, kernel_size=(1, 7), padding=(0, 3))
        self.branch7x7_3 = BasicConv2d(c7, 192, kernel_size=(7, 1), padding=(3, 0))
        self.branch7x7dbl_1 = BasicConv2d(in_ch, c7, kernel_size=1)
        self.branch7x7dbl_2 = BasicConv2d(c7, c7, kernel_size=(7, 1), padding=(3, 0))
        self.branch7x7dbl_3 = BasicConv2d(c7, c7, kernel_size=(1, 7), padding=(0, 3))
        self.branch7x7dbl_4 = BasicConv2d(c7, c7, kernel_size=(7, 1), padding=(3, 0))
        self.branch7x7dbl_5 = BasicConv2d(c7, 192, kernel_size=(1, 7), padding=(0, 3))
        self.branch_pool = BasicConv2d(in_ch, 192, kernel_size=1)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        b1 = self.branch1x1(x)
        b7 = self.branch7x7_3(self.branch7x7_2(self.branch7x7_1(x)))
        bd = self.branch7x7dbl_1(x)
        for layer in (self.branch7x7dbl_2, self.branch7x7dbl_3, self.branch7x7dbl_4,
                      self.branch7x7dbl_5):
            bd = layer(bd)
        bp = self.branch_pool(F.avg_pool2d(x, kernel_size=3, stride=1, padding=1))
        return torch.cat([b1, b7, bd, bp], 1)


class InceptionD(nn.Module):
    def __init__(self, in_ch: int) -> None:
        super().__init__()
        self.branch3x3_1 = BasicConv2d(in_ch, 192, kernel_size=1)
        self.branch3x3_2 = BasicConv2d(192, 320, kernel_size=3, stride=2)
        self.branch7x7x3_1 = BasicConv2d(in_ch, 192, kernel_size=1)
        self.branch7x7x3_2 = BasicConv2d(192, 192, kernel_size=(1, 7), padding=(0, 3))
        self.branch7x7x3_3 = BasicConv2d(192, 192, kernel_size=(7, 1), padding=(3, 0))
        self.branch7x7x3_4 = BasicConv2d(192, 192, kernel_size=3, stride=2)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        b3 = self.branch3x3_2(self.branch3x3_1(x))
        b7 = self.branch7x7x3_4(self.branch7x7x3_3(self.branch7x7x3_2(self.branch7x7x3_1(x))))
        bp = F.max_pool2d(x, kernel_size=3, stride=2)
        return torch.cat([b3, b7, bp], 1)


class InceptionE(nn.Module):
    def __init__(self, in_ch: int) -> None:
        super().__init__()
        self.branch1x1 = BasicConv2d(in_ch, 320, kernel_size=1)
        self.branch3x3_1 = BasicConv2d(in_ch, 384, kernel_size=1)
        self.branch3x3_2a = BasicConv2d(384, 384, kernel_size=(1, 3), padding=(0, 1))
        self.branch3x3_2b = BasicConv2d(384, 384, kernel_size=(3, 1), padding=(1, 0))
        self.branch3x3dbl_1 = BasicConv2d(in_ch, 448, kernel_size=1)
        self.branch3x3dbl_2 = BasicConv2d(448, 384, kernel_size=3, padding=1)
        self.branch3x3dbl_3a = BasicConv2d(384, 384, kernel_size=(1, 3), padding=(0, 1))
        self.branch3x3dbl_3b = BasicConv2d(384, 384, kernel_size=(3, 1), padding=(1, 0))
        self.branch_pool = BasicConv2d(in_ch, 192, kernel_size=1)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        b1 = self.branch1x1(x)
        b3 = self.branch3x3_1(x)
        b3 = torch.cat([self.branch3x3_2a(b3), self.branch3x3_2b(b3)], 1)
        bd = self.branch3x3dbl_2(self.branch3x3dbl_1(x))
        bd = torch.cat([self.branch3x3dbl_3a(bd), self.branch3x3dbl_3b(bd)], 1)
        bp = self.branch_pool(F.avg_pool2d(x, kernel_size=3, stride=1, padding=1))
        return torch.cat([b1, b3, bd, bp], 1)


class InceptionAux(nn.Module):
    def __init__(self, in_ch: int, num_classes: int) -> None:
        super().__init__()
        self.conv0 = BasicConv2d(in_ch, 128, kernel_size=1)
        self.conv1 = BasicConv2d(128, 768, kernel_size=5)
        self.conv1.stddev = 0.01  # type: ignore[assignment]
        self.fc = nn.Linear(768, num_classes)
        self.fc.stddev = 0.001  # type: ignore[assignment]

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        x = F.avg_pool2d(x, kernel_size=5, stride=3)
        x = self.conv1(self.conv0(x))
        x = torch.flatten(F.adaptive_avg_pool2d(x, (1, 1)), 1)
        return self.fc(x)


class TactileInception(nn.Module):
    """Inception v3 (full or small) with MC-dropout placement and a prefix/suffix split.

    Parameters
    ----------
    num_classes: number of comparison platforms.
    small: stem + head only (``small_inception``).
    dropout: rate of the dropout before ``fc``.
    block_dropout: rate of dropout after the stem and after every Inception block (0 = none).
    aux_logits: build ``AuxLogits`` (full network only); its output is used only in training.
    transform_input: torchvision's input re-normalisation for ImageNet checkpoints.
    heads: K linear heads over the shared features (1 = the usual single classifier).
    """

    def __init__(self, num_classes: int, small: bool = False, dropout: float = 0.5,
                 block_dropout: float = 0.0, aux_logits: bool = False,
                 transform_input: bool = False, heads: int = 1) -> None:
        super().__init__()
        if num_classes < 2:
            raise InputError(f"num_classes must be >= 2, got {num_classes}")
        if heads < 1:
            raise InputError(f"heads must be >= 1, got {heads}")
        self.heads = int(heads)
        for name, rate in (("dropout", dropout), ("block_dropout", block_dropout)):
            if not 0.0 <= rate < 1.0:
                raise InputError(f"{name} must be in [0, 1), got {rate}")
        self.small = small
        self.transform_input = transform_input
        self.block_dropout = block_dropout
        self.Conv2d_1a_3x3 = BasicConv2d(3, 32, kernel_size=3, stride=2)
        self.Conv2d_2a_3x3 = BasicConv2d(32, 32, kernel_size=3)
        self.Conv2d_2b_3x3 = BasicConv2d(32, 64, kernel_size=3, padding=1)
        self.maxpool1 = nn.MaxPool2d(kernel_size=3, stride=2)
        self.Conv2d_3b_1x1 = BasicConv2d(64, 80, kernel_size=1)
        self.Conv2d_4a_3x3 = BasicConv2d(80, 192, kernel_size=3)
        self.maxpool2 = nn.MaxPool2d(kernel_size=3, stride=2)
        self.AuxLogits: nn.Module | None = None
        blocks: list[tuple[str, nn.Module]] = []
        if not small:
            blocks = [
                ("Mixed_5b", InceptionA(192, pool_features=32)),
                ("Mixed_5c", InceptionA(256, pool_features=64)),
                ("Mixed_5d", InceptionA(288, pool_features=64)),
                ("Mixed_6a", InceptionB(288)),
                ("Mixed_6b", InceptionC(768, channels_7x7=128)),
                ("Mixed_6c", InceptionC(768, channels_7x7=160)),
                ("Mixed_6d", InceptionC(768, channels_7x7=160)),
                ("Mixed_6e", InceptionC(768, channels_7x7=192)),
            ]
            for name, mod in blocks:
                setattr(self, name, mod)
            if aux_logits:
                self.AuxLogits = InceptionAux(768, num_classes)
            self.Mixed_7a = InceptionD(768)
            self.Mixed_7b = InceptionE(1280)
            self.Mixed_7c = InceptionE(2048)
            blocks += [("Mixed_7a", self.Mixed_7a), ("Mixed_7b", self.Mixed_7b),
                       ("Mixed_7c", self.Mixed_7c)]
        self._block_names = [n for n, _ in blocks]
        self.avgpool = nn.AdaptiveAvgPool2d((1, 1))
        self.dropout = nn.Dropout(p=dropout)
        self.block_drop = nn.Dropout(p=block_dropout)
        self.fc = nn.Linear(192 if small else 2048, num_classes * self.heads)
        self._init_weights()

    @property
    def num_classes(self) -> int:
        return self.fc.out_features // self.heads

    def _init_weights(self) -> None:
        # torchvision's scheme: truncated normal (std 0.1 or the module's stddev), BN = (1, 0).
        for m in self.modules():
            if isinstance(m, (nn.Conv2d, nn.Linear)):
                std = float(getattr(m, "stddev", 0.1))
                nn.init.trunc_normal_(m.weight, mean=0.0, std=std, a=-2, b=2)
                if isinstance(m, nn.Linear) and m.bias is not None:
                    nn.init.zeros_(m.bias)
            elif isinstance(m, nn.BatchNorm2d):
                nn.init.constant_(m.weight, 1)
                nn.init.constant_(m.bias, 0)

    def reset_classifier(self, num_classes: int) -> None:
        """Replace ``fc`` (and ``AuxLogits.fc``) for ``num_classes`` outputs (per head)."""
        self.fc = nn.Linear(self.fc.in_features, num_classes * self.heads)
        nn.init.trunc_normal_(self.fc.weight, std=0.1, a=-2, b=2)
        nn.init.zeros_(self.fc.bias)
        if self.AuxLogits is not None:
            aux = self.AuxLogits
            aux.fc = nn.Linear(768, num_classes)  # type: ignore[union-attr]
            nn.init.trunc_normal_(aux.fc.weight, std=0.001, a=-2, b=2)
            nn.init.zeros_(aux.fc.bias)

    def _transform(self, x: torch.Tensor) -> torch.Tensor:
        if not self.transform_input:
            return x
        x0 = x[:, 0:1] * (0.229 / 0.5) + (0.485 - 0.5) / 0.5
        x1 = x[:, 1:2] * (0.224 / 0.5) + (0.456 - 0.5) / 0.5
        x2 = x[:, 2:3] * (0.225 / 0.5) + (0.406 - 0.5) / 0.5
        return torch.cat([x0, x1, x2], 1)

    def stem(self, x: torch.Tensor) -> torch.Tensor:
        """(B, 3, H, W) -> (B, 192, h, w) stem features (deterministic)."""
        x = self._transform(x)
        x = self.maxpool1(self.Conv2d_2b_3x3(self.Conv2d_2a_3x3(self.Conv2d_1a_3x3(x))))
        return self.maxpool2(self.Conv2d_4a_3x3(self.Conv2d_3b_1x1(x)))

    def prefix(self, x: torch.Tensor) -> torch.Tensor:
        """Deterministic part: everything before the first dropout layer."""
        x = self.stem(x)
        if self.block_dropout > 0:
            return x
        for name in self._block_names:
            x = getattr(self, name)(x)
        return torch.flatten(self.avgpool(x), 1)

    def _pooled(self, h: torch.Tensor) -> torch.Tensor:
        """``prefix`` output -> (B, F) pooled features before the classifier's dropout."""
        if self.block_dropout > 0:
            h = self.block_drop(h)
            for name in self._block_names:
                h = self.block_drop(getattr(self, name)(h))
            h = torch.flatten(self.avgpool(h), 1)
        return h

    def _members(self, h: torch.Tensor) -> torch.Tensor:
        """(B, F) features -> (B, K, C) logits of the K heads, each behind its own dropout."""
        k, c = self.heads, self.num_classes
        hk = self.dropout(h.unsqueeze(1).expand(-1, k, -1))           # (B, K, F)
        w = self.fc.weight.view(k, c, -1)                              # (K, C, F)
        return torch.einsum("bkf,kcf->bkc", hk, w) + self.fc.bias.view(k, c)

    def _head(self, h: torch.Tensor) -> torch.Tensor:
        """(B, F) features -> (B, C) logits; ensemble: log of the members' mean softmax."""
        if self.heads == 1:
            return self.fc(self.dropout(h))
        logp = torch.log_softmax(self._members(h), dim=2)
        return torch.logsumexp(logp, dim=1) - math.log(self.heads)

    def suffix(self, h: torch.Tensor) -> torch.Tensor:
        """Stochastic part: from ``prefix`` output to logits (dropout active in train mode)."""
        return self._head(self._pooled(h))

    def features(self, x: torch.Tensor) -> torch.Tensor:
        """(B, 3, H, W) -> (B, F) inputs of the classifier ``fc`` (F = 192 small, 2048 full)."""
        return self._pooled(self.prefix(x))

    def member_logits(self, x: torch.Tensor) -> torch.Tensor:
        """(B, 3, H, W) -> (B, K, C) logits of the K heads (K = 1 for a single classifier)."""
        return self._members(self.features(x))

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        return self.suffix(self.prefix(x))

    def forward_train(self, x: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor | None]:
        """Logits ((B, C); with K > 1 heads the members' (B, K, C)) and, for the full network
        with aux logits, the auxiliary logits."""
        if self.AuxLogits is None:
            if self.heads > 1:
                return self.member_logits(x), None
            return self.forward(x), None
        x = self.stem(x)
        if self.block_dropout > 0:
            x = self.block_drop(x)
        aux = None
        for name in self._block_names:
            x = getattr(self, name)(x)
            if self.block_dropout > 0:
                x = self.block_drop(x)
            if name == "Mixed_6e":
                aux = self.AuxLogits(x)
        x = torch.flatten(self.avgpool(x), 1)
        return (self._members(x) if self.heads > 1 else self.fc(self.dropout(x))), aux


# --------------------------------------------------------------------------------------------
# Checkpoints


class LoadReport:
    """What a checkpoint did to a model, tensor by tensor."""

    def __init__(self) -> None:
        self.loaded: list[str] = []
        self.reset: list[str] = []          # present in the file, deliberately re-initialised
        self.missing: list[str] = []        # expected by the model, absent from the file
        self.mismatched: list[tuple[str, tuple, tuple]] = []  # (key, file shape, model shape)
        self.unexpected: list[str] = []     # in the file, unknown to the model

    @property
    def ok(self) -> bool:
        return not self.mismatched and not self.missing

    def to_dict(self) -> dict:
        return {
            "loaded": len(self.loaded), "reset": self.reset, "missing": self.missing,
            "mismatched": [{"key": k, "file": list(a), "model": list(b)}
                           for k, a, b in self.mismatched],
            "unexpected": self.unexpected,
        }

    def summary(self) -> str:
        lines = [f"matched and loaded: {len(self.loaded)} tensors"]
        lines += [f"reset (re-initialised for the platforms): {k}" for k in self.reset]
        lines += [f"missing from file: {k}" for k in self.missing]
        lines += [f"shape mismatch: {k}: file {list(a)} vs model {list(b)}"
                  for k, a, b in self.mismatched]
        if self.unexpected:
            lines.append(f"not used by this model: {len(self.unexpected)} tensors "
                         f"(e.g. {self.unexpected[0]})")
        return "\n".join(lines)


# Keys that are re-created for the platforms, never taken from an ImageNet file.
_HEAD_KEYS = ("fc.weight", "fc.bias", "AuxLogits.fc.weight", "AuxLogits.fc.bias")


def read_checkpoint(path: str | Path) -> OrderedDict[str, torch.Tensor]:
    """Read a state_dict from ``path`` safely (``weights_only=True``).

    Accepts a bare state_dict or a dict holding one under ``state_dict`` / ``model``; strips a
    ``module.`` prefix (DataParallel). Raises InputError naming the file on any problem.
    """
    p = Path(path)
    if not p.is_file():
        raise InputError(f"weights file not found: {p}")
    try:
        obj = torch.load(p, map_location="cpu", weights_only=True)
    except Exception as exc:  # noqa: BLE001 - any unpickling failure is a bad file
        raise InputError(f"weights file {p} is not a readable torch checkpoint: {exc}") from exc
    if isinstance(obj, dict) and not all(isinstance(v, torch.Tensor) for v in obj.values()):
        for key in ("state_dict", "model", "model_state_dict"):
            if isinstance(obj.get(key), dict):
                obj = obj[key]
                break
    if not isinstance(obj, dict) or not obj:
        raise InputError(f"weights file {p} holds no state_dict")
    out: OrderedDict[str, torch.Tensor] = OrderedDict()
    for k, v in obj.items():
        if not isinstance(v, torch.Tensor):
            raise InputError(f"weights file {p}: entry {k!r} is not a tensor")
        out[k[7:] if k.startswith("module.") else k] = v
    return out


def load_weights(model: TactileInception, state: dict[str, torch.Tensor],
                 keep_head: bool = False) -> LoadReport:
    """Copy matching tensors of ``state`` into ``model``; report every key.

    The classifier (``fc``, ``AuxLogits.fc``) is reset for the platforms unless ``keep_head`` and
    its shape matches. Tensors with wrong shapes are not loaded and are listed as mismatched.
    """
    report = LoadReport()
    own = model.state_dict()
    new_state = {}
    for key, target in own.items():
        if key not in state:
            report.missing.append(key)
            continue
        src = state[key]
        if key in _HEAD_KEYS and not (keep_head and tuple(src.shape) == tuple(target.shape)):
            report.reset.append(key)
            continue
        if tuple(src.shape) != tuple(target.shape):
            report.mismatched.append((key, tuple(src.shape), tuple(target.shape)))
            continue
        new_state[key] = src.to(target.dtype)
        report.loaded.append(key)
    # Head keys absent from an ImageNet-free file are "reset", not missing.
    report.missing = [k for k in report.missing if k not in _HEAD_KEYS]
    report.unexpected = [k for k in state if k not in own]
    model.load_state_dict(new_state, strict=False)
    return report


def build_model(name: str, num_classes: int, dropout: float = 0.5, block_dropout: float = 0.0,
                aux_logits: bool = False, weights: str | Path | None = None,
                strict_weights: bool = True,
                heads: int = 1) -> tuple[TactileInception, LoadReport | None]:
    """Build a model variant by name; optionally load a torchvision-format checkpoint.

    ``inception_v3`` with ``weights`` uses torchvision's ``transform_input`` convention.
    With ``strict_weights`` a checkpoint with missing or mismatched tensors raises InputError
    listing them.
    """
    if name not in MODEL_NAMES:
        raise InputError(f"unknown model {name!r}; choose one of {', '.join(MODEL_NAMES)}")
    if weights is not None and name == "inception_v3_random":
        raise InputError("model inception_v3_random takes no weights file; use inception_v3")
    model = TactileInception(num_classes, small=(name == "small_inception"), dropout=dropout,
                             block_dropout=block_dropout,
                             aux_logits=aux_logits and name != "small_inception",
                             transform_input=weights is not None, heads=heads)
    report = None
    if weights is not None:
        report = load_weights(model, read_checkpoint(weights))
        if strict_weights and not report.ok:
            raise InputError(f"weights file {weights} does not fit {name}:\n{report.summary()}")
    return model, report

