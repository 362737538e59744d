"""Saliency maps (captum Input x Gradient, Grad-CAM) and the saliency experiment."""

import json

import numpy as np
import torch

from tactex_ros.cli.main import main
from tactex_lab.cnn.models import build_model
from tactex_lab.cnn.preprocess import to_tensor, view
from tactex_lab.cnn.saliency import (display_image, grad_cam, input_x_gradient,
                                      target_layer)


def _model(name="small_inception", seed=0):
    torch.manual_seed(seed)
    return build_model(name, 3)[0]


def test_maps_shape_range_and_determinism():
    m = _model()
    x = torch.randn(2, 3, 48, 48)
    a = input_x_gradient(m, x, [0, 2])
    b = grad_cam(m, x, 1)
    assert a.shape == (2, 48, 48) and b.shape == (2, 48, 48)
    assert a.min() >= 0 and np.isclose(a.max(), 1.0) and b.min() >= 0 and b.max() <= 1
    np.testing.assert_array_equal(a, input_x_gradient(m, x, [0, 2]))
    assert m.training  # mode restored


def test_input_x_gradient_is_zero_where_the_input_is_zero():
    m = _model()
    x = torch.randn(1, 3, 48, 48)
    x[..., :, :16] = 0.0
    a = input_x_gradient(m, x, 0)
    assert np.all(a[0, :, :16] == 0) and a[0, :, 16:].max() > 0


def test_grad_cam_layer_is_the_last_conv_block():
    small = _model()
    assert target_layer(small) is small.Conv2d_4a_3x3
    full = build_model("inception_v3_random", 3)[0]
    assert target_layer(full) is full.Mixed_7c


def test_display_image_undoes_normalisation():
    img = np.random.default_rng(0).integers(0, 255, (240, 320, 3), dtype=np.uint8)
    v = view(img, 0.0, 48)
    back = display_image(to_tensor(v[None]))[0]
    assert np.abs(back.astype(int) - v.astype(int)).max() <= 1
    f = display_image(to_tensor(v[None], fourier=True), fourier=True)
    assert f.shape == (1, 48, 48, 3) and f.dtype == np.uint8


def test_saliency_command_tiny(tmp_path):
    out = tmp_path / "sal"
    rc = main(["experiment", "saliency", "--source", "sim", "--classes", "4", "--per-class", "2",
               "--folds", "1", "--rounds", "1", "--explore-rounds", "1", "--input-size", "32",
               "--fourier", "both", "--quiet", "--out", str(out)])
    assert rc == 0
    s = json.loads((out / "summary.json").read_text())
    assert set(s["classify"]) == {"spatial", "fourier"}
    assert len(s["explore"]["spatial"]["rounds"]) == 2     # round 1 and the final decision
    for f in ("classify_spatial.png", "classify_fourier.png", "explore_spatial_rounds.png",
              "explore_fourier_round1.png"):
        assert (out / f).stat().st_size > 0
