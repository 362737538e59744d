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
from tactex_lab.experiments.press_cache import FEATURES


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


def test_the_four_frame_descriptor_is_the_trials_frames4_hm(octopi_press):
    """``descriptor_frames=4`` with the height map: the descriptor averaged over the strongest
    and 3 more frames, then the strongest frame's height map (``press_cache``'s ``frames4_hm``),
    not the mean of 4 height maps."""
    frames = octopi_press("basket")
    idx, _ = strongest_contact(frames)
    frame, nc = frames[idx], frames[0]
    extra = [frames[max(idx - k, 1)] for k in (1, 2, 3)]
    touch = Touch(frame, nc, np.stack(extra))
    x = texture.describe_touch(touch, 4, with_height_map=True)
    means = np.mean([texture.describe(f, nc) for f in [frame] + extra], axis=0)
    hm = pf.height_map(texture.contact_difference(frame, nc))
    np.testing.assert_allclose(x, np.concatenate([means, hm]), rtol=0, atol=1e-9)
    cache = {"f0": texture.describe(frame, nc)[None],
             "extra": np.stack([texture.describe(f, nc) for f in extra])[None], "hm": hm[None]}
    np.testing.assert_allclose(FEATURES["frames4_hm"](cache)[0], x, rtol=0, atol=1e-9)
    # 2 frames: the strongest and the first extra
    two = texture.describe_touch(touch, 2, with_height_map=False)
    np.testing.assert_allclose(two, np.mean([texture.describe(f, nc) for f in (frame, extra[0])],
                                            axis=0), rtol=0, atol=1e-9)
