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
    theirs = belief_curves(scenes, [parse_setting("d=default:learner.descriptor_height_map=false")],
                           f"replay:{small_library}", 5, 4, "t", quiet=True)["d"]
    for a, b in zip(mine, theirs):
        assert a.extra == b.extra and a.correct == b.correct
        np.testing.assert_allclose(a.conf, b.conf, rtol=1e-9)


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
             "grow": rng.normal(size=(5, pf.GROWTH_DIM))}
    sizes = {k: f(cache).shape[1] for k, f in press_cache.FEATURES.items()}
    fb, hm, gr = pf.FB_DIM, pf.HM_DIM, pf.GROWTH_DIM
    assert sizes == {"frame": 106, "frames4": 106, "growth": 212, "regions": 212,
                     "frame_regstd": 212, "fb": fb, "hm": hm, "fb_hm": fb + hm,
                     "frame_fb": 106 + fb, "frame_hm": 106 + hm, "frame_grow": 106 + gr,
                     "frames4_fb": 106 + fb, "frames4_hm": 106 + hm, "frames4_grow": 106 + gr,
                     "frames4_all": 106 + fb + hm + gr}
    np.testing.assert_allclose(press_cache.FEATURES["frames4"](cache)[0],
                               np.mean([cache["f0"][0], *cache["extra"][0]], axis=0))
