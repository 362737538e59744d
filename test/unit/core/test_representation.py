"""Prepared representation: fit on a library, file round trip, refusal of bad files, and the
`tactex prepare` -> `tactex trial --representation` path on real presses built at test time."""

import json

import numpy as np
import pytest

from tactex_ros.cli.main import main
from tactex_ros.core import representation as rp
from tactex_ros.core.errors import InputError
from tactex_ros.core.config import TrialConfig, preset
from tactex_ros.core.descriptor import DescriptorLearner
from tactex_ros.core.engine import TrialSpec, run_trial
from tactex_ros.core.texture import DIM, descriptor_dim
from tactex_ros.core.touch import Touch


def _library(rng, noisy_dims=(0, 1)):
    """Classes differ in every dimension by ~1; dims ``noisy_dims`` vary 10x more within a
    class than the others."""
    out = {}
    for c in range(6):
        centre = rng.normal(0, 1.0, DIM)
        x = centre + rng.normal(0, 0.1, (5, DIM))
        x[:, list(noisy_dims)] += rng.normal(0, 1.0, (5, len(noisy_dims)))
        out[f"k{c}"] = x
    return out


def test_fit_downweights_dimensions_that_vary_within_a_class(tmp_path):
    rep = rp.fit(_library(np.random.default_rng(0)), shrink=0.01)
    w = np.abs(np.diag(rep.whiten))
    assert w[:2].max() < 0.5 * np.median(w[2:])
    path = rp.save(rep, tmp_path / "r.npz")
    back = rp.load(path)
    np.testing.assert_allclose(back.whiten, rep.whiten)
    x = np.random.default_rng(1).normal(size=(3, DIM))
    np.testing.assert_allclose(back.apply(x), ((x - rep.mean) / rep.std) @ rep.whiten.T)
    assert (back.classes, back.presses) == (6, 30)


def test_the_file_records_its_descriptor_and_the_learner_checks_it(tmp_path):
    rep = rp.load(rp.save(rp.fit(_library(np.random.default_rng(0))), tmp_path / "r.npz"))
    assert rep.descriptor_dim == DIM == descriptor_dim(False)
    rep.check_descriptor(False, "r.npz")
    with pytest.raises(InputError, match="learner.descriptor_height_map=false"):
        rep.check_descriptor(True, "r.npz")
    with pytest.raises(InputError, match="learner.descriptor_height_map=false"):
        DescriptorLearner(2, preset("descriptor", representation=str(tmp_path / "r.npz")))
    np.savez(tmp_path / "lie.npz", format=np.array(rp.FORMAT), mean=rep.mean, std=rep.std,
             whiten=rep.whiten, descriptor_dim=np.array(descriptor_dim(True)))
    with pytest.raises(InputError, match="do not fit"):
        rp.load(tmp_path / "lie.npz")


def test_the_file_records_its_frames_and_the_learner_checks_them(tmp_path):
    rep = rp.fit(_library(np.random.default_rng(0)))
    assert rep.frames == 0
    rep.frames = 4
    back = rp.load(rp.save(rep, tmp_path / "f4.npz"))
    assert back.frames == 4
    back.check_descriptor(False, "f4.npz", 4)
    with pytest.raises(InputError, match="learner.descriptor_frames=1"):
        back.check_descriptor(False, "f4.npz", 1)
    with pytest.raises(InputError, match="learner.descriptor_frames=1"):
        DescriptorLearner(2, preset("descriptor", representation=str(tmp_path / "f4.npz"),
                                    descriptor_height_map=False))
    DescriptorLearner(2, preset("descriptor", representation=str(tmp_path / "f4.npz"),
                                descriptor_height_map=False, descriptor_frames=4))
    # an older file without the field: not recorded, any frame count
    old = {k: v for k, v in np.load(tmp_path / "f4.npz").items() if k != "descriptor_frames"}
    np.savez(tmp_path / "old.npz", **old)
    assert rp.load(tmp_path / "old.npz").frames == 0
    rp.load(tmp_path / "old.npz").check_descriptor(False, "old.npz", 3)
    np.savez(tmp_path / "bad.npz", **dict(old, descriptor_frames=np.array(-1)))
    with pytest.raises(InputError, match="descriptor_frames"):
        rp.load(tmp_path / "bad.npz")


