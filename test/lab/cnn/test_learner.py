import numpy as np
import pytest

from tactex_ros.core.config import CnnSettings, preset, trial_preset
from tactex_ros.core.engine import TouchFailed, TrialEngine
from tactex_ros.core.errors import InputError
from tactex_lab.cnn.learner import OnlineLearner, class_weights
from tactex_lab.cnn.preprocess import augment, view
from tactex_ros.core.touch import validate_frame
from stripes import stripe_frames

FAST = dict(input_size=48, steps=4, batch_size=16, mc_passes=8)


def test_class_weights_hand_computed():
    w = class_weights(np.array([0, 0, 0, 1, 2, 2]), 4)
    np.testing.assert_allclose(w, [6 / (4 * 3), 6 / 4, 6 / (4 * 2), 0])
    # weighted total per class is equal: n_c * w_c = N / C
    counts = np.array([3, 1, 2])
    np.testing.assert_allclose(counts * w[:3], 6 / 4)


def test_rotated_views_have_no_black_corners():
    white = np.full((240, 320, 3), 255, np.uint8)
    white[0, 0] = 0  # not constant
    views = augment(white, 36, 64, np.random.default_rng(0))
    assert views.shape == (36, 64, 64, 3)
    assert views.min() > 200  # no zero-padded corner anywhere, at any angle


def test_view_rotation_is_a_rotation():
    img = stripe_frames(0, 1)[0]
    a = view(img, 0.0, 100).astype(float)
    b = view(img, 90.0, 100).astype(float)
    np.testing.assert_allclose(np.rot90(b, k=-1)[5:-5, 5:-5], a[5:-5, 5:-5], atol=40)


def test_bad_frames_are_rejected_with_reason():
    with pytest.raises(InputError, match="shape"):
        validate_frame(np.zeros((10, 10, 3), np.uint8))
    with pytest.raises(InputError, match="dtype"):
        validate_frame(np.zeros((240, 320, 3), np.float32))
    with pytest.raises(InputError, match="constant"):
        validate_frame(np.zeros((240, 320, 3), np.uint8))


def test_config_validation_names_the_field():
    with pytest.raises(InputError, match="input_size"):
        preset("cnn", input_size=8)
    with pytest.raises(InputError, match="model"):
        CnnSettings(model="vgg")
    with pytest.raises(InputError, match="configuration"):
        preset("turbo")


def _run(seed: int, strategy: str = "variance", rounds: int = 3, **over):
    frames = stripe_frames(1, 4)
    rng = np.random.default_rng(seed)
    cfg = preset("cnn", **{**FAST, **over})
    eng = TrialEngine(4, cfg, trial_preset("cnn", strategy=strategy, rounds=rounds), seed=seed)

    def touch(p):
        k = 2 if p == 0 else p - 1
        noise = rng.integers(-6, 7, (240, 320, 3))
        return np.clip(frames[k].astype(int) + noise, 0, 255).astype(np.uint8)

    return eng.run(touch, truth=3)


def test_seeded_determinism():
    a, b = _run(5), _run(5)
    assert [r.probs for r in a.rounds] == [r.probs for r in b.rounds]
    assert [r.platform for r in a.rounds] == [r.platform for r in b.rounds]
    assert a.final.probs == b.final.probs
    c = _run(6)
    assert c.final.probs != a.final.probs


def test_engine_records_rounds_and_learns_an_easy_trial():
    res = _run(0, rounds=4, steps=10)
    assert res.touches == 5 + 4
    assert len(res.rounds) == 4 and all(r.platform in (1, 2, 3, 4) for r in res.rounds)
    for r in res.rounds:
        assert len(r.probs) == 4 and abs(sum(r.probs) - 1) < 1e-6
        assert len(r.scores) == 4 and r.train_s > 0 and r.score_s > 0
    assert res.prediction == 3 and res.correct
    d = res.to_dict()
    assert d["correct"] is True and d["prediction"] == "c3" and len(d["rounds"]) == 4


def test_yoto_never_revisits():
    res = _run(1, strategy="yoto", rounds=3)
    assert res.touches == 5
    assert all(r.platform is None for r in res.rounds)
    assert len(res.rounds) == 3  # training rounds still run


def test_failed_touch_is_recorded_and_trial_goes_on():
    frames = stripe_frames(2, 4)
    calls = {"n": 0}

    def touch(p):
        calls["n"] += 1
        if calls["n"] == 7:
            raise TouchFailed("no contact before deadline")
        return frames[2 if p == 0 else p - 1]

    eng = TrialEngine(4, preset("cnn", **FAST), trial_preset("cnn", rounds=3), seed=0)
    res = eng.run(touch, truth=3)
    assert len(res.failed_touches) == 1 and "deadline" in res.failed_touches[0]["reason"]
    assert res.touches == 5 + 3          # the failed touch was repeated at once
    calls["n"] = 0
    eng = TrialEngine(4, preset("cnn", **FAST), trial_preset("cnn", rounds=3, touch_retries=0),
                      seed=0)
    res = eng.run(touch, truth=3)
    assert len(res.failed_touches) == 1
    assert res.touches == 5 + 3 - 1      # without retries the round is lost


def test_learner_training_reduces_loss():
    frames = stripe_frames(3, 3)
    L = OnlineLearner(3, preset("cnn", **{**FAST, "steps": 15}), seed=0)
    for k, f in enumerate(frames):
        L.add_touch(f, k)
    first = L.train_round().mean_loss
    for _ in range(4):
        last = L.train_round().mean_loss
    assert last < first * 0.7
