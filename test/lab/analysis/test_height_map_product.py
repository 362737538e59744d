"""The shipped descriptor with the height map (``core/texture.py``) is the feature the issue 33
trials ran (``experiments/press_cache.py``'s ``frame_hm``: the strongest frame's descriptor, then
``press_features.height_map`` of its contact difference), on real presses. The lab's height map
is the product's (one implementation); before the move the two agreed to 1e-9 on these presses
(this test's first version, commit "test: the product's height map equals the lab's")."""

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
    assert pf.height_map is texture.height_map and lab.shape == (pf.HM_DIM,)
    assert np.all(np.isfinite(lab)) and np.ptp(lab) > 0
    # the shipped descriptor: the trials' frame_hm (strongest frame's descriptor, then hm)
    x = texture.describe_touch(Touch(frame, nc), 1, with_height_map=True)
    np.testing.assert_allclose(x, np.concatenate([texture.describe(frame, nc), lab]),
                               rtol=0, atol=1e-9)
    assert x.shape == (texture.descriptor_dim(True),) == (texture.DIM + texture.HM_DIM,)
