"""Issue 33's candidate press features (``analysis/press_features.py``): the height map is
recovered from a colour image rendered with a linear colour response, the filter bank is
invariant to rotating the texture and sees its scale and orientation."""

import numpy as np

from tactex_lab.analysis import press_features as pf


def _surface(h=208, w=288, seed=0):
    rng = np.random.default_rng(seed)
    f = np.fft.fft2(rng.normal(size=(h, w)))
    fy, fx = np.fft.fftfreq(h)[:, None], np.fft.fftfreq(w)[None, :]
    r = np.sqrt(fx ** 2 + fy ** 2)
    return np.real(np.fft.ifft2(f * np.exp(-(r / 0.06) ** 2)))       # smooth random relief


def test_integrate_recovers_a_height_from_its_gradient():
    hgt = _surface()
    gy, gx = np.gradient(hgt)
    got = pf.integrate(gx, gy)
    assert np.corrcoef(got.ravel(), hgt.ravel())[0, 1] > 0.98


def test_gradient_map_finds_the_colour_response_without_calibration():
    hgt = _surface(seed=1)
    gy, gx = np.gradient(hgt)
    response = np.array([[1.0, 0.2], [-0.5, 0.9], [-0.4, -1.1]])    # (RGB, (gx, gy))
    d = (np.stack([gx, gy], -1) @ response.T).astype(np.float32)
    ex, ey, m = pf.gradient_map(d)
    # up to one scale and sign: M @ response is a multiple of the identity
    b = m @ response
    assert abs(b[0, 1]) < 0.05 * abs(b[0, 0]) and abs(b[1, 0]) < 0.05 * abs(b[0, 0])
    assert abs(b[1, 1] / b[0, 0] - 1.0) < 0.05
    assert abs(np.corrcoef(ex.ravel(), gx.ravel())[0, 1]) > 0.99


def test_filter_bank_is_rotation_invariant_and_sees_scale_and_direction():
    y, x = np.mgrid[:208, :208].astype(np.float32)
    lines = np.sin(2 * np.pi * 0.14 * (x * np.cos(0.3) + y * np.sin(0.3)))
    d = np.repeat(lines[..., None], 3, -1)
    a = pf.filter_bank(d)
    b = pf.filter_bank(np.ascontiguousarray(np.rot90(d)))
    np.testing.assert_allclose(a, b, atol=0.05)
    first = a[:len(pf.FB_FREQS)]
    assert int(np.argmax(first)) == pf.FB_FREQS.index(0.14)
    noise = np.random.default_rng(0).normal(size=(208, 208, 1)).repeat(3, -1)
    j = pf.FB_FREQS.index(0.14)
    aniso = a[len(pf.FB_FREQS) + j]                 # 2nd harmonic over orientations
    assert aniso > 0.5 > pf.filter_bank(noise)[len(pf.FB_FREQS) + j]
