"""`tactex experiment unseen`: its cached-descriptor trials are the trials `experiment real`
runs on the same presses (same scenes, same draws, same beliefs), and its settings parse."""

import numpy as np
import pytest

from tactex_ros.core.errors import InputError
from tactex_lab.analysis import press_features as pf
from tactex_ros.core.preparation import PrepareSettings
from tactex_lab.experiments import press_cache, unseen
from tactex_lab.experiments.curves import belief_curves, draw_scenes, parse_setting


@pytest.fixture(scope="module")
def small_library(octopi_dir, tmp_path_factory):
    lib = tmp_path_factory.mktemp("lib")
    for cls in ("rice", "millet", "sponge", "tissue", "basket"):
        (lib / cls).mkdir()
        for f in sorted((octopi_dir / cls).glob("*.mov"))[:3]:
            (lib / cls / f.name).symlink_to(f)
    return lib


@pytest.mark.slow
def test_cached_trials_equal_the_replayed_trials(small_library, tmp_path):
    cache = press_cache.load_cache(press_cache.build_cache(small_library, tmp_path / "c.npz"))
    assert cache["f0"].shape == (15, 106) and cache["reg"].shape == (15, 4, 106)
    assert cache["extra"].shape == (15, 3, 106) and cache["early"].shape == (15, 106)
    scenes = draw_scenes(sorted(set(cache["cls"].tolist())), 3, 3, 7)
    mine = unseen.scene_curves(unseen.Setting("d"), None, cache, scenes, seed=5, budget=4)
    # the cache's "frame" is the 106-number descriptor: replayed with the height map off
    theirs = belief_curves(scenes, [parse_setting("d=descriptor:learner.descriptor_height_map=false")],
                           f"replay:{small_library}", 5, 4, "t", quiet=True)["d"]
    for a, b in zip(mine, theirs, strict=True):
        assert a.extra == b.extra and a.correct == b.correct
        np.testing.assert_allclose(a.conf, b.conf, rtol=1e-9)


@pytest.mark.slow
def test_a_cache_is_built_once_under_the_folders_name(small_library, tmp_path):
    first = press_cache.cached(small_library, tmp_path)
    path = tmp_path / f"{small_library.name}.npz"
    made = path.stat().st_mtime_ns
    again = press_cache.cached(small_library, tmp_path)
    assert path.stat().st_mtime_ns == made            # loaded, not described again
    assert sorted(again) == sorted(first) and (again["f0"] == first["f0"]).all()
    assert not (tmp_path / f"{small_library.name}_candidates.npz").exists()
    press_cache.cached(small_library, tmp_path, rebuild=True)
    assert path.stat().st_mtime_ns > made


def test_settings_parse_and_name_what_is_wrong():
    s = unseen.Setting.parse("x=feature:regions,kind:lda,dims:12,calibration:stop")
    assert (s.label, s.feature, s.prepare.kind, s.prepare.dims, s.prepare.calibration) == (
        "x", "regions", "lda", 12, "stop")
    # the product's preparation schema; the lab states where it differs (no metric unless named)
    d = unseen.Setting.parse("d=")
    assert d.prepare == PrepareSettings(kind="none") and PrepareSettings().kind == "whiten"
    assert d.to_dict() == {"label": "d", "feature": "frame", "kind": "none", "dims": 24,
                           "calibration": "off", "shrink": 1.0}
    with pytest.raises(InputError, match="calibration"):
        unseen.Setting.parse("x=calibration:sometimes")
    with pytest.raises(InputError, match="unknown key"):
        unseen.Setting.parse("x=colour:red")
    with pytest.raises(InputError, match="feature one of"):
        unseen.Setting.parse("x=feature:nope")