def test_bad_representation_files_are_refused_by_name(tmp_path):
    with pytest.raises(InputError, match="not found"):
        rp.load(tmp_path / "missing.npz")
    (tmp_path / "junk.npz").write_bytes(b"not an npz file")
    with pytest.raises(InputError, match="not loadable"):
        rp.load(tmp_path / "junk.npz")
    np.savez(tmp_path / "other.npz", format=np.array("other"))
    with pytest.raises(InputError, match="not a tactex-representation"):
        rp.load(tmp_path / "other.npz")
    np.savez(tmp_path / "small.npz", format=np.array(rp.FORMAT), mean=np.zeros(3),
             std=np.ones(3), whiten=np.eye(3))
    with pytest.raises(InputError, match="do not fit"):
        rp.load(tmp_path / "small.npz")
    rep = rp.fit(_library(np.random.default_rng(0)))
    rep.temperature = -1.0
    rp.save(rep, tmp_path / "neg.npz")
    with pytest.raises(InputError, match="temperature"):
        rp.load(tmp_path / "neg.npz")
    with pytest.raises(InputError, match="at least 2"):
        rp.fit({"a": np.zeros((3, DIM)), "b": np.zeros((1, DIM))})
    with pytest.raises(InputError, match="kind"):
        rp.fit(_library(np.random.default_rng(0)), kind="pca")


def test_lda_keeps_the_directions_the_classes_differ_in(tmp_path):
    """Classes differ only along dims 0..2; the rest is within-class noise. The 3 LDA
    directions then lie mostly inside dims 0..2, and the file keeps the map and temperature."""
    rng = np.random.default_rng(3)
    lib = {}
    for c in range(10):
        centre = np.zeros(DIM)
        centre[:3] = rng.normal(0, 3.0, 3)
        lib[f"k{c}"] = centre + rng.normal(0, 1.0, (40, DIM))
    rep = rp.fit(lib, kind="lda", dims=3)
    assert rep.whiten.shape == (3, DIM) and rep.dims == 3 and rep.kind == "lda"
    w = rep.whiten / np.linalg.norm(rep.whiten, axis=1, keepdims=True)
    share = (w[:, :3] ** 2).sum(axis=1)          # of each direction's weight on dims 0..2
    np.testing.assert_allclose(share, [0.9369, 0.8748, 0.7304], atol=1e-3)
    x = rng.normal(size=(4, DIM))
    assert rep.apply(x).shape == (4, 3)
    rep.temperature, rep.calibration = 0.25, {"trials": 7}
    back = rp.load(rp.save(rep, tmp_path / "lda.npz"))
    np.testing.assert_allclose(back.apply(x), rep.apply(x))
    assert (back.kind, back.temperature, back.calibration) == ("lda", 0.25, {"trials": 7})
    # more dims than the class means span are clipped to classes - 1
    assert rp.fit(lib, kind="lda", dims=40).dims == 9
    # kind none: the identity
    ident = rp.fit(lib, kind="none")
    np.testing.assert_allclose(ident.apply(x), x)


@pytest.mark.slow
def test_prepare_then_trial_with_the_file(octopi_dir, tmp_path):
    lib = tmp_path / "lib"
    for cls in ("rice", "millet", "sponge"):
        (lib / cls).mkdir(parents=True)
        for f in sorted((octopi_dir / cls).glob("*.mov"))[:2]:
            (lib / cls / f.name).symlink_to(f)
    out = tmp_path / "rep.npz"
    assert main(["prepare", "--library", f"replay:{lib}", "--out", str(out), "--kind",
                 "whiten", "--calibration", "off"]) == 0
    assert rp.load(out).presses == 6
    js = tmp_path / "t.json"
    assert main(["trial", "--source", f"replay:{octopi_dir}", "--classes",
                 "basket,tissue,wires", "--reference", "tissue", "--seed", "1",
                 "--representation", str(out), "--json", str(js), "--quiet"]) == 0
    d = json.loads(js.read_text())
    assert d["model"] == "descriptor" and d["truth"] == "c2"
    assert main(["trial", "--source", f"replay:{octopi_dir}", "--representation",
                 str(tmp_path / "nope.npz")]) == 2
    # the default describes with the height map and the shipped embedding
    assert rp.load(out).descriptor_dim == descriptor_dim(True) + 128
    # a file prepared on the other descriptor: refused (exit 2) unless the setting follows it
    old = tmp_path / "old.npz"
    assert main(["prepare", "--library", f"replay:{lib}", "--out", str(old), "--kind",
                 "whiten", "--calibration", "off", "--height-map", "off",
                 "--embedding", "none"]) == 0
    assert rp.load(old).descriptor_dim == descriptor_dim(False)
    trial = ["trial", "--source", f"replay:{octopi_dir}", "--classes", "basket,tissue,wires",
             "--reference", "tissue", "--seed", "1", "--representation", str(old), "--quiet"]
    assert main(trial) == 2
    assert main(trial + ["--set", "learner.descriptor_height_map=false"]) == 2   # embedding
    assert main(trial + ["--set", "learner.descriptor_height_map=false",
                         "--set", "learner.descriptor_embedding="]) == 0
    # prepared from 4 frames per press: recorded; a 1-frame learner refused (exit 2)
    f4 = tmp_path / "f4.npz"
    assert main(["prepare", "--library", f"replay:{lib}", "--out", str(f4), "--kind",
                 "whiten", "--calibration", "off", "--frames", "4"]) == 0
    assert (rp.load(f4).frames, rp.load(out).frames) == (4, 1)
    trial4 = trial[:-3] + ["--representation", str(f4), "--quiet"]
    assert main(trial4) == 2
    assert main(trial4 + ["--set", "learner.descriptor_frames=4"]) == 0


