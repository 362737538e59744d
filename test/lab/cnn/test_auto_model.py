"""Model 'cnn_auto' (escalation on evidence) and the failure-mode guards of the trial engine."""

import numpy as np
import pytest
import torch

from tactex_ros.core.config import preset, trial_preset
from tactex_ros.core.ladder import parse_cnn_rungs
from tactex_ros.core.engine import TouchRejected, TrialEngine
from tactex_ros.core.errors import InputError
from tactex_ros.core.guards import ContactGuard, flatness_score
from tactex_lab.cnn.learner import OnlineLearner
from tactex_ros.core.strategies import VarianceStrategy
from stripes import stripe_frames

FAST = dict(input_size=32, steps=2, batch_size=8, mc_passes=4, augment=3, bn_recalibrate=8)


def _touch_fn(seed=0, n=4):
    frames = stripe_frames(seed, n)
    rng = np.random.default_rng(seed)

    def touch(p: int) -> np.ndarray:
        k = (p - 1) % n if p else 1
        noisy = frames[k].astype(np.int16) + rng.integers(-3, 4, frames[k].shape)
        return np.clip(noisy, 0, 255).astype(np.uint8)
    return touch


def test_parse_ladder_checks_names_and_sizes():
    assert parse_cnn_rungs("small_inception@32, small_inception", 64) == [
        "small_inception@32", "small_inception@64"]
    with pytest.raises(InputError, match="unknown model"):
        parse_cnn_rungs("resnet@32", 64)
    with pytest.raises(InputError, match="at least 75"):
        parse_cnn_rungs("inception_v3_random@48", 64)
    with pytest.raises(InputError, match="empty"):
        parse_cnn_rungs(" , ", 64)


def test_auto_escalates_on_evidence_and_keeps_touches():
    # thresholds that any trial meets: entropy "not falling" after 1 round
    cfg = preset("cnn", model="cnn_auto", auto_ladder="small_inception@32,small_inception@40",
                 auto_patience=1, auto_min_drop=1.0, auto_entropy=0.0, auto_catchup=1,
                 **{k: v for k, v in FAST.items() if k != "input_size"})
    eng = TrialEngine(3, cfg, trial_preset("cnn", rounds=4), seed=1)
    res = eng.run(_touch_fn(1, 3), truth=2)
    models = [(r.model, r.detail.input_size) for r in res.rounds + [res.final]]
    assert models[0] == ("small_inception", 32)
    assert models[-1] == ("small_inception", 40)
    esc = [r for r in res.rounds + [res.final] if r.detail.escalation]
    assert len(esc) == 1 and "entropy" in esc[0].detail.escalation
    # every stored touch was re-added to the escalated learner, at its input size
    assert eng.learner.inner.n_views == int(eng.touches.sum()) * cfg.augment
    assert [x.shape[-1] for x in eng.learner.inner._ref_parts] == [40]
    d = res.to_dict()
    assert d["models"] == ["small_inception@32", "small_inception@40"]
    assert d["escalations"][0]["model"] == "small_inception@40"


def test_auto_stays_cheap_without_evidence():
    cfg = preset("cnn", model="cnn_auto", auto_ladder="small_inception@32,small_inception@40",
                 auto_heldout_acc=0.0, auto_entropy=1.0,
                 **{k: v for k, v in FAST.items() if k != "input_size"})
    res = TrialEngine(3, cfg, trial_preset("cnn", rounds=5), seed=0).run(_touch_fn(0, 3), truth=1)
    assert {r.detail.input_size for r in res.rounds + [res.final]} == {32}
    assert not res.to_dict()["escalations"]


def test_heldout_touches_recorded_before_training():
    cfg = preset("cnn", **FAST)
    res = TrialEngine(3, cfg, trial_preset("cnn", rounds=3), seed=0).run(_touch_fn(0, 3), truth=1)
    assert res.rounds[0].heldout == []            # nothing trained before round 1
    assert all(len(r.heldout) == 1 for r in res.rounds[1:] + [res.final])


def test_contact_guard_rejects_blank_and_no_contact_frames():
    tex = stripe_frames(0, 1)[0]
    flat = np.full((240, 320, 3), 100, np.uint8)
    flat[::7, ::5] += 1
    assert flatness_score(flat) < 0.35 < flatness_score(tex)
    g = ContactGuard()
    assert g.check(tex)[0] and not g.check(flat)[0]
    g.set_reference(tex)                          # the same frame = no contact against it
    ok, reason = g.check(tex)
    assert not ok and "no contact" in reason
    # lighting drift alone is not contact
    drift = np.clip(tex.astype(int) + np.array([6, -4, 3]), 0, 255).astype(np.uint8)
    assert not g.check(drift)[0]


def test_engine_rejects_blank_touch_and_run_goes_on():
    cfg = preset("cnn", **FAST)
    flat = np.full((240, 320, 3), 90, np.uint8)
    flat[0, 0] = 91
    eng = TrialEngine(3, cfg, trial_preset("cnn", rounds=2), seed=0)
    with pytest.raises(TouchRejected, match="blank"):
        eng.add_touch(1, flat)
    assert eng.touches[0] == 0 and 1 in eng.baseline_platforms()
    # unguarded: the same frame is stored
    eng2 = TrialEngine(3, preset("cnn", guards=False, **FAST), trial_preset("cnn", rounds=2))
    eng2.add_touch(1, flat)
    assert eng2.touches[0] == 1
    # in run(): a blank touch is a recorded failure, the platform is retried
    good = _touch_fn(0, 3)
    calls = {"n": 0}

    def touch(p):
        calls["n"] += 1
        return flat if calls["n"] == 2 else good(p)
    res = TrialEngine(3, cfg, trial_preset("cnn", rounds=2), seed=0).run(touch, truth=1)
    assert len(res.failed_touches) == 1 and "blank" in res.failed_touches[0]["reason"]


