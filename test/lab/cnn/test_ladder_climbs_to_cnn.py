"""Model 'auto' (core/ladder.py) with the lab's CNN as its top rung: a scene the descriptor
cannot settle (two comparisons alike) climbs to the CNN, which gets every touch, and the trial's
JSON records when and why; the touches keep being chosen by information gain."""

import json

import numpy as np
import pytest

from tactex_ros.core.config import TrialConfig, preset
from tactex_ros.core.engine import TrialSpec
from stripes import stripe_frames


def _touch_fn(seed: int = 0):
    """Reference = comparison 1; comparison 2 shows the same stripes (the hard pair)."""
    frames = stripe_frames(seed, 3)
    rng = np.random.default_rng(seed)
    cls = {0: 0, 1: 0, 2: 0, 3: 1, 4: 2}

    def touch(p: int) -> np.ndarray:
        f = frames[cls[p]].astype(np.int16) + rng.integers(-3, 4, frames[0].shape)
        return np.clip(f, 0, 255).astype(np.uint8)
    return touch


@pytest.mark.slow
def test_hard_scene_climbs_to_the_cnn_and_records_why():
    cfg = preset("default", model="auto", guards=False, ladder="descriptor,cnn@32",
                 ladder_patience=2, ladder_catchup=1)
    eng = TrialSpec(4, cfg, TrialConfig(rounds=5, stop_confidence=0.0), seed=0).engine()
    out = eng.run(_touch_fn(), truth=1)             # the test reads its learner after
    d = json.loads(json.dumps(out.to_dict()))            # what the trial JSON holds
    assert len(d["escalations"]) == 1
    esc = d["escalations"][0]
    assert esc["round"] == 3 and esc["model"] == "small_inception@32"
    assert esc["reason"].startswith("descriptor -> cnn@32: ")
    # the evidence fell below its own test's threshold, and the trial JSON records it
    ev = eng.learner.evidence
    limit = {"heldout": cfg.ladder_heldout_acc, "not_sharpening": cfg.ladder_min_gain,
             "close": cfg.ladder_margin}
    assert ev.threshold == limit[ev.test] and ev.value < ev.threshold
    assert esc["reason"] == f"descriptor -> cnn@32: {ev}"
    assert ev.decisions == 2
    models = [r["model"] for r in d["rounds"]] + [d["final"]["model"]]
    assert models[:2] == ["descriptor", "descriptor"]
    assert set(models[2:]) == {"small_inception"}
    # the CNN got every comparison touch of the trial (augmented views) and trained
    cnn = eng.learner.inner
    assert cnn.n_views == int(eng.touches.sum()) * cnn.cfg.augment
    assert cnn.rounds_trained >= 1 + 4        # catch-up round + one per decision on the rung
    # a descriptor rung's round has no detail; a CNN rung's is a TrainingDetail
    assert d["rounds"][0]["detail"] is None and d["rounds"][1]["detail"] is None
    detail = d["rounds"][2]["detail"]
    assert detail["kind"] == "training" and detail["input_size"] == 32
    assert detail["escalation"] == esc["reason"]
    assert detail["train_loss"] == detail["train_loss"]      # not NaN


class _Cut(Exception):
    """The process dies here."""


@pytest.mark.slow
def test_ladder_resumes_on_its_cnn_rung_from_the_checkpoint():
    """Cut after round 4 (on the CNN rung since round 3): the ladder's checkpoint restores the
    CNN's state, and the trial goes on as the uninterrupted one without re-training."""
    cfg = preset("default", model="auto", guards=False, ladder="descriptor,cnn@32",
                 ladder_patience=2, ladder_catchup=1)

    def engine():
        return TrialSpec(4, cfg, TrialConfig(rounds=6, stop_confidence=0.0), seed=0).engine()
    full = engine().run(_touch_fn(), truth=1)
    eng, src, stored, saved = engine(), _touch_fn(), [], {}

    def touch(p: int):
        stored.append((p, src(p)))
        return stored[-1][1]

    def on_round(r) -> None:
        saved["ck"], saved["n"] = eng.checkpoint(), len(stored)
        if r.round == 4:
            raise _Cut()
    with pytest.raises(_Cut):
        eng.run(touch, truth=1, on_round=on_round)
    from tactex_ros.core.touch import as_touch
    resumed = engine()
    resumed.restore(*saved["ck"][:1], [(p, as_touch(t)) for p, t in stored[:saved["n"]]],
                    saved["ck"][1])
    assert resumed.learner.rung == "cnn@32"
    trained = resumed.learner.inner.rounds_trained
    rest = _touch_fn()
    for p, _ in stored[:saved["n"]]:
        rest(p)
    res = resumed.run(rest, truth=1)
    assert [r.platform for r in res.rounds] == [r.platform for r in full.rounds]
    np.testing.assert_allclose(res.final.probs, full.final.probs, rtol=1e-5, atol=1e-6)
    assert resumed.learner.inner.rounds_trained > trained