@pytest.mark.slow
def test_prepare_skips_a_press_the_contact_guard_rejects(octopi_dir, tmp_path, capsys,
                                                         held_press):
    """A library press without contact (a real press's first frame, held) is left out of the
    representation, as a trial's contact guard refuses it on the robot; the real presses stay."""
    lib = tmp_path / "lib"
    for cls in ("rice", "millet", "sponge"):
        (lib / cls).mkdir(parents=True)
        for f in sorted((octopi_dir / cls).glob("*.mov"))[:2]:
            (lib / cls / f.name).symlink_to(f)
    held_press(lib / "rice" / "held.avi", "rice")
    out = tmp_path / "rep.npz"
    assert main(["prepare", "--library", f"replay:{lib}", "--out", str(out), "--kind",
                 "whiten", "--calibration", "off", "--embedding", "none"]) == 0
    assert rp.load(out).presses == 6 and rp.load(out).classes == 3
    assert "held.avi" in capsys.readouterr().err


@pytest.mark.slow
def test_a_replayed_trial_presses_again_where_a_recording_has_no_contact(octopi_dir, tmp_path,
                                                                         held_press):
    """`tactex trial --source replay:DIR` judges every press against its own no-contact frame
    (recordings of separate sessions): a held frame of another class's press is refused and
    pressed again (a failed touch in the result), as the robot refuses a press without contact.
    """
    lib = tmp_path / "lib"
    for cls in ("rice", "millet", "sponge"):
        (lib / cls).mkdir(parents=True)
        for f in sorted((octopi_dir / cls).glob("*.mov"))[:2]:
            (lib / cls / f.name).symlink_to(f)
    held_press(lib / "millet" / "held.avi", "tissue")
    refused = 0
    for seed in range(4):
        js = tmp_path / f"t{seed}.json"
        assert main(["trial", "--source", f"replay:{lib}", "--classes", "rice,millet,sponge",
                     "--reference", "millet", "--seed", str(seed), "--set",
                     "trial.rounds=4", "--set", "trial.stop_confidence=1.0", "--json", str(js),
                     "--quiet"]) == 0
        d = json.loads(js.read_text())
        refused += sum("no contact" in f["reason"] for f in d["failed_touches"])
        assert all("no contact" in f["reason"] for f in d["failed_touches"])
    assert refused >= 1


@pytest.mark.slow
def test_prepare_calibrates_the_temperature_with_classes_left_out(octopi_dir, tmp_path):
    """`tactex prepare --calibration target` on 12 real classes (2 presses each): the file holds
    a temperature and what the left-out trials measured; a trial uses it."""
    lib = tmp_path / "lib"
    classes = sorted(p.name for p in octopi_dir.iterdir() if p.is_dir())[:12]
    for cls in classes:
        (lib / cls).mkdir(parents=True)
        for f in sorted((octopi_dir / cls).glob("*.mov"))[:2]:
            (lib / cls / f.name).symlink_to(f)
    out = tmp_path / "cal.npz"
    assert main(["prepare", "--library", f"replay:{lib}", "--out", str(out), "--calibration",
                 "target", "--calibration-scenes", "3", "--calibration-budget", "2"]) == 0
    rep = rp.load(out)
    assert rep.kind == "whiten" and np.isfinite(rep.temperature) and rep.temperature > 0
    cal = rep.calibration
    assert cal["trials"] == 9 and cal["decisions"] == 27 and cal["method"] == "target"
    assert cal["wrong_stop"]["0.9"] <= 0.03
    js = tmp_path / "t.json"
    assert main(["trial", "--source", f"replay:{octopi_dir}", "--classes",
                 "basket,tissue,wires", "--reference", "tissue", "--seed", "1",
                 "--representation", str(out), "--json", str(js), "--quiet"]) == 0
    d = json.loads(js.read_text())
    assert d["sure"] in (True, False) and 0 < d["confidence"] <= 1


