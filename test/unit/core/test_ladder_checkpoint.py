"""Model 'auto' (core/ladder.py) resumed from its learner checkpoint: a trial cut after it
climbed continues on the rung it had reached with the same decisions and result as the
uninterrupted trial; bytes that do not fit are refused by name."""

from __future__ import annotations

import numpy as np
import pytest

from tactex_ros.core import representation as rp
from tactex_ros.core.calibration import PLACEHOLDER_FRAME
from tactex_ros.core.config import TrialConfig, preset
from tactex_ros.core.engine import TrialEngine
from tactex_ros.core.errors import InputError
from tactex_ros.core.texture import descriptor_dim

DIM = descriptor_dim(True)        # the shipped descriptor (with the height map)
from tactex_ros.core.touch import Touch


class Cut(Exception):
    """The process dies here."""


def _touches():
    """Comparisons 1 and 2 (the match) share a centre: the descriptor rung stays unsure."""
    rng = np.random.default_rng(3)
    centres = rng.normal(0, 1, (4, DIM))
    centres[1] = centres[0]

    def touch(platform: int) -> Touch:
        c = centres[0 if platform == 0 else platform - 1]
        return Touch(PLACEHOLDER_FRAME, None, None, c + rng.normal(0, 0.3, DIM))
    return touch


@pytest.fixture
def engine(tmp_path):
    rng = np.random.default_rng(0)
    lib = {f"k{c}": rng.normal(0, 1, DIM) + rng.normal(0, 0.2, (4, DIM)) for c in range(5)}
    rep = str(rp.save(rp.fit(lib), tmp_path / "rep.npz"))
    cfg = preset("descriptor", model="auto", guards=False, representation=rep,
                 ladder="descriptor,representation", ladder_patience=2)
    return lambda: TrialEngine(4, cfg, TrialConfig(rounds=8, stop_confidence=0.0), seed=0)


def _cut_run(eng: TrialEngine, cut_round: int):
    """Run until the checkpoint after ``cut_round``; returns (state, blob, stored touches)."""
    src, stored, saved = _touches(), [], {}

    def touch(p: int) -> Touch:
        t = src(p)
        stored.append((p, t))
        return t

    def on_round(r) -> None:
        ck = eng.checkpoint()
        if ck is not None:
            saved["ck"], saved["n"] = ck, len(stored)
        if r.round == cut_round:
            raise Cut()
    with pytest.raises(Cut):
        eng.run(touch, truth=1, on_round=on_round)
    return saved["ck"][0], saved["ck"][1], stored[:saved["n"]]


def test_resumed_ladder_continues_on_its_rung(engine):
    full = engine().run(_touches(), truth=1)
    assert [r.round for r in full.rounds if r.detail and r.detail.escalation] == [3]
    state, blob, stored = _cut_run(engine(), cut_round=4)       # after the climb
    eng = engine()
    eng.restore(state, stored, blob)
    assert eng.learner.rung == "representation" and len(eng.learner.active) == 2
    src = _touches()
    for p, _ in stored:                                       # the source after those touches
        src(p)
    res = eng.run(src, truth=1)
    assert [r.platform for r in res.rounds] == [r.platform for r in full.rounds]
    assert [r.model for r in res.rounds] == [r.model for r in full.rounds]
    np.testing.assert_allclose(res.final.probs, full.final.probs, rtol=1e-12)
    assert res.prediction == full.prediction and res.touches == full.touches


def test_ladder_state_that_does_not_fit_is_refused(engine):
    state, blob, stored = _cut_run(engine(), cut_round=4)
    with pytest.raises(InputError, match="^ladder state unreadable"):
        engine().learner.load_state(b"\x00\x00")
    eng = engine()
    with pytest.raises(InputError, match="^ladder state of another ladder or other touches"):
        eng.learner.load_state(blob)                          # no touches added first
