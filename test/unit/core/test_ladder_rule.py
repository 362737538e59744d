"""Model 'auto' (core/ladder.py): the escalation rule on synthetic beliefs (exact values), the
rung list, a skipped rung, and a trial on synthetic descriptors that climbs and says why."""

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from tactex_ros.core import representation as rp
from tactex_ros.core.build import make_learner
from tactex_ros.core.calibration import PLACEHOLDER_FRAME
from tactex_ros.core.config import TrialConfig, preset
from tactex_ros.core.engine import TrialSpec, run_trial
from tactex_ros.core.errors import InputError
from tactex_ros.core.ladder import (EntropyRule, Evidence, Ladder, Rule, entropy_reason,
                                    escalation_reason, parse_cnn_rungs, parse_rungs, rungs_of)
from tactex_ros.core.texture import descriptor_dim

DIM = descriptor_dim(True)        # the shipped descriptor (with the height map)
from tactex_ros.core.touch import Touch

RULE = Rule(patience=2, min_gain=0.1, sure=0.9, margin=0.1, window=3, heldout_acc=0.5)


def b(*p: float) -> np.ndarray:
    return np.array(p)


def test_nothing_is_tested_before_patience_decisions():
    assert escalation_reason([b(0.3, 0.3, 0.2, 0.2)], [False] * 5, RULE) is None


def test_heldout_touches_misclassified():
    ev = escalation_reason([b(0.6, 0.2, 0.1, 0.1)] * 2, [True, True, False, False], RULE)
    assert ev == Evidence("heldout", pytest.approx(1 / 3), 0.5, 2)
    # a window not yet full is not judged; 2 of 3 right is enough
    assert escalation_reason([b(0.6, 0.2, 0.1, 0.1)] * 2, [False, False], RULE) is None
    assert escalation_reason([b(0.6, 0.2, 0.1, 0.1)] * 2, [False, True, True], RULE) is None


def test_belief_that_does_not_sharpen_over_patience_decisions():
    hist = [b(0.50, 0.20, 0.20, 0.10), b(0.55, 0.20, 0.15, 0.10), b(0.58, 0.22, 0.1, 0.1)]
    ev = escalation_reason(hist, [], RULE)
    assert (ev.test, ev.value, ev.threshold, ev.decisions) == ("not_sharpening",
                                                               pytest.approx(0.08), 0.1, 3)
    rising = [b(0.40, 0.30, 0.20, 0.10), b(0.55, 0.20, 0.15, 0.10), b(0.70, 0.1, 0.1, 0.1)]
    assert escalation_reason(rising, [], RULE) is None


def test_best_two_close():
    ev = escalation_reason([b(0.4, 0.3, 0.2, 0.1), b(0.45, 0.40, 0.1, 0.05)], [], RULE)
    assert (ev.test, ev.value, ev.decisions) == ("close", pytest.approx(0.05), 2)
    assert escalation_reason([b(0.4, 0.3, 0.2, 0.1), b(0.55, 0.40, 0.05, 0.0)], [], RULE) is None


def test_a_sharp_belief_never_climbs_on_belief_evidence():
    flat = [b(0.92, 0.05, 0.02, 0.01)] * 4
    assert escalation_reason(flat, [], RULE) is None
    assert escalation_reason(flat, [False, False, False], RULE).test == "heldout"


ERULE = EntropyRule(patience=2, min_drop=0.7, entropy=0.2, window=3, heldout_acc=0.5,
                    num_classes=4)          # floor 0.2 log 4 = 0.277 nats


def test_cnn_auto_rule_heldout_from_the_first_full_window():
    # unlike the belief rule, held-back touches are judged before any decision on the rung
    ev = entropy_reason([], [True, False, False], ERULE)
    assert ev == Evidence("heldout", pytest.approx(1 / 3), 0.5, 0)
    assert ERULE.describe(ev, "a", "b") == \
        "held-back touches: 0.33 of the last 3 classified right < 0.5"
    assert entropy_reason([1.0], [False, False], ERULE) is None


def test_cnn_auto_rule_entropy_that_does_not_fall():
    ev = entropy_reason([1.0, 0.8, 0.5], [], ERULE)      # fell 50 % < 70 %, above 0.277
    assert (ev.test, ev.value, ev.before, ev.decisions) == ("entropy", 0.5, 1.0, 3)
    assert ev.threshold == pytest.approx(0.2 * np.log(4))
    assert ERULE.describe(ev, "a", "b") == \
        "entropy not falling: 1.000 -> 0.500 nats over 2 rounds, above 0.277"
    assert entropy_reason([1.0, 0.8], [], ERULE) is None          # not more than patience
    assert entropy_reason([1.0, 0.8, 0.29], [], ERULE) is None    # fell 71 %
    assert entropy_reason([0.5, 0.4, 0.27], [], ERULE) is None    # below the floor


