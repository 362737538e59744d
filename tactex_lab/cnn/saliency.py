"""Saliency maps of the tactile CNN with captum (thesis 2.4, 5.5): Input x Gradient and Grad-CAM.

- ``input_x_gradient``: captum ``InputXGradient`` of the target logit w.r.t. the input, summed
  over |channels| -> (N, S, S), per image scaled to [0, 1].
- ``grad_cam``: captum ``LayerGradCam`` on the last convolutional block (``Conv2d_4a_3x3`` for
  ``small_inception``, ``Mixed_7c`` for the full network): ReLU of the gradient-weighted
  activation map, upsampled to the input (bilinear, ``LayerAttribution.interpolate``),
  per image scaled to [0, 1].
- ``display_image``: what the model saw, as uint8 RGB: the ImageNet-normalised view undone, or
  for Fourier inputs the channel-mean standardised log spectrum as a grey image.

The model runs in eval mode (no dropout, batch norm on its running statistics), so the maps are
deterministic for given weights; the mode is restored afterwards.
"""

from __future__ import annotations

import numpy as np
import torch

from tactex_lab.cnn.models import TactileInception
from tactex_lab.cnn.preprocess import IMAGENET_MEAN, IMAGENET_STD


def _scale01(a: torch.Tensor) -> np.ndarray:
    a = a.detach().float()
    flat = a.reshape(a.shape[0], -1)
    lo = flat.min(dim=1).values.view(-1, *([1] * (a.dim() - 1)))
    hi = flat.max(dim=1).values.view(-1, *([1] * (a.dim() - 1)))
    return ((a - lo) / (hi - lo).clamp_min(1e-12)).cpu().numpy()


def target_layer(model: TactileInception) -> torch.nn.Module:
    """The last convolutional block: Grad-CAM's layer."""
    return model.Conv2d_4a_3x3 if model.small else model.Mixed_7c


class _Eval:
    def __init__(self, model: torch.nn.Module) -> None:
        self.model, self.was = model, model.training

    def __enter__(self):
        self.model.eval()
        return self.model

    def __exit__(self, *exc):
        self.model.train(self.was)


def _plain(x: torch.Tensor) -> torch.Tensor:
    # captum needs gradients w.r.t. a leaf in the default memory format
    return x.detach().contiguous().clone().requires_grad_(True)


def input_x_gradient(model: TactileInception, x: torch.Tensor,
                     target: int | list[int] | torch.Tensor) -> np.ndarray:
    """(N, 3, S, S) -> (N, S, S) in [0, 1]: |input x d logit_target / d input| over channels."""
    from captum.attr import InputXGradient
    with _Eval(model):
        attr = InputXGradient(model).attribute(_plain(x), target=_targets(target, len(x)))
    return _scale01(attr.abs().sum(dim=1))


def grad_cam(model: TactileInception, x: torch.Tensor,
             target: int | list[int] | torch.Tensor) -> np.ndarray:
    """(N, 3, S, S) -> (N, S, S) in [0, 1]: Grad-CAM on ``target_layer``, upsampled."""
    from captum.attr import LayerAttribution, LayerGradCam
    with _Eval(model):
        cam = LayerGradCam(model, target_layer(model)).attribute(
            _plain(x), target=_targets(target, len(x)), relu_attributions=True)
        up = LayerAttribution.interpolate(cam, tuple(x.shape[-2:]), interpolate_mode="bilinear")
    return _scale01(up[:, 0])


def _targets(target, n: int):
    if isinstance(target, int):
        return target
    return torch.as_tensor(list(target) if not torch.is_tensor(target) else target,
                           dtype=torch.long).view(n)


def display_image(x: torch.Tensor, fourier: bool = False) -> np.ndarray:
    """(N, 3, S, S) model input -> (N, S, S, 3) uint8 for display."""
    a = x.detach().float().contiguous().cpu().numpy().transpose(0, 2, 3, 1)
    if fourier:
        g = a.mean(axis=3)
        g = (g - g.min(axis=(1, 2), keepdims=True)) / (np.ptp(g, axis=(1, 2), keepdims=True)
                                                        + 1e-12)
        return np.repeat((g[..., None] * 255).astype(np.uint8), 3, axis=3)
    rgb = a * IMAGENET_STD + IMAGENET_MEAN
    return (np.clip(rgb, 0, 1) * 255).astype(np.uint8)
