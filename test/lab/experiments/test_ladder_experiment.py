"""`tactex experiment ladder` on a small descriptor cache written here (no frames: descriptor
settings and the ladder's two descriptor rungs): paired settings, CPU per trial, climbs."""

import json

import numpy as np

from tactex_ros.cli.main import main
from tactex_ros.core import representation as rp
from tactex_ros.core.texture import DIM


def _cache(tmp_path, name="lab"):
    """6 classes x 4 presses; classes 0 and 1 nearly alike (hard scenes)."""
    rng = np.random.default_rng(0)
    centres = rng.normal(0, 1, (6, DIM))
    centres[1] = centres[0] + rng.normal(0, 0.05, DIM)
    x = np.concatenate([c + rng.normal(0, 0.3, (4, DIM)) for c in centres])
    cls = np.repeat([f"k{i}" for i in range(6)], 4)
    np.savez(tmp_path / f"{name}.npz", f0=x, cls=cls,
             path=np.array([f"/nowhere/{i}.mov" for i in range(len(x))]))
    lib = {f"m{i}": rng.normal(0, 1, DIM) + rng.normal(0, 0.3, (4, DIM)) for i in range(5)}
    return str(rp.save(rp.fit(lib), tmp_path / "rep.npz"))


def test_ladder_experiment_pairs_settings_and_counts_cpu(tmp_path):
    rep = _cache(tmp_path)
    out = tmp_path / "out"
    rc = main(["experiment", "ladder", "--test", "/data/lab", "--cache-dir", str(tmp_path),
               "--representation", rep, "--scenes", "6", "--budget", "4", "--quiet",
               "--setting", "descriptor=descriptor",
               "--setting", f"auto=descriptor:learner.model=auto,learner.representation={rep},"
                            "learner.ladder=descriptor+representation,"
                            "learner.ladder_patience=1,learner.ladder_min_gain=0.5,"
                            "learner.ladder_sure=1.0",
               "--thresholds", "0.9", "1.01", "--out", str(out)])
    assert rc == 0
    s = json.loads((out / "summary.json").read_text())
    runs = json.loads((out / "runs.json").read_text())
    assert s["scenes"] == 6 and len(runs["auto"]) == len(runs["descriptor"]) == 6
    # the same scenes for both settings
    assert [c["classes"] for c in runs["auto"]] == [c["classes"] for c in runs["descriptor"]]
    lad = s["ladder"]["auto"]["thresholds"]["1.01"]
    climbed = sum(1 for c in runs["auto"] if c["escalations"])
    assert climbed >= 1
    assert lad["reached"].get("representation", 0.0) == climbed / 6
    assert all(c["cpu"] == sorted(c["cpu"]) and c["cpu"][0] >= 0 for c in runs["auto"])
    assert s["paired"]["descriptor"]["thresholds"]["auto"]["0.9"]["p"] <= 1.0


def test_ladder_experiment_refuses_a_missing_representation(tmp_path, capsys):
    _cache(tmp_path)
    rc = main(["experiment", "ladder", "--test", "/data/lab", "--cache-dir", str(tmp_path),
               "--representation", str(tmp_path / "none.npz"), "--out", str(tmp_path / "o")])
    assert rc == 2
    assert "none.npz" in capsys.readouterr().err
