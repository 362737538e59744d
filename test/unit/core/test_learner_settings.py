"""Per-learner settings (a discriminated union on ``model``), the one override syntax (dotted
schema paths) and a round's learner-typed detail: exact values, refusals naming the field."""

from __future__ import annotations

import json
import math
import re

import pytest

from tactex_ros.core.config import (AutoSettings, CnnSettings, DescriptorSettings, LadderSettings,
                                    TrialConfig, TrialSettings, learner_class, learner_settings,
                                    preset)
from tactex_ros.core.schema import fields, nearest, overrides
from tactex_ros.core.engine import (RoundRecord, TrainingDetail, TrialOutcome, TrialSpec,
                                    training_of)
from tactex_ros.core.errors import InputError
from tactex_ros.core.learners import TrainStats


def test_each_learner_has_its_own_fields_and_shipped_defaults() -> None:
    d = DescriptorSettings()
    assert d.model_dump() == {
        "model": "descriptor", "guards": True, "contact_flat_min": 0.35, "contact_min": 0.8,
        "descriptor_frames": 1, "descriptor_height_map": True, "descriptor_embedding": "sim",
        "descriptor_embedding_frames": 4, "match_prior_scale": 1.0,
        "match_prior_strength": 4.0,
        "descriptor_no_contact": True, "representation": "", "representation_temperature": True,
        "match_units": "scene", "match_temperature": 0.0251, "contact_region_min": 0.0,
        "fabric_library": True}
    assert learner_settings({}) == d == TrialSettings().learner == preset("default")
    c = CnnSettings()
    assert (c.model, c.input_size, c.epochs, c.lr, c.mc_passes, c.guards) == \
        ("small_inception", 299, 10, 1e-3, 20, True)
    assert not hasattr(d, "lr") and not hasattr(c, "match_temperature")
    a = AutoSettings()
    assert set(a.model_dump()) - set(c.model_dump()) == {
        "auto_ladder", "auto_patience", "auto_min_drop", "auto_entropy", "auto_window",
        "auto_heldout_acc", "auto_catchup"}
    assert a.model == "cnn_auto"
    lad = LadderSettings()
    assert set(lad.model_dump()) - set(d.model_dump()) == {
        "ladder", "ladder_patience", "ladder_min_gain", "ladder_sure", "ladder_margin",
        "ladder_window", "ladder_heldout_acc", "ladder_catchup", "threads", "device"}
    assert {k: v for k, v in lad.model_dump().items() if k in DescriptorSettings.model_fields} == \
        {**d.model_dump(), "model": "auto"}
    assert [learner_class(m).__name__ for m in ("descriptor", "inception_v3", "cnn_auto",
                                                "auto")] == \
        ["DescriptorSettings", "CnnSettings", "AutoSettings", "LadderSettings"]
    assert type(preset("cnn")) is CnnSettings and type(preset("seed_faithful")) is CnnSettings


@pytest.mark.parametrize("data, message", [
    ({"learner": {"lr": 0.1}},
     "tactex trial: learner.lr: unknown name for a descriptor learner; known: model, guards, "
     "contact_flat_min, contact_min, descriptor_frames,"),
    ({"config": "cnn", "learner": {"match_temperature": 0.1}},
     "tactex trial: learner.match_temperature: unknown name for a cnn learner; known: model,"),
    ({"config": "cnn", "learner": {"auto_patience": 3}},
     "tactex trial: learner.auto_patience: unknown name for a cnn learner"),
    ({"learner": {"model": "vgg"}},
     "tactex trial: learner.model: Input should be 'descriptor', 'small_inception', "
     "'inception_v3', 'inception_v3_random', 'cnn_auto' or 'auto' (got 'vgg')"),
    ({"config": "cnn", "learner": {"input_size": 4}},
     "tactex trial: learner.input_size: Input should be greater than or equal to 32 (got 4)"),
])
def test_a_field_the_learner_lacks_is_refused_by_name(data: dict, message: str) -> None:
    with pytest.raises(InputError, match="^" + re.escape(message)):
        TrialSettings.check(data, "tactex trial")


