"""The e-value stop rule (core/evidence.py): a hand-computed e-process, Ville's bound under the
null by simulation, the fit on a library, and the engine's stop at 1 / alpha."""

import math

import numpy as np
import pytest

from tactex_ros.core.calibration import PLACEHOLDER_FRAME
from tactex_ros.core.config import TrialConfig, preset
from tactex_ros.core.engine import TrialEngine, TrialSpec, trial_preset
from tactex_ros.core.errors import InputError
from tactex_ros.core.evidence import (EProcess, EvidenceModel, fit_evidence,
                                      normalised_distance)
from tactex_ros.core.touch import Touch

# log-normal same N(0, 1), null N(1, 1) in log z: log ratio = -log z + 0.5
UNIT = EvidenceModel(mu_same=0.0, sd_same=1.0, mu_diff=1.0, sd_diff=1.0)


def test_log_ratio_hand_computed():
    assert UNIT.log_ratio(1.0) == pytest.approx(0.5, abs=1e-12)
    assert UNIT.log_ratio(math.e) == pytest.approx(-0.5, abs=1e-12)
    m = EvidenceModel(mu_same=0.0, sd_same=0.5, mu_diff=0.0, sd_diff=1.0)
    # lz = log 2: -0.5 (2 lz)^2 - log 0.5 + 0.5 lz^2 + log 1
    lz = math.log(2.0)
    assert m.log_ratio(2.0) == pytest.approx(-1.5 * lz ** 2 + math.log(2.0), abs=1e-12)


def test_eprocess_hand_computed():
    e = EProcess(2, UNIT, alpha=0.2)
    samples: list[list[np.ndarray]] = [[], [], []]

    def touch(p: int, x: list[float]) -> None:
        v = np.asarray(x, float)
        e.add_touch(p, v, [list(s) for s in samples])
        samples[p].append(v)

    touch(0, [0.0, 0.0])          # nothing to compare with yet
    assert e.observations == 0 and e.evalues.tolist() == [1.0, 1.0]
    touch(1, [1.0, 0.0])          # z = 1 / sqrt 2 against the reference
    touch(2, [3.0, 4.0])          # z = 5 / sqrt 2
    touch(0, [0.0, 0.0])          # the same two distances again, to c1's and c2's means
    assert e.observations == 4
    assert e.evalues[0] == pytest.approx(2.0 * math.e, rel=1e-12)      # (sqrt2 e^0.5)^2
    assert e.evalues[1] == pytest.approx(math.e * 2.0 / 25.0, rel=1e-12)
    assert e.sure() == 0           # E_1 = 2e = 5.44 >= 1 / 0.2 = 5


def test_eprocess_stops_at_one_over_alpha():
    e = EProcess(2, UNIT, alpha=0.2)
    e.observe(0, 1.0 / math.sqrt(2.0))
    e.observe(0, 1.0 / math.sqrt(2.0))       # E_1 = 2e = 5.44 >= 5
    assert e.sure() == 0
    st = e.state()
    assert st["alpha"] == 0.2 and st["threshold"] == pytest.approx(5.0)
    assert st["evalues"][0] == pytest.approx(2.0 * math.e) and st["evalues"][1] == 1.0
    e2 = EProcess(2, UNIT, alpha=0.1)        # 1/alpha = 10 > 5.44: not yet
    e2.observe(0, 1.0 / math.sqrt(2.0))
    e2.observe(0, 1.0 / math.sqrt(2.0))
    assert e2.sure() is None


def test_normalised_distance():
    assert normalised_distance(np.array([3.0, 4.0]), [np.zeros(2)]) == pytest.approx(
        5.0 / math.sqrt(2.0))
    # mean of 3 earlier touches (1, 0): ||(1, 0)|| / sqrt(1 + 1/3)
    assert normalised_distance(np.array([2.0, 0.0]), [np.array([1.0, 0.0])] * 3) == \
        pytest.approx(1.0 / math.sqrt(4.0 / 3.0))
    with pytest.raises(InputError):
        normalised_distance(np.zeros(2), [])


