import numpy as np
import pytest

from tactex_ros.cli.main import main
from tactex_ros.core.errors import InputError
from tactex_ros.sim.fabrics import FabricParams, load_catalogue
from tactex_ros.sources.simulated import parse_difficulty
from tactex_ros.sources import open_source


@pytest.fixture(scope="module")
def src():
    return open_source("sim:medium")


def radial_spectrum(img: np.ndarray, bins: int = 24) -> np.ndarray:
    """Rotation-invariant texture statistic: log radial power spectrum of the grey image."""
    g = img.astype(np.float64).mean(axis=2)
    g = g[40:200, 80:240]
    g = g - g.mean()
    p = np.abs(np.fft.fftshift(np.fft.fft2(g))) ** 2
    yy, xx = np.indices(p.shape)
    r = np.hypot(yy - p.shape[0] / 2, xx - p.shape[1] / 2)
    edges = np.linspace(1, p.shape[0] / 2, bins + 1)
    return np.log(np.array([p[(r >= a) & (r < b)].mean() for a, b in zip(edges, edges[1:], strict=False)]))


def test_shape_dtype_and_determinism(src):
    a = src.press("denim", np.random.default_rng(3))
    b = src.press("denim", np.random.default_rng(3))
    c = src.press("denim", np.random.default_rng(4))
    assert a.shape == (240, 320, 3) and a.dtype == np.uint8
    np.testing.assert_array_equal(a, b)
    assert np.abs(a.astype(int) - c).mean() > 1.0  # every touch is a different press
    t1, t2 = src.trial(["denim", "satin"], seed=9), src.trial(["denim", "satin"], seed=9)
    a1, a2 = t1(0), t2(0)
    np.testing.assert_array_equal(a1.frame, a2.frame)
    # every simulated touch carries the session's no-contact frame, as a real sensor's does
    np.testing.assert_array_equal(a1.no_contact, a2.no_contact)
    assert a1.no_contact.shape == (240, 320, 3) and a1.no_contact.dtype == np.uint8


@pytest.mark.slow
def test_every_catalogue_fabric_renders_with_contact(src):
    assert len(src.classes) >= 25
    rng = np.random.default_rng(0)
    blank = src.renderer.no_contact(rng).astype(float)
    for name in src.classes:
        img = src.press(name, rng)
        assert img.shape == (240, 320, 3)
        # a contact frame differs from the no-contact frame by a few grey levels, like the
        # real sensor (octopi-dev: 1-5 on average), never by nothing
        assert 0.5 < np.abs(img - blank).mean() < 30, name


@pytest.mark.slow
def test_fabrics_differ_more_than_presses_and_gap_shrinks_with_difficulty():
    """between-fabric / within-fabric distance of a rotation-invariant spectrum statistic,
    both as distances between means of two presses (equal noise on both sides)."""
    ratios = {}
    for q in (0.2, 0.9, 1.0):
        s = open_source(f"sim:{q}")
        between, within = [], []
        for seed in range(10):
            names = s.draw_scene(3, seed)
            rng = np.random.default_rng(seed)
            feats = {n: [radial_spectrum(s.press(n, rng)) for _ in range(4)] for n in names}
            for n in names:
                f = feats[n]
                within.append(np.linalg.norm(np.mean(f[:2], 0) - np.mean(f[2:], 0)))
            for i in range(3):
                for j in range(i + 1, 3):
                    between.append(np.linalg.norm(np.mean(feats[names[i]][:2], 0) -
                                                  np.mean(feats[names[j]][:2], 0)))
        ratios[q] = np.mean(between) / np.mean(within)
    assert ratios[0.2] > 2.0 * ratios[1.0]          # different fabrics differ more
    assert ratios[0.2] > ratios[0.9] > ratios[1.0]  # and the gap shrinks as difficulty rises
    assert ratios[1.0] < 1.6                         # identical parameters: about press noise


def test_bad_names_and_parameters_are_named(tmp_path, src):
    with pytest.raises(InputError, match="velvet"):
        src.press("velvet", np.random.default_rng(0))
    with pytest.raises(InputError, match="pitch_mm"):
        FabricParams("plain", pitch_mm=-1.0).check()
    with pytest.raises(InputError, match="family"):
        FabricParams("lace", pitch_mm=1.0).check()
    bad = tmp_path / "f.yaml"
    bad.write_text("fabrics:\n  - {name: x, family: twill, pitch_mm: 0.3, repeat: 2}\n")
    with pytest.raises(InputError, match="repeat"):
        load_catalogue(bad)
    bad.write_text("fabrics:\n  - {name: x, family: plain, pitch_mm: 0.3, colour: red}\n")
    with pytest.raises(InputError, match="colour"):
        load_catalogue(bad)
    # errors located in the file: entry index and field
    bad.write_text("fabrics:\n  - {name: x, family: plain, pitch_mm: 0.3}\n"
                   "  - {name: y, family: plain, pitch_mm: 9.0}\n")
    with pytest.raises(InputError, match=r"fabrics\.1\.pitch_mm: .*4\.5 \(got 9\.0\)"):
        load_catalogue(bad)
    bad.write_text("fabrics:\n  - {name: x, family: plain, pitch_mm: 0.3}\n"
                   "  - {name: x, family: felt, pitch_mm: 0.3}\n")
    with pytest.raises(InputError, match=r"fabrics\.1\.name: duplicate fabric name 'x'"):
        load_catalogue(bad)
    bad.write_text("fabrics:\n  - {name: x, family: twill, pitch_mm: 0.3, repeat: 2}\n")
    with pytest.raises(InputError, match=r"fabrics\.0\.repeat: twill needs repeat >= 3"):
        load_catalogue(bad)
    with pytest.raises(InputError, match="difficulty"):
        parse_difficulty("brutal")
    assert main(["sim", "render", "--fabric", "velvet", "--out", str(tmp_path / "a.png")]) == 2
    assert main(["sim", "render", "--fabric", "denim", "--out", str(tmp_path / "a.png")]) == 0
    assert (tmp_path / "a.png").stat().st_size > 1000


def test_sim_trial_end_to_end_easy(tmp_path):
    import json
    out = tmp_path / "t.json"
    assert main(["trial", "--source", "sim:easy", "--rounds", "2", "--seed", "2",
                 "--json", str(out), "--quiet"]) == 0
    d = json.loads(out.read_text())
    assert d["truth"] in {"c1", "c2", "c3", "c4"}
    # 5 baseline touches + one per round; the default stop rule may end it before round 2
    assert d["touches"] == 5 + len(d["rounds"]) and len(d["rounds"]) <= 2
    if d["stop_reason"] == "confident":
        assert max(d["final"]["probs"]) >= 0.9
    else:
        assert d["stop_reason"] == "rounds" and len(d["rounds"]) == 2