def test_a_preset_gives_way_to_another_family_and_round_trips() -> None:
    # the preset's CNN values are left out when the model given is the descriptor ...
    s = TrialSettings.check({"config": "seed_faithful", "learner": {"model": "descriptor"}})
    assert s.learner == DescriptorSettings() and s.trial.strategy == "variance"
    # ... and kept where the family has them (cnn_auto is a CNN ladder)
    a = TrialSettings.check({"config": "cnn", "learner": {"model": "cnn_auto"}}).learner
    assert type(a) is AutoSettings and (a.input_size, a.steps, a.lr) == (48, 8, 3e-3)
    # a model dump validates back to the same settings (the explorer's config.json)
    for name in ("default", "cnn", "seed_faithful"):
        s = TrialSettings.check({"config": name})
        back = TrialSettings.check(json.loads(json.dumps(s.model_dump())))
        assert back == s and type(back.learner) is type(s.learner)
    # the ladder 'auto' has the descriptor's settings, not the CNN preset's
    lad = TrialSettings.check({"config": "cnn", "learner": {"model": "auto"}}).learner
    assert type(lad) is LadderSettings and not hasattr(lad, "lr")
    # cnn_auto's stages: the CNN settings with cnn_auto's values, the ladder fields left out
    stage = a.as_model("inception_v3_random", input_size=96)
    assert type(stage) is CnnSettings and (stage.model, stage.input_size, stage.lr) == \
        ("inception_v3_random", 96, 3e-3)
    with pytest.raises(InputError, match="^configuration 'default': lr: unknown name for a "
                                         "descriptor learner"):
        preset("default", lr=0.1)


def test_fields_of_the_union() -> None:
    every = {s.name: s for s in fields(TrialSettings)}
    assert every["learner.model"].tag and every["learner.model"].read_only
    assert every["learner.model"].choices == ("descriptor", "small_inception", "inception_v3",
                                              "inception_v3_random", "cnn_auto", "auto")
    assert every["learner.guards"].learners == ()
    assert every["learner.lr"].learners == ("cnn", "cnn_auto")
    assert every["learner.auto_patience"].learners == ("cnn_auto",)
    assert every["learner.ladder_patience"].learners == ("auto",)
    assert every["learner.match_temperature"].learners == ("descriptor", "auto")
    descriptor = [s.name for s in fields(TrialSettings, values={"learner": {"model":
                                                                           "descriptor"}})]
    assert [n for n in descriptor if n.startswith("learner.")] == [
        "learner.model", "learner.guards", "learner.contact_flat_min", "learner.contact_min",
        "learner.descriptor_frames", "learner.descriptor_height_map",
        "learner.descriptor_embedding", "learner.descriptor_embedding_frames",
        "learner.match_prior_scale",
        "learner.match_prior_strength", "learner.descriptor_no_contact", "learner.representation",
        "learner.representation_temperature", "learner.match_units",
        "learner.match_temperature", "learner.contact_region_min", "learner.fabric_library"]
    cnn = {s.name for s in fields(TrialSettings, values={"learner": {"model": "inception_v3"}})}
    assert "learner.lr" in cnn and "learner.auto_patience" not in cnn
    assert "learner.match_temperature" not in cnn and "learner.contact_region_min" not in cnn


def test_overrides_are_dotted_schema_paths_typed_by_the_schema() -> None:
    assert overrides(TrialSettings, ["learner.lr=1e-3", "trial.strategy=infogain",
                                     "learner.guards=false", "trial.rounds=7",
                                     "learner.model=auto", "config=cnn"]) == {
        "learner": {"lr": 0.001, "guards": False, "model": "auto"},
        "trial": {"strategy": "infogain", "rounds": 7}, "config": "cnn"}
    assert overrides(TrialSettings, ["trial.rounds=3", "trial.rounds=4"]) == \
        {"trial": {"rounds": 4}}                                   # a later item wins
    assert overrides(TrialSettings, None) == {}
    given = overrides(TrialSettings, ["learner.match_temperature=0.1"])
    assert TrialSettings.check(given).learner.match_temperature == 0.1


