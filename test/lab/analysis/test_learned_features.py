"""Issue 33's learned candidates (``analysis/learned_features.py``): the scattering is rotation
invariant and tells textures apart, the small CNN learns classes it is trained on, the screen
pairs its scenes, and a library sees its own network's embeddings (``library_view``)."""

import numpy as np
from tactex_lab.analysis import learned_features as lf
from tactex_lab.analysis.learned_features import library_view
from tactex_lab.analysis import metric_screen
from tactex_lab.experiments.press_cache import FEATURES


def _stripes(freq: float, angle: float, size: int, rng: np.random.Generator) -> np.ndarray:
    y, x = np.mgrid[:size, :size].astype(np.float32)
    u = x * np.cos(angle) + y * np.sin(angle)
    return (np.sin(2 * np.pi * freq * u + rng.uniform(0, 6.3))
            + 0.3 * rng.normal(size=(size, size))).astype(np.float32)


def test_scattering_is_rotation_invariant_and_tells_scales_apart():
    rng = np.random.default_rng(0)
    op = lf.Scattering((64, 64), j=3)
    assert op.dim == 3 * 3 + 3 * 5 == 24
    fine = _stripes(0.25, 0.3, 64, rng)
    a, b = op(fine), op(np.rot90(fine).copy())
    assert a.shape == (24,) and np.all(np.isfinite(a))
    coarse = op(_stripes(0.06, 0.3, 64, rng))
    # a quarter turn moves the energy by L/2 orientations: the features barely change, far
    # less than between two scales of stripes
    assert np.abs(a - b).max() < 0.1 * np.abs(a - coarse).max()


def test_the_cnn_learns_the_classes_it_is_trained_on():
    rng = np.random.default_rng(1)
    freqs = (0.06, 0.14, 0.3)
    def press(c: int) -> np.ndarray:
        return np.stack([np.repeat(_stripes(freqs[c], rng.uniform(0, 3.1), 72, rng)[None], 3, 0)
                         for _ in range(4)]).astype(np.float16)
    cls = np.array([str(c) for c in range(3) for _ in range(6)])
    half = np.stack([press(int(c)) for c in cls])
    body, log = lf.train_cnn(half, cls, steps=60, batch=16, seed=0)
    assert log["steps"] == 60 and np.isfinite(log["loss"])
    test_cls = np.array([c for c in range(3) for _ in range(4)])
    one, four, ms = lf.embed(body, np.stack([press(c) for c in test_cls]), log["scale"])
    assert one.shape == four.shape == (12, lf.EMBED) and ms > 0
    means = np.stack([four[test_cls == c].mean(0) for c in range(3)])
    nearest = np.argmin(((four[:, None] - means[None]) ** 2).sum(-1), 1)
    assert (nearest == test_cls).mean() >= 0.75


def test_the_screen_tests_each_feature_against_todays_and_the_best_prepared():
    rng = np.random.default_rng(2)
    def cache(n_cls: int) -> dict:
        cls = np.repeat(np.arange(n_cls).astype(str), 4)
        centres = rng.normal(size=(n_cls, 8))
        return {"cls": cls, "noise": rng.normal(size=(4 * n_cls, 8)),
                "good": centres[cls.astype(int)] + 0.2 * rng.normal(size=(4 * n_cls, 8))}
    noise = lambda c: c["noise"]                                   # noqa: E731
    feats = {"frame": noise, "frame_hm": noise, "frames4_hm": noise,
             "good": lambda c: c["good"]}
    rows = metric_screen.feature_screen(cache(12), cache(10), feats, scenes=200)
    by = {(r["direction"], r["feature"], r["metric"]): r for r in rows}
    assert len(rows) == 2 * 4 * 2
    for d in ("a_with_b", "b_with_a"):
        good, today = by[d, "good", "none"], by[d, "frame_hm", "none"]
        assert good["acc_1"] > 0.9 and today["acc_1"] < 0.5
        assert set(good["vs"]) == {"frame_hm/none", "frames4_hm/whiten"}
        assert good["vs"]["frame_hm/none"]["1"]["p"] < 1e-6
        assert today["vs"]["frame_hm/none"]["1"]["p"] == 1.0
        assert by[d, "frame", "none"]["vs"] == {}


