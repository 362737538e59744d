"""Perturbations of a touch (``sources/perturb.py``): exact values on constructed frames."""

import numpy as np
import pytest

from tactex_ros.core.errors import InputError
from tactex_ros.core.touch import Touch
from tactex_ros.sources import perturb as P


def _touch(contact: float = 20.0, channel: int = 0, extra: bool = True) -> Touch:
    """No-contact frame 100 everywhere; the contact frames +``contact`` in ``channel`` on the
    square rows 70..169, columns 100..199 (10 000 px)."""
    nc = np.full((240, 320, 3), 100, np.uint8)
    f = nc.copy()
    f[70:170, 100:200, channel] = 100 + contact
    return Touch(frame=f, no_contact=nc, extra=np.stack([f, f]) if extra else None)


def test_drift_gain_and_offset_by_hand():
    t = _touch()
    w = np.array([1.0, 0.5, -1.0])
    # touch 2 at 4 % per touch: gain 1 + 2 * 0.04 * w = (1.08, 1.04, 0.92), offset 2 * 4 * w / 4
    out = P.lighting_drift(t, 2, 4.0, w)
    assert out.no_contact[0, 0].tolist() == [110, 105, 90]          # 108 + 2, 104 + 1, 92 - 2
    assert out.frame[100, 150].tolist() == [int(np.rint(120 * 1.08 + 2)), 105, 90]  # 132
    assert out.extra.shape == (2, 240, 320, 3) and np.array_equal(out.extra[1], out.frame)
    assert P.lighting_drift(t, 0, 4.0, w) is t and P.lighting_drift(t, 3, 0.0, w) is t
    # saturates instead of wrapping
    assert P.lighting_drift(t, 50, 10.0, np.ones(3)).frame.max() == 255


def test_noise_is_gaussian_seeded_and_independent_per_frame():
    t = _touch()
    a = P.sensor_noise(t, 5.0, np.random.default_rng(3))
    b = P.sensor_noise(t, 5.0, np.random.default_rng(3))
    assert np.array_equal(a.frame, b.frame) and np.array_equal(a.no_contact, b.no_contact)
    d = a.no_contact.astype(float) - 100
    assert d.std() == pytest.approx(5.0, abs=0.05) and abs(d.mean()) < 0.05
    assert not np.array_equal(a.extra[0], a.extra[1])      # separate captures
    assert P.sensor_noise(t, 0.0, np.random.default_rng(3)) is t


def test_partial_contact_masks_the_share_beyond_the_line():
    t = _touch()
    # angle 0: the line is vertical; the half of the contact square with x >= 149.5 is lost
    out = P.partial_contact(t, 0.5, 0.0)
    for f in (out.frame, out.extra[0], out.extra[1]):
        assert np.all(f[70:170, 100:150, 0] == 120) and np.all(f[70:170, 150:200, 0] == 100)
    assert np.array_equal(out.no_contact, t.no_contact)
    # angle pi / 2: the lower half of the rows is lost
    low = P.partial_contact(t, 0.5, np.pi / 2)
    assert np.all(low.frame[70:120, 100:200, 0] == 120) and np.all(low.frame[120:170, :, 0] == 100)
    assert np.array_equal(P.partial_contact(t, 1.0, 0.3).frame, t.no_contact)
    assert P.partial_contact(Touch(frame=t.frame), 0.5, 0.0).no_contact is None   # no reference


def test_contact_mask_counts_the_square():
    m = P.contact_mask(_touch().frame, _touch().no_contact)
    assert m[70:170, 100:200].all() and m.sum() >= 10000 and not m[:60].any()


def test_low_force_scales_the_contact_difference():
    out = P.low_force(_touch(contact=40.0), 0.75)
    assert out.frame[100, 150, 0] == 110 and out.frame[0, 0, 0] == 100      # 100 + 0.25 * 40
    assert np.all(out.extra[:, 100, 150, 0] == 110)
    assert np.array_equal(P.low_force(_touch(), 1.0).frame, _touch().no_contact)


def test_worn_gel_blurs_and_weakens_the_difference():
    nc = np.full((240, 320, 3), 100, np.uint8)
    f = np.full((240, 320, 3), 116, np.uint8)        # a uniform difference of 16 stays uniform
    out = P.worn_gel(Touch(frame=f, no_contact=nc), 8.0)
    assert np.all(out.frame == 108)                   # 100 + 16 / (1 + 8 / 8)
    edge = P.worn_gel(_touch(contact=40.0, extra=False), 4.0).frame[120, :, 0].astype(float)
    assert edge[150] < 100 + 40 / 1.5 + 0.5 and edge[98] > 100     # weaker, and spread out
    assert edge[150] == pytest.approx(100 + 40 / 1.5, abs=1.0)


def test_perturbation_counts_touches_and_seeds_each():
    t = _touch()
    a, b = P.Perturbation("drift", 2.0, 7), P.Perturbation("drift", 2.0, 7)
    assert a(t) is t                                  # touch 0: no drift yet
    one = a(t)
    assert np.array_equal(one.frame, b(b(t)).frame) and a.k == 2
    g = 1 + 0.02 * a.weights
    assert one.no_contact[0, 0].tolist() == np.rint(100 * g + 2 * a.weights / 4).tolist()
    n1, n2 = P.Perturbation("noise", 5.0, 1), P.Perturbation("noise", 10.0, 1)
    # the same draw at every severity: noise at 10 is twice the noise at 5 (before rounding)
    d1 = n1(t).no_contact.astype(float) - 100
    d2 = n2(t).no_contact.astype(float) - 100
    assert np.abs(d2 - 2 * d1).max() <= 1.5
    with pytest.raises(InputError, match="perturbation 'x'"):
        P.Perturbation("x", 1.0, 0)
    with pytest.raises(InputError, match="low force"):
        P.Perturbation("low_force", 1.5, 0)(t)