@pytest.mark.parametrize("item, message", [
    ("lr=1e-3", "--set 'lr=1e-3': unknown setting 'lr'; nearest valid: 'learner.lr'"),
    ("learner.lrr=1", "--set 'learner.lrr=1': unknown setting 'learner.lrr'; nearest valid: "
                      "'learner.lr'"),
    ("trial.stratgy=random", "--set 'trial.stratgy=random': unknown setting 'trial.stratgy'; "
                             "nearest valid: 'trial.strategy'"),
    ("learner.lr", "--set 'learner.lr': expected PATH=VALUE, e.g. learner.lr=1e-3"),
    ("learner.lr=abc", "--set 'learner.lr=abc': Input should be a valid number, unable to "
                       "parse string as a number (got 'abc')"),
    ("trial.rounds=2.5", "--set 'trial.rounds=2.5': Input should be a valid integer, unable to "
                         "parse string as an integer (got '2.5')"),
    ("trial.rounds=5000", "--set 'trial.rounds=5000': Input should be less than or equal to "
                          "1000 (got '5000')"),
    ("learner.guards=maybe", "--set 'learner.guards=maybe': Input should be a valid boolean, "
                             "unable to interpret input (got 'maybe')"),
    ("learner.model=vgg", "--set 'learner.model=vgg': Input should be 'descriptor', "
                          "'small_inception', 'inception_v3', 'inception_v3_random', 'cnn_auto' "
                          "or 'auto' "
                          "(got 'vgg')"),
])
def test_overrides_refuse_bad_items(item: str, message: str) -> None:
    with pytest.raises(InputError, match="^" + re.escape(message) + "$"):
        overrides(TrialSettings, [item])


def test_nearest() -> None:
    known = ["learner.lr", "learner.model", "trial.rounds", "trial.strategy"]
    assert nearest("lr", known) == "learner.lr"
    assert nearest("trial.round", known) == "trial.rounds"
    assert nearest("rounds", known) == "trial.rounds"


def _record(detail: TrainingDetail | None) -> RoundRecord:
    return RoundRecord(round=1, platform=2, probs=[0.25, 0.75], scores=[0.1, 0.2],
                       predictive_entropy=0.5, score_s=0.25, choose_s=0.125, touches=[1, 1],
                       model="descriptor" if detail is None else "small_inception",
                       detail=detail)


def test_a_round_keeps_common_fields_and_its_learners_detail() -> None:
    plain = _record(None)
    assert (plain.train_s, plain.decision_s, plain.model_label) == (0.0, 0.375, "descriptor")
    stats = TrainStats(seconds=2.0, steps=8, mean_loss=0.5, skipped=1, grad_norm=3.0,
                       restored=True, escalation="entropy: 0.9 > 0.2")
    trained = _record(TrainingDetail.of(stats, input_size=48))
    assert trained.detail == TrainingDetail(input_size=48, train_s=2.0, train_loss=0.5,
                                            skipped_steps=1, restored=True, grad_norm=3.0,
                                            escalation="entropy: 0.9 > 0.2")
    assert (trained.train_s, trained.decision_s, trained.model_label) == \
        (2.0, 2.375, "small_inception@48")
    out = TrialOutcome(prediction=2, truth=2, touches=3, rounds=[trained], final=plain)
    d = out.to_dict()
    assert d["rounds"][0]["detail"] == {
        "input_size": 48, "train_s": 2.0, "train_loss": 0.5, "skipped_steps": 1,
        "restored": True, "grad_norm": 3.0, "escalation": "entropy: 0.9 > 0.2",
        "kind": "training"}
    assert d["final"]["detail"] is None and "train_loss" not in d["final"]
    assert d["models"] == ["descriptor", "small_inception@48"]
    assert d["escalations"] == [{"round": 1, "reason": "entropy: 0.9 > 0.2",
                                 "model": "small_inception@48"}]
    assert training_of(d["rounds"][0])["train_loss"] == 0.5 and training_of(d["final"]) == {}
    # the flat shape of files written before the detail existed
    old = {"model": "small_inception", "train_loss": 0.25, "input_size": 64, "train_s": 1.0,
           "skipped_steps": 0, "restored": False, "grad_norm": 2.0, "escalation": None}
    assert training_of(old) == {"input_size": 64, "train_s": 1.0, "train_loss": 0.25,
                                "skipped_steps": 0, "restored": False, "grad_norm": 2.0,
                                "escalation": None}
    assert training_of({"model": "descriptor", "train_loss": None, "input_size": 299}) == {}