def test_region_and_frame_features_have_the_documented_sizes():
    rng = np.random.default_rng(0)
    cache = {"f0": rng.normal(size=(5, 106)), "extra": rng.normal(size=(5, 3, 106)),
             "early": rng.normal(size=(5, 106)), "reg": rng.normal(size=(5, 4, 106)),
             "fb": rng.normal(size=(5, pf.FB_DIM)), "hm": rng.normal(size=(5, pf.HM_DIM)),
             "grow": rng.normal(size=(5, pf.GROWTH_DIM)), "scat": rng.normal(size=(5, 42)),
             "cnn": rng.normal(size=(5, 128)), "cnn4": rng.normal(size=(5, 128))}
    sizes = {k: f(cache).shape[1] for k, f in press_cache.FEATURES.items()}
    fb, hm, gr = pf.FB_DIM, pf.HM_DIM, pf.GROWTH_DIM
    assert sizes == {"frame": 106, "frames4": 106, "growth": 212, "regions": 212,
                     "frame_regstd": 212, "fb": fb, "hm": hm, "fb_hm": fb + hm,
                     "frame_fb": 106 + fb, "frame_hm": 106 + hm, "frame_grow": 106 + gr,
                     "frames4_fb": 106 + fb, "frames4_hm": 106 + hm, "frames4_grow": 106 + gr,
                     "frames4_all": 106 + fb + hm + gr, "scat": 42, "frame_hm_scat": 106 + hm + 42,
                     "cnn": 128, "cnn4": 128, "frame_hm_cnn": 106 + hm + 128,
                     "frames4_hm_cnn4": 106 + hm + 128, "frame_hm_cnn4": 106 + hm + 128}
    np.testing.assert_allclose(press_cache.FEATURES["frames4"](cache)[0],
                               np.mean([cache["f0"][0], *cache["extra"][0]], axis=0))


def test_a_setting_temperature_is_the_learners_or_the_families_choice():
    s = unseen.Setting.parse("t=feature:frame_hm,temperature:worst")
    fams = {"feature": "frame_hm",
            "held_out": {"octopi-dev": {"settings": {"worst": {"temperature": 0.0421}}}}}
    assert unseen.setting_temperature(s, "octopi-dev", fams) == 0.0421
    assert unseen.setting_temperature(unseen.Setting.parse("t=temperature:0.07"), "x",
                                      None) == 0.07
    assert unseen.setting_temperature(unseen.Setting("d"), "x", fams) is None
    with pytest.raises(InputError, match="held out"):
        unseen.setting_temperature(s, "octopi-objects", fams)
    with pytest.raises(InputError, match="needs --families"):
        unseen.setting_temperature(s, "octopi-dev", None)
    with pytest.raises(InputError, match="calibrated on 'frame_hm'"):   # another descriptor
        unseen.setting_temperature(unseen.Setting.parse("t=temperature:worst"), "octopi-dev",
                                   fams)
    with pytest.raises(InputError, match="calibrated on 'frame_hm'"):   # a representation
        unseen.setting_temperature(unseen.Setting.parse(
            "t=feature:frame_hm,kind:whiten,temperature:worst"), "octopi-dev", fams)
    with pytest.raises(InputError, match="give one"):
        unseen.Setting.parse("t=calibration:stop,temperature:0.05")
    for bad in ("-1", "hot"):
        with pytest.raises(InputError, match="a number > 0 or one of"):
            unseen.Setting.parse(f"t=temperature:{bad}")


def test_a_setting_temperature_reaches_the_trials_belief():
    rng = np.random.default_rng(3)
    classes = [f"k{i}" for i in range(6)]
    centre = {c: rng.normal(0, 1, 129) for c in classes}
    cls = np.repeat(classes, 4)
    cache = {"f0": np.stack([centre[c][:106] + rng.normal(0, 0.7, 106) for c in cls]),
             "hm": np.stack([centre[c][106:] + rng.normal(0, 0.7, 23) for c in cls]),
             "cls": cls}
    scenes = draw_scenes(classes, 4, 4, 1)
    run = lambda t: unseen.scene_curves(unseen.Setting("d", feature="frame_hm"), None, cache,
                                        scenes, seed=2, budget=3, temperature=t)
    default, same, sharp = run(None), run(0.05), run(0.15)
    for a, b, c in zip(default, same, sharp, strict=True):
        assert a.conf == b.conf                           # 0.05 is the preset's temperature
        # the first decision sees the same touches: a hotter temperature, a sharper belief
        assert c.conf[0] > a.conf[0]