def test_cnn_auto_is_the_ladder_with_cnn_rungs():
    cfg = preset("cnn", model="cnn_auto", auto_ladder="small_inception@32,small_inception",
                 auto_patience=3, auto_catchup=1, lr=1e-2)
    assert cfg.is_ladder and not cfg.plugin and preset("cnn").plugin
    plan = rungs_of(cfg, 4)
    assert plan.names == ["small_inception@32", "small_inception@48"]
    assert plan.rule == EntropyRule(3, 0.7, 0.2, 3, 0.5, 4) and plan.catchup == 1
    rung = plan.config("small_inception@48")
    assert (rung.model, rung.input_size, rung.lr, rung.steps) == ("small_inception", 48, 1e-2, 8)
    assert parse_cnn_rungs("inception_v3@96", 48) == ["inception_v3@96"]


@pytest.mark.parametrize("text", ["", "descriptor,vgg", "descriptor@32", "cnn@16",
                                  "default", "auto"])
def test_bad_rungs_refused(text):
    with pytest.raises(InputError):
        parse_rungs(text)


def test_rungs_parse_with_commas_or_plus():
    assert parse_rungs("descriptor+representation,cnn@64") == ["descriptor", "representation",
                                                               "cnn@64"]


def _rep_file(tmp_path) -> str:
    rng = np.random.default_rng(0)
    lib = {f"k{c}": rng.normal(0, 1, DIM) + rng.normal(0, 0.2, (4, DIM)) for c in range(5)}
    return str(rp.save(rp.fit(lib), tmp_path / "rep.npz"))


def test_rung_without_its_file_is_skipped_with_a_note():
    lad = make_learner(4, preset("descriptor", model="auto", ladder="descriptor,representation"))
    assert isinstance(lad, Ladder) and lad.rungs == ["descriptor"]
    assert len(lad.notes) == 1 and "representation" in lad.notes[0]


def _scene_touches(twins: bool):
    """Touch function over 4 comparisons whose descriptors are drawn around class centres;
    with ``twins`` comparisons 1 and 2 (the match) have the same centre."""
    rng = np.random.default_rng(3)
    centres = rng.normal(0, 1, (4, DIM))
    if twins:
        centres[1] = centres[0]

    def touch(platform: int) -> Touch:
        c = centres[0 if platform == 0 else platform - 1]
        return Touch(PLACEHOLDER_FRAME, None, None, c + rng.normal(0, 0.3, DIM))
    return touch


def test_trial_climbs_on_a_hard_scene_and_records_why(tmp_path):
    cfg = preset("descriptor", model="auto", guards=False, representation=_rep_file(tmp_path),
                 ladder="descriptor,representation", ladder_patience=2)
    spec = TrialSpec(4, cfg, TrialConfig(rounds=8, stop_confidence=0.0), seed=0)
    out = run_trial(spec, _scene_touches(twins=True), truth=1).to_dict()
    esc = out["escalations"]
    assert len(esc) == 1 and esc[0]["round"] == 3          # patience 2: first test at round 3
    assert esc[0]["reason"].startswith("descriptor -> representation")
    models = [r["model"] for r in out["rounds"]]
    assert models[:2] == ["descriptor", "descriptor"] and set(models[2:]) == {"representation"}
    assert out["notes"] == []


def test_trial_stays_on_the_descriptor_when_the_scene_is_easy(tmp_path):
    cfg = preset("descriptor", model="auto", guards=False, representation=_rep_file(tmp_path),
                 ladder="descriptor,representation")
    spec = TrialSpec(4, cfg, TrialConfig(rounds=8), seed=0)
    out = run_trial(spec, _scene_touches(twins=False), truth=1).to_dict()
    assert out["correct"] and out["escalations"] == []
    assert {r["model"] for r in out["rounds"] + [out["final"]]} == {"descriptor"}


def test_the_products_learners_need_no_installed_metadata():
    """From a checkout that is not installed (no entry points at all) ``descriptor`` and
    ``auto`` are still built (in code); a CNN is refused by name, exit status 2."""
    code = ("import importlib.metadata as m; m.entry_points = lambda **kw: []; "
            "from tactex_ros.core.build import make_learner; "
            "from tactex_ros.core.config import preset; "
            "from tactex_ros.core.errors import InputError; "
            "lad = make_learner(4, preset('descriptor', model='auto')); "
            "d = make_learner(4, preset('descriptor')); "
            "print(type(lad).__name__, lad.rungs, type(d).__name__)\n"
            "try: make_learner(4, preset('cnn', model='cnn_auto'))\n"
            "except InputError as e: print(e)\n"
            "make_learner(4, preset('cnn'))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         cwd=Path(__file__).resolve().parents[3], timeout=600)
    assert out.stdout.split("\n")[0] == "Ladder ['descriptor'] DescriptorLearner", out.stderr
    # cnn_auto is a ladder of plug-in CNNs: without them no rung is usable, each one named
    assert out.stdout.split("\n")[1].startswith(
        "ladder 'small_inception@48,small_inception@96': no usable rung"), out.stdout
    assert "InputError" in out.stderr and "small_inception" in out.stderr