def test_ville_bound_under_the_null():
    # z drawn from the null f0 itself, 40 observations per run: the share of runs whose E ever
    # reaches 1/alpha is at most alpha (Ville), within 3 binomial sigma of 20000 runs
    m = EvidenceModel(mu_same=0.0, sd_same=0.6, mu_diff=0.8, sd_diff=0.6)
    rng = np.random.default_rng(5)
    alpha, runs, steps = 0.03, 20000, 40
    lz = rng.normal(m.mu_diff, m.sd_diff, size=(runs, steps))
    lr = (-0.5 * ((lz - m.mu_same) / m.sd_same) ** 2 + 0.5 * ((lz - m.mu_diff) / m.sd_diff) ** 2)
    ever = (np.cumsum(lr, axis=1) >= math.log(1 / alpha)).any(axis=1).mean()
    assert ever <= alpha + 3 * math.sqrt(alpha * (1 - alpha) / runs)
    # the same check of EProcess itself on a few runs agrees with the vectorised one
    hits = 0
    for r in range(300):
        e = EProcess(1, m, alpha)
        for z in np.exp(lz[r]):
            e.observe(0, float(z))
            if e.sure() is not None:
                hits += 1
                break
    assert hits == int((np.cumsum(lr[:300], axis=1) >= math.log(1 / alpha)).any(axis=1).sum())
    # under H1 the rule does stop (the test can fail: a rule that never stops is not valid)
    lz1 = rng.normal(m.mu_same, m.sd_same, size=(2000, steps))
    lr1 = (-0.5 * ((lz1 - m.mu_same) / m.sd_same) ** 2 +
           0.5 * ((lz1 - m.mu_diff) / m.sd_diff) ** 2)
    assert (np.cumsum(lr1, axis=1) >= math.log(1 / alpha)).any(axis=1).mean() > 0.95


def test_the_nearest_null_pairs_each_class_with_its_nearest_classes_only():
    """Class means on a line at 0, 1, 3, 7 (one dimension, 3 touches each, no spread within a
    class): with nearest=1 the null pairs are 0-1, 1-3 (1's nearest is 0, 3's is 1) and 3-7;
    their z = |difference| / sqrt(2), so the null's log z mean is that of 1, 2, 4."""
    from tactex_ros.core.evidence import _null_pairs
    means = [np.array([0.0]), np.array([1.0]), np.array([3.0]), np.array([7.0])]
    assert _null_pairs(means, 1) == [[1], [2], [3], []]
    assert _null_pairs(means, 0) == _null_pairs(means, 3) == [[1, 2, 3], [2, 3], [3], []]
    rng = np.random.default_rng(0)
    lib = {f"k{i}": np.full((3, 1), m[0]) + rng.normal(0, 1e-3, (3, 1))
           for i, m in enumerate(means)}
    near, every = fit_evidence(lib, nearest=1), fit_evidence(lib)
    want = np.mean(np.log(np.array([1.0, 2.0, 4.0]) / math.sqrt(2)))
    assert near.mu_diff == pytest.approx(want, abs=1e-2)
    assert near.mu_diff < every.mu_diff          # the nearest different class is closer
    with pytest.raises(InputError, match="nearest"):
        fit_evidence(lib, nearest=-1)


def test_fit_on_a_library():
    rng = np.random.default_rng(0)
    lib = {f"k{i}": rng.normal(3.0 * i, 0.3, size=(6, 5)) for i in range(4)}
    m = fit_evidence(lib)
    assert m.mu_same < m.mu_diff and m.sd_same == m.sd_diff > 0
    # same-class z of (n, D=5) normal with sigma 0.3: ||a-b||/sqrt2 ~ 0.3 chi_5, log ~ log(0.63)
    assert m.mu_same == pytest.approx(math.log(0.3 * math.sqrt(5)), abs=0.25)
    with pytest.raises(InputError, match="2 classes"):
        fit_evidence({"a": np.zeros((3, 2))})
    with pytest.raises(InputError, match="sd_same"):
        EvidenceModel(0.0, 0.0, 1.0, 1.0)
    assert EvidenceModel.from_dict(m.to_dict()) == m
    with pytest.raises(InputError, match="mu_diff"):
        EvidenceModel.from_dict({"mu_same": 0, "sd_same": 1, "sd_diff": 1})


def _touches(values: list[float], seed: int = 0):
    rng = np.random.default_rng(seed)

    def touch(p: int) -> Touch:
        return Touch(PLACEHOLDER_FRAME, None, None, values[p] + 0.05 * rng.standard_normal(4))
    return touch


def test_engine_stops_at_the_evalue_and_records_the_bound():
    model = EvidenceModel(mu_same=math.log(0.1), sd_same=0.5, mu_diff=math.log(2.0),
                          sd_diff=0.5)
    cfg = preset("default", guards=False)
    tc = trial_preset("default", rounds=10, stop_rule="evalue", stop_alpha=0.03)
    res = TrialSpec(3, cfg, tc, seed=0, evidence=model).engine().run(
        _touches([0.0, 0.0, 2.0, 4.0]), truth=1)
    assert res.stop_reason == "confident" and res.sure is True and res.correct
    b = res.to_dict()["bound"]
    assert b["rule"] == "evalue" and b["alpha"] == 0.03
    assert b["evalues"][0] >= 1 / 0.03 and max(b["evalues"][1:]) < 1 / 0.03
    # no comparison matches: the e-values stay low, the budget ends not sure
    res2 = TrialSpec(3, cfg, tc, seed=0, evidence=model).engine().run(
        _touches([1.0, -1.0, 2.5, 4.0]), truth=1)
    assert res2.sure is False and res2.stop_reason == "rounds" and res2.touches == 4 + 10
    # the threshold rule records its theta
    res3 = TrialSpec(3, cfg, trial_preset("default", rounds=4)).engine().run(
        _touches([0.0, 0.0, 2.0, 4.0]), truth=1)
    assert res3.to_dict()["bound"] == {"rule": "threshold", "stop_confidence": 0.9}