def test_families_summaries_of_separate_held_out_runs_are_read_as_one(tmp_path):
    import json
    for held, t in (("octopi-dev", 0.04), ("octopi-objects", 0.03)):
        (tmp_path / held).mkdir()
        (tmp_path / held / "summary.json").write_text(json.dumps(
            {"feature": "frame_hm", "held_out": {held: {"settings": {"worst": {
                "temperature": t}}}}}))
    fams = unseen.read_families([str(tmp_path / "octopi-dev" / "summary.json"),
                                 str(tmp_path / "octopi-objects" / "summary.json")])
    s = unseen.Setting.parse("t=feature:frame_hm,temperature:worst")
    assert [unseen.setting_temperature(s, h, fams) for h in ("octopi-dev", "octopi-objects")] \
        == [0.04, 0.03]
    with pytest.raises(InputError, match="more than one file"):
        unseen.read_families([str(tmp_path / "octopi-dev" / "summary.json")] * 2)
    with pytest.raises(InputError, match="not a file"):
        unseen.read_families([str(tmp_path / "none.json")])


def test_a_temperature_chosen_on_the_sim_family_is_the_calibrations_target():
    """``temperature:sim_target``: the largest grid temperature whose left-out trials on the
    third family keep the wrong stops at the shipped stop <= 3 %, with the library's
    representation applied as is; a family whose presses barely vary gets a sharper one."""
    from tactex_ros.core import calibration, representation
    s = unseen.Setting.parse("t=feature:frame_hm,kind:whiten,temperature:sim_target")
    assert s.temperature == unseen.SIM_CHOICE
    assert unseen.setting_temperature(s, "octopi-dev", None) is None   # chosen per direction
    rng = np.random.default_rng(0)
    def family(noise: float) -> dict:
        cls = np.repeat([f"f{i}" for i in range(12)], 4)
        centres = rng.normal(size=(12, 129))
        x = centres[np.repeat(np.arange(12), 4)] + noise * rng.normal(size=(48, 129))
        return {"cls": cls, "f0": x[:, :106], "hm": x[:, 106:]}
    lib = family(0.5)
    rep = representation.fit(press_cache.by_class(lib, "frame_hm"))
    beta, report = unseen.sim_temperature(s, rep, family(0.5), seed=0)
    assert np.isclose(calibration.GRID, beta).any()
    assert report["wrong_stop"]["0.9"] <= unseen.SIM_GOAL
    sharp, _ = unseen.sim_temperature(s, rep, family(0.05), seed=0)
    assert sharp >= beta


def test_a_press_without_contact_is_pressed_again_and_left_out_of_the_library():
    """A cached press the contact guard rejects (``contact_ok`` False) fails when touched, the
    engine presses again (another press of the class), and the library leaves it out. Its
    vector is NaN: had the trial or the library used it, the belief would not be finite."""
    from tactex_ros.core.config import TrialConfig, preset
    from tactex_ros.core.engine import TouchFailed, TrialSpec, run_trial
    from tactex_ros.sources.replay import ReplayTrial
    rng = np.random.default_rng(3)
    cls = np.repeat(np.array(["a", "b", "c", "d", "e"]), 3)
    x = rng.normal(0, 1, (15, 106)) + np.repeat(rng.normal(0, 3, (5, 106)), 3, axis=0)
    bad = 4                                           # the second press of class "b"
    x[bad] = np.nan
    ok = np.ones(15, bool)
    ok[bad] = False
    cache = {"cls": cls, "f0": x, "contact_ok": ok}
    lib = press_cache.by_class(cache, "frame")
    assert [len(v) for v in lib.values()] == [3, 2, 3, 3, 3]
    assert np.isfinite(lib["b"]).all()
    src = press_cache.CachedPresses(x, cls, ~ok)
    with pytest.raises(TouchFailed):
        src.touch(bad)
    plat = ["b", "a", "b", "c", "d"]
    draws = ReplayTrial(src, plat, 1)
    got, failed = [], 0
    for _ in range(3):                                # every press of "b", the bad one once
        try:
            got.append(draws(0 if not got else 2).descriptor)
        except TouchFailed:
            failed += 1
    assert failed == 1 and len(got) == 2 and all(np.isfinite(g).all() for g in got)
    # a whole trial: the failed press is recorded, the belief stays finite
    cfg = preset("descriptor", guards=False, descriptor_height_map=False)
    tcfg = TrialConfig(strategy="infogain", rounds=6, stop_confidence=0.0)
    hit = False
    for seed in range(6):
        res = run_trial(TrialSpec(4, cfg, tcfg, seed=seed), ReplayTrial(src, plat, seed),
                        truth=2)
        assert np.isfinite(res.final.probs).all()
        hit |= len(res.failed_touches) > 0
    assert hit


