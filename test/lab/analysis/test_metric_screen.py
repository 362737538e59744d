"""The MLP metric's screening (``experiment unseen --screen-mlp``): the per-scene proxy, exact
on a seeded set, and the rows of both directions paired against the whitening."""

import numpy as np
import pytest

from tactex_lab.analysis import metric_screen


def _cache(rng, n_cls, per):
    cls = np.repeat([f"k{i}" for i in range(n_cls)], per)
    x = (rng.normal(0, 1, (n_cls * per, 8))
         + np.repeat(rng.normal(0, 1.5, (n_cls, 8)), per, axis=0))
    return {"cls": cls, "f0": x}


@pytest.fixture
def caches():
    rng = np.random.default_rng(5)
    return _cache(rng, 6, 3), _cache(rng, 7, 3)


def test_scene_hits_exact(caches):
    a, _ = caches
    h = metric_screen.scene_hits(a["f0"], a["cls"], None, 1, scenes=200, seed=0)
    assert h.shape == (200,) and h.mean() == pytest.approx(0.87)
    assert h[:10].tolist() == [True] * 6 + [False] + [True] * 3
    h2 = metric_screen.scene_hits(a["f0"], a["cls"], None, 2, scenes=200, seed=0)
    assert h2.mean() == pytest.approx(0.91)
    # a metric that keeps only noise (a constant map) finds the match at chance or worse
    class Flat:
        def apply(self, x):
            return np.zeros((len(x), 1))
    assert metric_screen.scene_hits(a["f0"], a["cls"], Flat(), 1, scenes=200).mean() < 0.4


def test_screen_rows_both_directions_paired_against_the_whitening(caches):
    a, b = caches
    rows = metric_screen.screen(a, b, {"frame": lambda c: c["f0"]},
                                grid=(("triplet", 4, 0.1),), steps=5, scenes=300)
    assert [(r["direction"], r["metric"]) for r in rows] == [
        ("a_with_b", "whiten"), ("a_with_b", "mlp"), ("b_with_a", "whiten"), ("b_with_a", "mlp")]
    assert rows[0]["acc_1"] == pytest.approx(0.8566666666666667)
    assert rows[2]["acc_1"] == pytest.approx(0.71)
    assert rows[2]["acc_2"] == pytest.approx(0.6466666666666666)
    assert rows[3]["acc_1"] == pytest.approx(0.7133333333333334)
    v = rows[3]["vs_whiten"]["1"]
    # the same 300 scenes: the MLP alone right on 2, the whitening alone on 1
    assert (v["n"], v["a_only"], v["b_only"], v["p"]) == (300, 2, 1, 1.0)
    assert rows[1]["apply_us"] > 0 and rows[1]["loss"] == "triplet"


@pytest.mark.slow
def test_unseen_screen_mlp_command_writes_the_rows_and_refuses_bad_steps(caches, tmp_path):
    import json

    from tactex_ros.cli.main import main
    for name, c in zip(("liba", "libb"), caches, strict=True):
        np.savez(tmp_path / f"{name}.npz", cls=c["cls"], f0=c["f0"],
                 extra=np.repeat(c["f0"][:, None], 3, axis=1))
    base = ["experiment", "unseen", "--a", str(tmp_path / "liba"), "--b",
            str(tmp_path / "libb"), "--cache-dir", str(tmp_path), "--screen-mlp",
            "--mlp-losses", "triplet", "--mlp-decays", "0.1", "--mlp-features", "frame"]
    assert main(base + ["--mlp-steps", "0", "--out", str(tmp_path / "bad")]) == 2
    assert main(base + ["--mlp-steps", "3", "--out", str(tmp_path / "out")]) == 0
    rows = json.loads((tmp_path / "out" / "metric_screen.json").read_text())
    assert [(r["direction"], r["metric"]) for r in rows] == [
        ("a_with_b", "whiten"), ("a_with_b", "mlp"), ("b_with_a", "whiten"), ("b_with_a", "mlp")]
    assert rows[1]["steps"] == 3 and rows[1]["decay"] == 0.1