def test_the_descriptor_trains_nothing_in_a_trial() -> None:
    import numpy as np
    rng = np.random.default_rng(0)
    frames = [rng.integers(0, 255, (240, 320, 3), dtype=np.uint8) for _ in range(4)]
    spec = TrialSpec(3, DescriptorSettings(guards=False),
                     TrialSettings.check({"trial": {"rounds": 2,
                                                    "stop_confidence": 0.0}}).trial)
    eng = spec.engine()
    assert not hasattr(eng.learner, "train_round")
    res = eng.run(lambda p: frames[p], truth=1)
    assert [r.detail for r in res.rounds + [res.final]] == [None, None, None]
    assert all(r.train_s == 0.0 for r in res.rounds + [res.final])


def test_resume_reads_a_record_with_the_flat_learner_dump(tmp_path) -> None:
    from tactex_ros.trial.resume import check_settings
    now = TrialSettings.check({})
    old = {**now.learner.model_dump(), "input_size": 299, "lr": 0.001, "epochs": 10}
    (tmp_path / "config.json").write_text(json.dumps(
        {"learner": old, "trial": now.trial.model_dump()}))
    check_settings(tmp_path, {"learner": now.learner.model_dump(),
                              "trial": now.trial.model_dump()})          # accepted
    changed = now.learner.replace(match_temperature=0.1).model_dump()
    with pytest.raises(InputError, match=r"^resume: learner.match_temperature is 0.1 now but "
                                         r"0.0251 in the record"):
        check_settings(tmp_path, {"learner": changed, "trial": now.trial.model_dump()})


def test_tactex_trial_set(tmp_path, capsys) -> None:
    from tactex_ros.cli.main import main
    assert main(["trial", "--source", "sim", "--set", "learner.lr=0.1", "--quiet"]) == 2
    assert "learner.lr: unknown name for a descriptor learner" in capsys.readouterr().err
    assert main(["trial", "--source", "sim", "--set", "trial.round=1", "--quiet"]) == 2
    assert "nearest valid: 'trial.rounds'" in capsys.readouterr().err
    out = tmp_path / "t.json"
    assert main(["trial", "--source", "sim", "--rounds", "5", "--set", "trial.rounds=1",
                 "--set", "trial.stop_confidence=0", "--quiet", "--json", str(out)]) == 0
    d = json.loads(out.read_text())
    assert (len(d["rounds"]), d["stop_reason"], d["final"]["detail"]) == (1, "rounds", None)


def test_round_record_with_a_training_detail_survives_its_checkpoint_form() -> None:
    """A CNN round written into checkpoint.json (``asdict``, strict JSON) reads back equal;
    a detail of an unknown kind is refused."""
    from dataclasses import asdict

    from tactex_ros.core.engine import RoundRecord, TrainingDetail, _round_record
    from tactex_ros.core.outputs import dumps

    rec = RoundRecord(round=2, platform=3, probs=[0.1, 0.2, 0.6, 0.1], scores=None,
                      predictive_entropy=1.1, score_s=0.01, choose_s=0.002,
                      touches=[1, 1, 2, 1], model="small_inception",
                      detail=TrainingDetail(input_size=32, train_s=0.5, train_loss=0.7,
                                            grad_norm=2.5, escalation="held-back touches"))
    back = _round_record(json.loads(dumps(asdict(rec))))
    assert back.detail == rec.detail and back.train_s == 0.5 and back.probs == rec.probs
    assert math.isnan(back.cpu_s)
    bad = asdict(rec)
    bad["detail"]["kind"] = "other"
    with pytest.raises(InputError, match="detail kind"):
        _round_record(bad)


def test_a_reference_scoring_strategy_needs_a_learner_that_scores_the_reference():
    """infogain scores the reference too: the learners whose settings say they can
    (``scores_reference``: descriptor, auto) run it; a CNN's settings are refused before any
    learner is built (no torch)."""
    from tactex_ros.core.engine import TrialEngine
    trial = TrialConfig(strategy="infogain")
    assert [c.scores_reference for c in (DescriptorSettings, CnnSettings, AutoSettings,
                                         LadderSettings)] == [True, False, False, True]
    for model in ("small_inception", "cnn_auto"):
        with pytest.raises(InputError, match="strategy 'infogain'"):
            TrialEngine(4, preset("default", model=model), trial)
    assert TrialEngine(4, preset("default", model="auto"), trial).learner.rungs[0] == "descriptor"
