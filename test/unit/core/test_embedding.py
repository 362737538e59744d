"""The learned embedding in numpy (``core/embedding.py``): the convolution's numbers by hand,
the shipped network's file, the learner's descriptor with it, and the files it refuses."""

import numpy as np
import pytest

from tactex_ros.core import embedding, representation
from tactex_ros.core.config import preset
from tactex_ros.core.descriptor import DescriptorLearner, descriptor_size, raw_descriptor
from tactex_ros.core.errors import InputError
from tactex_ros.core.texture import DIM_HEIGHT_MAP, contact_difference
from tactex_ros.core.touch import Touch


def _one_layer(stride: int) -> embedding.Embedding:
    w = np.zeros((2, 3, 3, 3), np.float32)
    w[0, 0, 1, 1] = 1.0          # output 0: the red channel itself
    w[1, 1, :, :] = 1.0          # output 1: the 3 x 3 sum of the green channel
    return embedding.Embedding([embedding.Layer(w, np.array([0.0, -1.0], np.float32), stride)],
                               scale=2.0)


def test_a_convolution_by_hand():
    x = np.zeros((1, 3, 3, 3), np.float32)
    x[0, :, :, 0] = [[1, -2, 3], [4, 5, -6], [7, 8, 9]]
    x[0, 1, 1, 1] = 2.0                          # one green pixel in the middle
    y = embedding._conv_relu(x, _one_layer(1).layers[0])
    assert y.shape == (1, 3, 3, 2)
    assert y[0, :, :, 0].tolist() == [[1, 0, 3], [4, 5, 0], [7, 8, 9]]   # ReLU of red
    # every 3 x 3 window (zero padded) holds the green pixel: 2 - 1 = 1
    assert y[0, :, :, 1].tolist() == [[1] * 3] * 3
    y2 = embedding._conv_relu(x, _one_layer(2).layers[0])
    assert y2.shape == (1, 2, 2, 2) and y2[0, :, :, 0].tolist() == [[1, 3], [7, 9]]
    # the whole pass: the mean over the image of the last layer
    assert np.allclose(_one_layer(1).forward(x)[0], [37 / 9, 1.0])


def test_input_is_the_half_resolution_difference_scaled():
    emb = _one_layer(1)
    d = np.ones((2, 8, 10, 3), np.float32) * 4.0
    x = emb.prepare(d)
    assert x.shape == (2, 4, 5, 3) and np.allclose(x, 2.0)       # / scale
    emb.norm = "image"
    d[1] *= np.arange(10, dtype=np.float32)[None, :, None]
    x = emb.prepare(d)
    assert np.allclose(x[1].std(), 1.0, atol=1e-4)
    with pytest.raises(InputError, match="frames, H, W, 3"):
        emb.prepare(np.ones((8, 10, 3)))


def test_the_shipped_network_was_trained_on_the_simulator_alone():
    emb = embedding.load(embedding.resolve("sim"))
    assert embedding.resolve("sim") == embedding.SHIPPED and emb.dim == embedding.EMBED == 128
    assert emb.trained_on["source"].startswith("sim") and emb.trained_on["recorded_presses"] == 0
    assert [lay.stride for lay in emb.layers] == [2, 2, 2, 1] and len(emb.identity) == 16
    assert embedding.load(embedding.SHIPPED) is emb                 # once per process


def _touch(seed: int, extra: bool = False) -> Touch:
    rng = np.random.default_rng(seed)
    nc = rng.integers(80, 120, (240, 320, 3)).astype(np.uint8)
    frames = [np.clip(nc.astype(int) + rng.integers(-30, 30, nc.shape), 0, 255).astype(np.uint8)
              for _ in range(4)]
    return Touch(frames[0], nc, frames[1:] if extra else None)