def test_a_library_sees_its_own_networks_embeddings():
    c = {"f0": np.zeros((2, 3)), "hm": np.ones((2, 1)), "extra": np.zeros((2, 3, 3)),
         "cnn": np.full((2, 2), 5.0), "cnn_lib": np.full((2, 2), 7.0),
         "cnn4": np.full((2, 2), 6.0), "cnn4_lib": np.full((2, 2), 8.0)}
    lib = library_view(c)
    assert FEATURES["frame_hm_cnn"](c)[0].tolist() == [0, 0, 0, 1, 5, 5]
    assert FEATURES["frame_hm_cnn"](lib)[0].tolist() == [0, 0, 0, 1, 7, 7]
    assert FEATURES["frames4_hm_cnn4"](lib)[0].tolist() == [0, 0, 0, 1, 8, 8]
    assert FEATURES["frame_hm_cnn4"](c)[0].tolist() == [0, 0, 0, 1, 6, 6]
    plain = {"f0": np.zeros((2, 3))}
    assert library_view(plain) is not plain and library_view(plain).keys() == plain.keys()


def test_the_numpy_forward_pass_equals_the_trained_network():
    """The product's numpy embedding (``core/embedding.py``, batch normalisation folded in)
    gives the lab's torch network's numbers, after a save and a load."""
    import torch
    from tactex_ros.core import embedding
    rng = np.random.default_rng(3)
    half = rng.normal(size=(6, 1, 3, 72, 72)).astype(np.float16)
    cls = np.array(["a", "b", "c"] * 2)
    for norm in ("global", "image"):
        body, log = lf.train_cnn(half, cls, steps=5, batch=4, seed=0, norm=norm)
        emb = lf.to_embedding(body, log, {"test": True})
        d = rng.normal(size=(2, 144, 144, 3)).astype(np.float32) * 4
        x = emb.prepare(d)
        assert x.shape == (2, 72, 72, 3)
        with torch.no_grad():
            ref = body(torch.from_numpy(x.transpose(0, 3, 1, 2).copy())).numpy()
        assert np.abs(emb.forward(x) - ref).max() < 1e-4 * max(1.0, np.abs(ref).max())
        one, _, _ = lf.embed(body, x.transpose(0, 3, 1, 2)[:, None] * (
            log["scale"] if norm == "global" else 1.0), log["scale"], norm)
        if norm == "global":       # the lab's embed divides by the same scale
            assert np.allclose(one, ref, atol=1e-4)
    import tempfile
    from pathlib import Path
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "net.npz"
        emb.save(path)
        back = embedding.load(path)
        assert back.norm == "image" and back.trained_on == {"test": True} and back.dim == lf.EMBED
        assert np.array_equal(back(d), emb(d))


def test_the_photometric_augmentation_varies_the_look_not_the_layout():
    import pytest
    import torch
    from tactex_ros.core.errors import InputError
    rng = np.random.default_rng(0)
    xb = torch.from_numpy(np.stack([np.repeat(_stripes(0.14, 0.3, 32, rng)[None], 3, 0)
                                    for _ in range(64)]))
    out = lf._photometric(xb, np.random.default_rng(1))
    assert out.shape == xb.shape and out.dtype == torch.float32
    ratio = (out.std(dim=(1, 2, 3)) / xb.std(dim=(1, 2, 3))).numpy()
    # contrast x 0.5-2 with a channel jitter, some crops blurred (less contrast), noise added
    assert ratio.min() > 0.3 and ratio.max() < 3.0 and ratio.max() / ratio.min() > 2.0
    # the texture stays where it was: each crop still correlates with its source
    corr = [np.corrcoef(a.ravel(), b.ravel())[0, 1] for a, b in zip(xb.numpy(), out.numpy(), strict=True)]
    assert min(corr) > 0.5
    assert torch.equal(out, lf._photometric(xb, np.random.default_rng(1)))   # seeded
    with pytest.raises(InputError, match="geometric, photometric"):
        lf.train_cnn(xb[:4, None].numpy().astype(np.float16), np.array(list("abab")), steps=1,
                     aug="colour")