@pytest.mark.slow
def test_contact_verdicts_are_the_guards_on_each_press(octopi_dir, tmp_path, held_press):
    """``add_contact_verdicts``: real presses pass, a press whose frames are all its first
    (no-contact) frame fails; the verdicts are kept beside the cache and reused."""
    lib = tmp_path / "lib"
    for cls in ("rice", "tissue"):
        (lib / cls).mkdir(parents=True)
        for f in sorted((octopi_dir / cls).glob("*.mov"))[:2]:
            (lib / cls / f.name).symlink_to(f)
    held_press(lib / "rice" / "held.avi", "rice")
    cache = {"path": np.array([str(p) for c in ("rice", "tissue")
                               for p in sorted((lib / c).iterdir())])}
    press_cache.add_contact_verdicts(cache, lib, tmp_path)
    assert cache["contact_ok"].tolist() == [True, True, False, True, True]
    kept = tmp_path / "lib_contact.npz"
    made = kept.stat().st_mtime_ns
    again = {"path": cache["path"]}
    press_cache.add_contact_verdicts(again, lib, tmp_path)
    assert kept.stat().st_mtime_ns == made and (again["contact_ok"] == cache["contact_ok"]).all()


@pytest.mark.slow
def test_cached_and_replayed_trials_refuse_the_same_press_without_contact(small_library,
                                                                          tmp_path, held_press):
    """With a press without contact in a class, the cached trials (its verdict in the cache)
    and the replayed trials (``contact_guard``: each touch judged against its own no-contact
    frame) press again the same way and give the same curves; without the guard the replayed
    trials differ in some scene (the bad press was drawn and counted)."""
    lib = tmp_path / "lib"
    for d in sorted(small_library.iterdir()):
        (lib / d.name).mkdir(parents=True)
        for f in sorted(d.iterdir()):
            (lib / d.name / f.name).symlink_to(f.resolve())
    held_press(lib / "rice" / "0held.avi", "rice")
    cache = press_cache.load_cache(press_cache.build_cache(lib, tmp_path / "c.npz"))
    press_cache.add_contact_verdicts(cache, lib, tmp_path)
    assert (~cache["contact_ok"]).sum() == 1
    classes = sorted(set(cache["cls"].tolist()))
    scenes = [["rice"] + s for s in (["rice", "millet", "sponge", "tissue"],
                                     ["basket", "rice", "tissue", "sponge"],
                                     ["millet", "tissue", "rice", "basket"])]
    scenes += draw_scenes(classes, 2, 3, 7)
    mine = unseen.scene_curves(unseen.Setting("d"), None, cache, scenes, seed=5, budget=4)
    setting = [parse_setting("d=descriptor:learner.descriptor_height_map=false")]
    theirs = belief_curves(scenes, setting, f"replay:{lib}", 5, 4, "t", quiet=True,
                           contact_guard=True)["d"]
    for a, b in zip(mine, theirs, strict=True):
        assert a.extra == b.extra and a.correct == b.correct
        np.testing.assert_allclose(a.conf, b.conf, rtol=1e-9)
    counted = belief_curves(scenes, setting, f"replay:{lib}", 5, 4, "t", quiet=True)["d"]
    assert any(not np.allclose(a.conf, b.conf) for a, b in zip(theirs, counted, strict=True))