def test_the_learner_appends_the_mean_embedding_of_its_frames():
    cfg = preset("default", descriptor_embedding="sim")
    assert descriptor_size(cfg) == DIM_HEIGHT_MAP + 128
    t = _touch(0, extra=True)
    x = raw_descriptor(t, cfg)
    plain = raw_descriptor(t, preset("descriptor"))
    assert x.shape == (DIM_HEIGHT_MAP + 128,) and np.array_equal(x[:DIM_HEIGHT_MAP], plain)
    emb = embedding.load(embedding.SHIPPED)
    diffs = np.stack([contact_difference(f, t.no_contact)
                      for f in [t.frame, *t.extra]])
    # the default: the descriptor of the strongest frame, the embedding's mean over 4 frames
    assert cfg.descriptor_frames == 1 and cfg.descriptor_embedding_frames == 4
    assert np.allclose(x[DIM_HEIGHT_MAP:], emb(diffs).mean(0), atol=1e-6)
    one = raw_descriptor(t, preset("default", descriptor_embedding_frames=1))
    assert np.allclose(one[DIM_HEIGHT_MAP:], emb(diffs[:1])[0], atol=1e-6)   # the strongest
    assert np.array_equal(one[:DIM_HEIGHT_MAP], plain)
    two = raw_descriptor(t, preset("default", descriptor_embedding_frames=2))
    assert np.allclose(two[DIM_HEIGHT_MAP:], emb(diffs[:2]).mean(0), atol=1e-6)
    # descriptor_frames averages the descriptor, not the embedding
    four = raw_descriptor(t, preset("default", descriptor_frames=4,
                                    descriptor_embedding_frames=1))
    assert np.allclose(four[DIM_HEIGHT_MAP:], one[DIM_HEIGHT_MAP:], atol=1e-12)
    assert not np.allclose(four[:DIM_HEIGHT_MAP], plain)
    # a touch without its burst: the strongest frame alone
    alone = raw_descriptor(_touch(0, extra=False), cfg)
    assert np.allclose(alone[DIM_HEIGHT_MAP:], emb(diffs[:1])[0], atol=1e-6)


def test_a_representation_of_another_embedding_is_refused(tmp_path):
    rng = np.random.default_rng(1)
    lib = {str(c): rng.normal(size=(5, DIM_HEIGHT_MAP)) + c for c in range(4)}
    path = representation.save(representation.fit(lib), tmp_path / "plain.npz")
    cfg = preset("default", descriptor_embedding="sim", representation=str(path))
    with pytest.raises(InputError, match="descriptor_embedding"):
        DescriptorLearner(4, cfg)
    lib = {k: np.hstack([v, rng.normal(size=(5, 128))]) for k, v in lib.items()}
    rep = representation.fit(lib)
    rep.embedding = embedding.load(embedding.SHIPPED).identity
    path = representation.save(rep, tmp_path / "emb.npz")
    back = representation.load(path)
    assert back.embedding == rep.embedding and back.descriptor_dim == DIM_HEIGHT_MAP + 128
    DescriptorLearner(4, preset("default", descriptor_embedding="sim",
                                representation=str(path)))        # accepted
    with pytest.raises(InputError, match="descriptor_embedding"):
        DescriptorLearner(4, preset("descriptor", representation=str(path)))


def test_a_representation_of_other_embedding_frames_is_refused(tmp_path):
    rng = np.random.default_rng(2)
    lib = {str(c): rng.normal(size=(5, DIM_HEIGHT_MAP + 128)) + c for c in range(4)}
    rep = representation.fit(lib)
    rep.embedding, rep.frames = embedding.load(embedding.SHIPPED).identity, 1
    rep.embedding_frames = 1
    path = representation.save(rep, tmp_path / "e1.npz")
    assert representation.load(path).embedding_frames == 1
    with pytest.raises(InputError, match="learner.descriptor_embedding_frames=1"):
        DescriptorLearner(4, preset("default", representation=str(path)))     # 4 frames
    DescriptorLearner(4, preset("default", representation=str(path),
                                descriptor_embedding_frames=1))           # accepted
    # a file made before the setting: its embedding took descriptor_frames (1)
    old = {k: v for k, v in np.load(path).items() if k != "embedding_frames"}
    np.savez(tmp_path / "old.npz", **old)
    assert representation.load(tmp_path / "old.npz").embedding_frames == 0
    with pytest.raises(InputError, match="descriptor_embedding_frames"):
        DescriptorLearner(4, preset("default", representation=str(tmp_path / "old.npz")))
    np.savez(tmp_path / "bad.npz", **dict(old, embedding_frames=np.array(1.5)))
    with pytest.raises(InputError, match="embedding_frames"):
        representation.load(tmp_path / "bad.npz")


def test_a_missing_or_foreign_weights_file_names_the_setting(tmp_path):
    with pytest.raises(InputError, match="descriptor_embedding=.*not found"):
        descriptor_size(preset("default", descriptor_embedding=str(tmp_path / "no.npz")))
    np.savez(tmp_path / "foreign.npz", a=np.zeros(3))
    with pytest.raises(InputError, match="not a tactex-embedding-1 file"):
        embedding.load(tmp_path / "foreign.npz")
    emb = _one_layer(1)
    emb.save(tmp_path / "bad.npz")          # a first layer that sees colour: loads
    assert embedding.load(tmp_path / "bad.npz").dim == 2


def test_a_missing_weights_file_is_refused_when_the_learner_is_built(tmp_path):
    """Before any touch: a trial never starts with a network it cannot load."""
    with pytest.raises(InputError, match="descriptor_embedding=.*not found"):
        DescriptorLearner(4, preset("default", descriptor_embedding=str(tmp_path / "no.npz")))