def _descriptor_touches(seed: int):
    """Touches of a 1 + 3 scene that carry their (DIM,) descriptors: reference = comparison 2."""
    rng = np.random.default_rng(seed)
    centres = rng.normal(0, 1.0, (3, DIM))
    frame = rng.integers(0, 256, (240, 320, 3), dtype=np.uint8)

    def touch(p: int) -> Touch:
        c = centres[1 if p == 0 else p - 1]
        return Touch(frame, descriptor=c + rng.normal(0, 0.3, DIM))
    return touch


def test_a_representation_in_memory_runs_the_trial_its_file_runs(tmp_path):
    """``TrialSpec.representation`` (a fold's fit, never saved) gives the trial the settings'
    file gives, its calibrated temperature included; ``TrialSpec.temperature`` fixes the
    belief's temperature; a CNN learner is refused by name."""
    rep = rp.fit(_library(np.random.default_rng(0)))
    rep.temperature = 0.02
    path = rp.save(rep, tmp_path / "r.npz")
    trial = TrialConfig(rounds=4, stop_confidence=0.0)
    plain = preset("descriptor", descriptor_height_map=False, guards=False)
    by_file = run_trial(TrialSpec(3, plain.replace(representation=str(path)), trial, seed=2),
                        _descriptor_touches(5), truth=2)
    in_memory = TrialSpec(3, plain, trial, seed=2, representation=rp.load(path))
    assert in_memory.engine().learner.match.beta == 0.02
    res = run_trial(in_memory, _descriptor_touches(5), truth=2)
    assert [r.platform for r in res.rounds] == [r.platform for r in by_file.rounds]
    np.testing.assert_array_equal(res.final.probs, by_file.final.probs)
    raw = run_trial(TrialSpec(3, plain, trial, seed=2), _descriptor_touches(5), truth=2)
    assert not np.allclose(raw.final.probs, by_file.final.probs)     # the representation counts
    fixed = TrialSpec(3, plain, trial, seed=2, representation=rep, temperature=0.5)
    assert fixed.engine().learner.match.beta == 0.5
    assert TrialSpec(3, plain, trial, temperature=0.5).engine().learner.representation is None
    with pytest.raises(InputError, match="temperature must be > 0"):
        TrialSpec(3, plain, trial, temperature=0.0).engine()
    with pytest.raises(InputError, match="need model 'descriptor'"):
        TrialSpec(3, preset("cnn"), TrialConfig(strategy="variance"),
                  representation=rep).engine()


def test_the_prepare_options_are_the_preparation_schema():
    """`tactex prepare`'s options are ``PrepareSettings``'s fields, with its defaults and
    ranges (the one preparation schema the lab's ``experiment unseen`` uses too)."""
    from tactex_ros.cli.main import build_parser
    from tactex_ros.core.preparation import PrepareSettings
    base = ["prepare", "--library", "sim", "--out", "x.npz"]
    parser = build_parser("prepare", plugins=False)
    args = parser.parse_args(base)
    assert {k: getattr(args, k) for k in PrepareSettings.model_fields} == \
        PrepareSettings().model_dump()
    args = parser.parse_args(base + ["--kind", "lda", "--dims", "12", "--calibration-start",
                                     "0.5", "--max-wrong", "0.05"])
    given = PrepareSettings(**{k: getattr(args, k) for k in PrepareSettings.model_fields})
    assert (given.kind, given.dims, given.calibration_start, given.max_wrong) == \
        ("lda", 12, 0.5, 0.05)
    for bad in (["--dims", "0"], ["--kind", "pca"], ["--calibration-folds", "1"]):
        with pytest.raises(SystemExit):
            parser.parse_args(base + bad)