def test_nonfinite_loss_is_skipped_with_guards_and_raises_without():
    frames = stripe_frames(0, 3)
    for guards in (True, False):
        L = OnlineLearner(3, preset("cnn", guards=guards, **FAST), seed=0)
        for k, f in enumerate(frames):
            L.add_touch(f, k)
        orig = L.model.forward_train
        calls = {"n": 0}

        def bad(x, orig=orig, calls=calls):
            calls["n"] += 1
            logits, aux = orig(x)
            return (logits * float("nan") if calls["n"] == 1 else logits), aux
        L.model.forward_train = bad
        if guards:
            st = L.train_round()
            assert st.skipped == 1 and st.steps == FAST["steps"] - 1 and not st.restored
            assert all(torch.isfinite(p).all() for p in L.model.parameters())
        else:
            with pytest.raises(FloatingPointError):
                L.train_round()


def test_round_rolled_back_when_most_steps_are_bad():
    L = OnlineLearner(3, preset("cnn", **FAST), seed=0)
    for k, f in enumerate(stripe_frames(0, 3)):
        L.add_touch(f, k)
    before = {k: v.clone() for k, v in L.model.state_dict().items() if "bn" not in k}
    orig = L.model.forward_train
    L.model.forward_train = lambda x: (orig(x)[0] * float("inf"), None)
    st = L.train_round()
    assert st.restored and st.skipped == FAST["steps"]
    assert L.opt.param_groups[0]["lr"] == pytest.approx(preset("cnn").lr / 2)
    after = L.model.state_dict()
    assert all(torch.equal(before[k], after[k]) for k in before)


def test_degenerate_scores_tie_break_vs_plain_argmax():
    probs = np.full((5, 4), 0.25)                  # every pass identical: all scores 0
    touches = np.array([3, 1, 2, 1])
    s = VarianceStrategy()
    assert s.choose(probs, touches, np.random.default_rng(0))[0] == 1
    assert s.choose(probs, touches, np.random.default_rng(0), tie_break=False)[0] == 0


def test_drift_norm_removes_a_per_touch_colour_offset():
    img = stripe_frames(0, 1)[0]
    shifted = np.clip(img.astype(int) + np.array([9, -7, 5]), 0, 255).astype(np.uint8)
    on = OnlineLearner(3, preset("cnn", drift_norm=True, **FAST), seed=0)
    a, b = on.test_tensor(img), on.test_tensor(shifted)
    assert float((a - b).abs().max()) < 0.05        # only clipping / rounding left
    off = OnlineLearner(3, preset("cnn", **FAST), seed=0)
    assert float((off.test_tensor(img) - off.test_tensor(shifted)).abs().max()) > 0.1


def test_rejected_touch_is_repeated_at_once_not_a_lost_round():
    """touch_retries: a guard-rejected touch is pressed again in the same round; with 0 retries
    the round is lost (one accepted touch fewer)."""
    cfg = preset("cnn", **FAST)
    flat = np.full((240, 320, 3), 90, np.uint8)
    flat[0, 0] = 91          # not constant: the guard (not frame validation) must refuse it
    good = _touch_fn(0, 3)

    def run(retries: int):
        calls = {"n": 0}

        def touch(p):
            calls["n"] += 1
            return flat if calls["n"] == 5 else good(p)     # the first round's touch is blank
        eng = TrialEngine(3, cfg, trial_preset("cnn", rounds=2, touch_retries=retries), seed=0)
        res = eng.run(touch, truth=1)
        return res, int(eng.touches.sum()) + eng.reference_touches, calls["n"]

    res2, accepted2, calls2 = run(2)
    res0, accepted0, calls0 = run(0)
    assert len(res2.failed_touches) == len(res0.failed_touches) == 1
    # baseline: reference + 3 comparisons; 2 rounds; the blank one repeated at once
    assert accepted2 == 4 + 2 and calls2 == 4 + 2 + 1
    assert accepted0 == 4 + 1 and calls0 == 4 + 2


def test_touch_retries_validated():
    with pytest.raises(InputError, match="touch_retries"):
        TrialEngine(3, preset("cnn", **FAST), trial_preset("cnn", touch_retries=-1))


def test_run_reports_rejections_and_honours_no_retry_failures():
    """on_rejected sees every frame add_touch refuses (guard or validation), which is retried;
    a TouchFailed(retry=False) (its thrower already retried) loses its touch at once."""
    from tactex_ros.core.engine import TouchFailed
    cfg = preset("cnn", **FAST)
    good = _touch_fn(0, 3)
    constant = np.full((240, 320, 3), 90, np.uint8)
    calls = {"n": 0}
    seen = []

    def touch(p):
        calls["n"] += 1
        if calls["n"] == 2:
            return constant                      # fails validation: refused, pressed again
        if calls["n"] == 6:
            raise TouchFailed("motion node gave up", retry=False)
        return good(p)
    eng = TrialEngine(3, cfg, trial_preset("cnn", rounds=2), seed=0)
    res = eng.run(touch, truth=1, on_rejected=lambda p, exc: seen.append((p, str(exc))))
    assert len(seen) == 1 and seen[0][0] == 1 and "constant" in seen[0][1]
    assert [f["reason"] for f in res.failed_touches][1] == "motion node gave up"
    assert calls["n"] == 5 + 2           # baseline 4 + 1 repeat, 2 rounds, no repeat of call 6
    assert int(eng.touches.sum()) + eng.reference_touches == 4 + 1