def test_evalue_settings_refused_by_name():
    with pytest.raises(InputError, match="stop_rule"):
        TrialConfig.check({"stop_rule": "bayes"}, "trial")
    with pytest.raises(InputError, match="stop_alpha"):
        TrialConfig.check({"stop_alpha": 0.0}, "trial")
    with pytest.raises(InputError, match="needs model 'descriptor'"):
        TrialEngine(3, preset("cnn"), trial_preset("cnn", stop_rule="evalue"))


def test_shipped_evidence_model_fits_the_default_settings():
    from tactex_ros.core.evidence import shipped_evidence
    m = shipped_evidence(preset("default"))
    assert m.mu_same < m.mu_diff                 # one material's touches are the closer
    with pytest.raises(InputError, match="descriptor space"):
        shipped_evidence(preset("descriptor"))   # no embedding: another space
    # the engine takes it when no model is given
    eng = TrialEngine(3, preset("default", guards=False),
                      trial_preset("default", stop_rule="evalue"))
    assert eng.eprocess is not None and eng.eprocess.model == m


def test_two_evalues_above_the_bound_are_not_sure():
    e = EProcess(3, UNIT, alpha=0.2)
    for c in (0, 2):
        e.observe(c, 1.0 / math.sqrt(2.0))
        e.observe(c, 1.0 / math.sqrt(2.0))        # both at 2e >= 5
    assert e.sure() is None
    e.observe(2, math.e ** 3)                     # log ratio -2.5: c3 falls to 2e e^-2.5 < 5
    assert e.sure() == 0


def test_scene_null_hand_computed():
    """null 'scene': the comparisons' own pairs move the null's mean closer (never past
    mu_same), and every e-value is recomputed with it; 'library' keeps the model's."""
    procs = {n: EProcess(3, UNIT, alpha=0.2, null=n) for n in ("library", "scene")}
    samples: list[list[np.ndarray]] = [[], [], [], []]

    def touch(p: int, x: list[float]) -> None:
        v = np.asarray(x, float)
        for e in procs.values():
            e.add_touch(p, v, [list(s) for s in samples])
        samples[p].append(v)

    touch(0, [0.0, 0.0])
    touch(1, [1.0, 0.0])              # z = 1/sqrt2 against the reference: log ratio 0.5 + log 2 / 2
    touch(2, [1.0, 0.0])              # pair c1-c2: distance 0 (floored)
    touch(3, [0.0, 1.0])              # pairs c3-c1, c3-c2: distance sqrt2, z = 1, log z 0
    lib, scene = procs["library"], procs["scene"]
    assert lib.null_mean() == 1.0 and lib.state()["null"] == "library"
    # three pairs: log z = log 1e-12, 0, 0 -> mean far below mu_same 0: clipped to 0
    assert scene.null_mean() == 0.0
    # mu_diff = mu_same: every ratio is 1, no evidence at all
    assert scene.evalues.tolist() == [1.0, 1.0, 1.0]
    assert lib.evalues[0] == pytest.approx(math.sqrt(2.0) * math.exp(0.5), rel=1e-12)
    st = scene.state()
    assert st["null"] == "scene" and st["null_mean_log_z"] == 0.0


def test_scene_null_waits_for_three_pairs_and_never_exceeds_the_model():
    e = EProcess(3, UNIT, alpha=0.2, null="scene")
    far = EvidenceModel(mu_same=0.0, sd_same=1.0, mu_diff=0.5, sd_diff=1.0)
    f = EProcess(3, far, alpha=0.2, null="scene")
    samples: list[list[np.ndarray]] = [[], [], [], []]
    for p, x in ((1, [0.0, 0.0]), (2, [0.0, 2.0 * math.e])):   # one pair
        v = np.asarray(x, float)
        e.add_touch(p, v, [list(s) for s in samples])
        f.add_touch(p, v, [list(s) for s in samples])
        samples[p].append(v)
    assert e.null_mean() == 1.0           # fewer than SCENE_NULL_MIN_PAIRS: the model's
    v = np.asarray([2.0 * math.e, 0.0])
    e.add_touch(3, v, [list(s) for s in samples])
    f.add_touch(3, v, [list(s) for s in samples])
    # three pairs, z = ||a - b|| / sqrt2: log z = 1 + log(2) / 2 (c1-c2, c1-c3), 1 + log 2
    # (c2-c3): their mean is above both models' mu_diff
    assert e.null_mean() == 1.0 and f.null_mean() == 0.5   # the model's, the closer one
    with pytest.raises(InputError, match="stop_null"):
        EProcess(3, UNIT, alpha=0.2, null="pooled")


