"""Crops at sensor resolution (``CnnSettings.sensor_crops``): exact pixels, positions, limits."""

import numpy as np
import pytest

from tactex_ros.core.config import preset
from tactex_ros.core.errors import InputError
from tactex_lab.cnn.learner import OnlineLearner
from tactex_lab.cnn.preprocess import augment, view


def _gradient() -> np.ndarray:
    yy, xx = np.mgrid[0:240, 0:320]
    img = np.stack([xx * 0.6, yy * 0.9, (xx + yy) * 0.4], axis=2)
    return np.clip(img, 0, 255).astype(np.uint8)


def test_native_view_is_the_frame_pixels():
    img = _gradient()
    a = view(img, 0.0, 96, native=True)
    np.testing.assert_array_equal(a, img[72:168, 112:208])        # centred, no resize
    b = view(img, 0.0, 64, native=True, centre=(39.5, 49.5))
    np.testing.assert_array_equal(b, img[18:82, 8:72])             # centre (x, y) = (39.5, 49.5)
    r = view(img, 90.0, 96, native=True).astype(int)
    np.testing.assert_allclose(np.rot90(r, k=-1), a.astype(int), atol=1)
    with pytest.raises(InputError, match="170 px crop"):
        view(img, 0.0, 170, native=True)


def test_native_augment_positions_and_identity():
    img = _gradient()
    v = augment(img, 12, 96, np.random.default_rng(0), include_identity=True, native=True)
    assert v.shape == (12, 96, 96, 3)
    np.testing.assert_array_equal(v[0], img[72:168, 112:208])
    # different positions: the mean red level (0.6 x column) of the views differs
    reds = v[1:, :, :, 0].mean(axis=(1, 2))
    assert reds.std() > 3.0


def test_learner_with_sensor_crops():
    lr = OnlineLearner(2, preset("cnn", input_size=96, sensor_crops=True, augment=3), seed=0)
    x = lr.add_touch(_gradient(), 0)
    assert tuple(x.shape) == (3, 3, 96, 96)
    with pytest.raises(InputError, match="sensor_crops"):
        OnlineLearner(2, preset("cnn", input_size=200, sensor_crops=True), seed=0)
