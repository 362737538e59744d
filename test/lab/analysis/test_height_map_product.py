"""The product's height map (``core/texture.py``) is the computation the issue 33 trials ran
(``tactex_lab/analysis/press_features.py`` via ``experiments/press_cache.py``'s ``frame_hm``),
on real presses."""

import numpy as np
import pytest

from tactex_ros.core import texture
from tactex_ros.core.contact import strongest_contact
from tactex_ros.core.touch import Touch
from tactex_lab.analysis import press_features as pf


@pytest.mark.parametrize("material", ["basket", "aluminium_foil"])
def test_product_height_map_matches_the_trials(octopi_press, material):
    frames = octopi_press(material)
    idx, _ = strongest_contact(frames)
    frame, nc = frames[idx], frames[0]
    d = texture.contact_difference(frame, nc)
    lab = pf.height_map(d)
    got = texture.height_map(d)
    assert got.shape == (texture.HM_DIM,) == lab.shape
    np.testing.assert_allclose(got, lab, rtol=0, atol=1e-9)
    # the shipped descriptor: the trials' frame_hm (strongest frame's descriptor, then hm)
    x = texture.describe_touch(Touch(frame, nc), 1, with_height_map=True)
    np.testing.assert_allclose(x, np.concatenate([texture.describe(frame, nc), lab]),
                               rtol=0, atol=1e-9)
    assert x.shape == (texture.descriptor_dim(True),) == (texture.DIM + texture.HM_DIM,)