@pytest.mark.parametrize("setting, named", [
    ("trial.stop_rule=bayes", "'threshold' or 'evalue'"),
    ("trial.stop_alpha=0.7", "stop_alpha"),
    ("trial.stop_alpha=0", "stop_alpha"),
    ("trial.stop_null=pooled", "'library' or 'scene'"),
])
def test_cli_refuses_bad_stop_settings(setting: str, named: str, capsys, tmp_path) -> None:
    from tactex_ros.cli.main import main
    assert main(["trial", "--source", "sim", "--set", setting,
                 "--record-dir", str(tmp_path)]) == 2
    assert named in capsys.readouterr().err
    assert not any(tmp_path.iterdir())            # refused before anything ran


def test_cli_evalue_trial_records_the_bound(capsys, tmp_path) -> None:
    import json

    from tactex_ros.cli.main import main
    assert main(["trial", "--source", "sim", "--comparisons", "3", "--seed", "3", "--set",
                 "trial.stop_rule=evalue", "--record-dir", str(tmp_path), "--quiet"]) == 0
    (res,) = [json.loads(p.read_text()) for p in tmp_path.glob("*/result.json")]
    b = res["bound"]
    assert b["rule"] == "evalue" and b["alpha"] == 0.03 and len(b["evalues"]) == 3
    assert res["sure"] == (sum(e >= b["threshold"] for e in b["evalues"]) == 1)
    assert all(r["evalues"] is not None for r in res["rounds"] + [res["final"]])
    from tactex_ros.trial.report import write_trial_report
    (folder,) = [p.parent for p in tmp_path.glob("*/result.json")]
    html = write_trial_report(folder).read_text()
    assert "id='stop-bound'" in html and f"{max(b['evalues']):.3g}" in html


def test_fit_over_spaces_pairs_only_within_a_space():
    """Two spaces far apart: the null takes only pairs of classes of one space, so it equals
    the fit of each space's pairs pooled, and cross-space distances never enter."""
    a = {"a": np.array([[0.0], [1.0]]), "b": np.array([[3.0]])}
    b = {"c": np.array([[100.0], [102.0]]), "d": np.array([[104.0]])}
    m = fit_evidence([a, b])
    same = np.log(np.array([1.0, 2.0]) / math.sqrt(2.0))
    diff = np.log(np.array([3.0, 2.0, 4.0, 2.0]) / math.sqrt(2.0))
    assert m.mu_same == pytest.approx(same.mean(), abs=1e-12)
    assert m.mu_diff == pytest.approx(diff.mean(), abs=1e-12)
    assert m.sd_same == pytest.approx(max(same.std(), diff.std()), abs=1e-12)


def test_prepare_fits_the_evidence_in_its_space_and_an_evalue_trial_uses_it(tmp_path):
    """`tactex prepare` keeps an evidence model fitted on class folds described by
    representations of the other folds; the representation file carries it, an e-value trial
    with that file stops on it, and a file without one is refused by name."""
    from tactex_ros.core import representation
    from tactex_ros.core.descriptor import descriptor_size
    from tactex_ros.core.preparation import PrepareSettings, heldout_evidence, prepare
    cfg = preset("descriptor", guards=False)
    d = descriptor_size(cfg)
    rng = np.random.default_rng(3)
    lib = {f"k{i}": rng.normal(rng.normal(0, 1, d), 0.2, size=(4, d)) for i in range(9)}
    s = PrepareSettings()
    rep = prepare(lib, s, cfg, seed=1)
    from functools import partial
    fit = partial(representation.fit, shrink=s.shrink, kind=s.kind, dims=s.dims)
    assert rep.evidence == heldout_evidence(lib, fit, s.calibration_folds, 1).to_dict()
    assert heldout_evidence({k: lib[k] for k in ("k0", "k1", "k2")}, fit, 3, 1) is None
    m = EvidenceModel.from_dict(rep.evidence)
    assert m.mu_same < m.mu_diff
    path = representation.save(rep, tmp_path / "rep.npz")
    assert representation.load(path).evidence == rep.evidence
    tc = trial_preset("default", rounds=6, stop_rule="evalue", stop_alpha=0.03)
    eng = TrialEngine(3, cfg.replace(representation=str(path)), tc)
    assert eng.eprocess is not None and eng.eprocess.model == m
    rep.evidence = {}
    old = representation.save(rep, tmp_path / "old.npz")
    with pytest.raises(InputError, match="holds no evidence model"):
        TrialEngine(3, cfg.replace(representation=str(old)), tc)
