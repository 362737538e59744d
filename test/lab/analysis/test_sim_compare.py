"""The sim-to-real report (``tactex sim compare``): statistics, ratios, ranking agreement."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from tactex_lab.analysis import sim_vs_real as compare
from tactex_lab.analysis.stats import spearman_interval
from tactex_ros.cli.main import main
from tactex_ros.core.errors import InputError
from tactex_lab.experiments.ranking import run_ranking


def _press(group: str, level: float, seed: int) -> compare.Press:
    """A constructed press: flat grey no-contact frame, contact = + ``level`` on a checker of
    8 px squares (so mean |contact - no contact| = level)."""
    rng = np.random.default_rng(seed)
    nc = np.full((240, 320, 3), 100, np.uint8)
    yy, xx = np.mgrid[0:240, 0:320]
    sign = np.where(((yy // 8) + (xx // 8)) % 2 == 0, 1, -1)[..., None]
    contact = (nc.astype(int) + sign * int(level)).astype(np.uint8)
    nc2 = np.clip(nc.astype(int) + rng.integers(-1, 2, nc.shape), 0, 255).astype(np.uint8)
    return compare.Press(group, group, f"{group}{seed}", nc, nc2, contact)


def test_frame_report_ratios_and_target():
    real = [_press("soft", 2, 0), _press("firm_textured", 4, 1)]
    sim = [_press("soft", 2, 2), _press("firm_textured", 6, 3)]
    rep = compare.frame_report(real, sim)
    checks = {(c["group"], c["statistic"]): c for c in rep["checks"]}
    # level: soft 2 vs 2 -> ratio 1; firm 6 vs 4 -> 1.5, outside the 25 % target
    assert checks[("soft", "diff_mean_abs")]["ratio"] == [1.0]
    assert checks[("soft", "diff_mean_abs")]["within_25pct"]
    assert checks[("firm_textured", "diff_mean_abs")]["ratio"] == [1.5]
    assert not checks[("firm_textured", "diff_mean_abs")]["within_25pct"]
    # all presses: real (2 + 4) / 2 = 3, sim (2 + 6) / 2 = 4
    assert rep["real"]["all"]["diff_mean_abs"] == pytest.approx(3.0)
    assert rep["sim"]["all"]["diff_mean_abs"] == pytest.approx(4.0)
    # the same checker pattern on both sides: its power below 0.1 cycles/px lies in the
    # 0.05-0.1 band only (ratio 1 there, undefined where the real share is 0)
    assert checks[("all", "band_shares")]["real"][:2] == [0.0, 0.0]
    assert checks[("all", "band_shares")]["ratio"][2] == 1.0
    assert rep["checks_passed"] == sum(c["within_25pct"] for c in rep["checks"])


def test_band_shares_and_hf_share_split_the_power():
    rng = np.random.default_rng(0)
    d = rng.normal(0, 1, (240, 320, 3)).astype(np.float32)
    b, hf = compare.band_shares(d), compare.hf_share(d)
    assert b.sum() + hf == pytest.approx(1.0, abs=1e-6)
    # white noise: power proportional to the area of each band in the frequency square
    f = np.hypot(np.fft.fftfreq(240)[:, None], np.fft.fftfreq(320)[None, :])
    assert hf == pytest.approx((f > 0.1).mean(), abs=0.01)
    # a pure 1/16 cycles/px grating lies in the 0.05-0.1 band only
    xx = np.arange(320)[None, :, None] * np.ones((240, 1, 3))
    g = np.sin(2 * np.pi * xx / 16)
    np.testing.assert_allclose(compare.band_shares(g), [0, 0, 1], atol=1e-6)


def test_spearman_interval():
    rng = np.random.default_rng(1)
    p = np.linspace(0.1, 0.9, 8)[:, None]
    a = (rng.random((8, 200)) < p).astype(float)
    b = (rng.random((8, 200)) < p).astype(float)
    same = spearman_interval(a, b, boot=300)
    assert same["rho"] > 0.9 and same["ci95"][0] > 0.6 and same["ci95"][1] <= 1.0
    rev = spearman_interval(a, b[::-1], boot=300)
    assert rev["rho"] < -0.9 and rev["ci95"][1] < -0.6
    tied = spearman_interval(np.ones((3, 5)), b[:3, :5], boot=50)
    assert np.isnan(tied["rho"]) and np.isnan(tied["ci95"][0])


@pytest.fixture
def tiny_real(octopi_dir: Path, tmp_path: Path) -> Path:
    """Four octopi-dev classes, two presses each (links, nothing copied)."""
    root = tmp_path / "real"
    for cls in ("cotton_ball", "basket", "rice", "tissue"):
        (root / cls).mkdir(parents=True)
        for i in (0, 1):
            (root / cls / f"{i}.mov").symlink_to(octopi_dir / cls / f"{i}.mov")
    return root


def test_report_end_to_end_on_a_tiny_setting(tiny_real: Path, tmp_path: Path):
    out_png, out_json = tmp_path / "cmp.png", tmp_path / "cmp.json"
    assert main(["sim", "compare", "--real", str(tiny_real), "--out", str(out_png),
                 "--json", str(out_json), "--presses", "1", "--real-presses", "1",
                 "--fabrics", "polar_fleece,cotton_canvas,corduroy", "--scenes", "2",
                 "--budget", "1", "--comparisons", "2",
                 "--setting", "default=default", "--setting", "random=default:trial.strategy=random"]
                ) == 0
    rep = json.loads(out_json.read_text())
    assert out_png.stat().st_size > 10_000
    assert rep["real_classes"] == ["basket", "cotton_ball", "rice", "tissue"]
    assert rep["sim_fabrics"] == ["corduroy", "cotton_canvas", "polar_fleece"]
    # soft (fleece; cotton ball, tissue) and firm textured groups on both sides
    assert rep["sim"]["soft"]["presses"] == 1 and rep["real"]["soft"]["presses"] == 2
    for c in rep["checks"]:
        r, s = np.atleast_1d(c["real"]), np.atleast_1d(c["sim"])
        np.testing.assert_allclose(c["ratio"], s / r, rtol=2e-3, atol=2e-3)
        assert c["within_25pct"] == bool(np.all(np.abs(np.asarray(c["ratio"]) - 1) <= 0.25))
    rk = rep["ranking"]
    assert list(rk["settings"]) == ["default", "random"]
    assert rk["scenes"] == 2 and rk["budget"] == 1
    assert rk["sim_failed_trials"] == 0 and rk["real_failed_trials"] == 0
    for v in rk["settings"].values():
        for side in ("sim", "real"):
            assert v[side]["accuracy"] in (0.0, 0.5, 1.0)
        assert v["gap_real_minus_sim"] == pytest.approx(v["real"]["accuracy"] -
                                                        v["sim"]["accuracy"])


def test_report_refuses_bad_input(tiny_real: Path, tmp_path: Path):
    base = ["sim", "compare", "--real", str(tiny_real), "--out", str(tmp_path / "x.png")]
    assert main(base + ["--fabrics", "velvet"]) == 2
    assert main(base + ["--scenes", "2", "--setting", "x=nopreset"]) == 2
    assert main(base + ["--scenes", "2", "--comparisons", "1"]) == 2
    with pytest.raises(InputError, match="scenes"):
        run_ranking(str(tiny_real), ["a=default", "b=default"], scenes=1,
                    comparisons=2, budget=1, seed=0, workers=1)


def test_session_stats_split_between_and_within_sessions():
    rng = np.random.default_rng(4)
    yy, xx = np.mgrid[0:240, 0:320]
    ramp = (xx / 320.0 * 40)[..., None]                 # a fixed large-scale pattern
    presses = []
    for k in range(40):                                  # 40 sessions x 4 presses
        level = 100 + 6.0 * rng.standard_normal()      # between-session std 6
        for _ in range(4):
            v = level + 0.5 * rng.standard_normal()     # within-session std 0.5
            nc = np.clip(v + ramp + np.zeros((1, 1, 3)), 0, 255).astype(np.uint8)
            presses.append(compare.Press("soft", "soft", f"s{k}", nc, nc, nc))
    st = compare.session_stats(presses)
    assert st["sessions"] == 40 and st["presses"] == 160
    np.testing.assert_allclose(st["session_mean_between_rgb"], 6.0, rtol=0.3)
    np.testing.assert_allclose(st["session_mean_within_rgb"], 0.5, rtol=0.35)
    # the same pattern in every session: no pattern spread (up to uint8 rounding)
    assert st["session_pattern_between"] < 0.01
    assert st["identity_1nn"] > 0.1          # chance: 3 of 159 other presses, 0.02
    # one press per session: no session statistics; frame_report then adds no session rows
    single = [presses[i] for i in range(0, 160, 4)]
    assert compare.session_stats(single) == {"sessions": 0}
    rep = compare.frame_report(single, single)
    assert not [c for c in rep["checks"] if c["group"] == "sessions"]
    rep = compare.frame_report(presses, presses)
    rows = [c for c in rep["checks"] if c["group"] == "sessions"]
    assert [c["statistic"] for c in rows] == list(compare.SESSION_KEYS)
    # the same presses on both sides: ratio 1 wherever the real value is not 0
    ratios = np.concatenate([np.atleast_1d(c["ratio"]) for c in rows]).astype(float)
    assert np.all(np.isnan(ratios) | (ratios == 1.0)) and np.isfinite(ratios).sum() >= 9
