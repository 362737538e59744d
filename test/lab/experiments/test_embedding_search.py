"""``experiment embedding-search``: the network is chosen on one direction and judged on the
other (``pick``), and a bad grid is refused at the edge (exit 2)."""

import argparse

import numpy as np
import pytest

from tactex_ros.cli.main import main
from tactex_ros.core.errors import InputError
from tactex_lab.experiments.embedding_search import _ensembles, _hits, pick


def _row(aug: str, steps: int, direction: str, acc_1: float, acc_2: float) -> dict:
    return {"aug": aug, "variants": 150, "steps": steps, "direction": direction,
            "metric": "none", "acc_1": acc_1, "acc_2": acc_2,
            "vs_first_1": {"p": 0.5}, "vs_first_2": {"p": 0.25}}


def test_the_network_chosen_on_one_direction_is_judged_on_the_other():
    rows = [_row("geometric", 1500, "A", 0.80, 0.90), _row("geometric", 1500, "B", 0.70, 0.80),
            _row("photometric", 1500, "A", 0.82, 0.91), _row("photometric", 1500, "B", 0.60, 0.7),
            _row("geometric", 3000, "A", 0.79, 0.90), _row("geometric", 3000, "B", 0.75, 0.85)]
    chosen = pick(rows, "A", "B", "none")
    assert chosen["setting"] == {"aug": "photometric", "variants": 150, "steps": 1500}
    # judged on B's figures, not A's
    assert (chosen["acc_1"], chosen["acc_2"]) == (0.60, 0.7)
    back = pick(rows, "B", "A", "none")
    assert back["setting"]["steps"] == 3000 and back["acc_1"] == 0.79
    with pytest.raises(InputError, match="whiten"):
        pick(rows, "A", "B", "whiten")


def test_a_bad_grid_is_refused_with_exit_2(tmp_path):
    assert main(["experiment", "embedding-search", "--a", str(tmp_path), "--b", str(tmp_path),
                 "--cache-dir", str(tmp_path), "--steps", "0"]) == 2
    assert not list(tmp_path.iterdir())          # refused before anything was cached


def _cache(rng, signal: bool, classes: int = 8, per: int = 4) -> dict:
    """A press cache whose 4-frame embedding separates the classes only with ``signal``."""
    cls = np.repeat(np.arange(classes), per)
    centre = rng.standard_normal((classes, 32)) * (5.0 if signal else 0.0)
    cnn4 = centre[cls] + rng.standard_normal((len(cls), 32))
    return {"cls": cls, "f0": rng.standard_normal((len(cls), 3)),
            "hm": rng.standard_normal((len(cls), 2)), "cnn4": cnn4, "cnn4_lib": cnn4}


def test_an_ensemble_appends_the_other_seeds_embeddings_and_is_never_picked():
    rng = np.random.default_rng(0)
    setting = ("geometric", 150, 1500)
    # seed 0's network sees nothing; seed 1's separates every class
    nets = {(setting, 0): {"a": _cache(rng, False), "b": _cache(rng, False)},
            (setting, 1): {"a": _cache(rng, True), "b": _cache(rng, True)}}
    hits = {(setting, s, t, "none"): _hits(nets[setting, s][t], nets[setting, s][lib], "none",
                                           200)
            for s in (0, 1) for t, lib in (("a", "b"), ("b", "a"))}
    args = argparse.Namespace(seed=[0, 1], kinds=["none"], scenes=200)
    rows = _ensembles([setting], args, nets, hits, {"a": "A", "b": "B"})
    assert [(r["direction"], r["ensemble"]) for r in rows] == [("A", True), ("B", True)]
    for r in rows:
        assert r["acc_1"] == 1.0              # the appended embedding carries the classes
        assert r["vs_first_1"]["p"] < 1e-6    # against seed 0's network alone
    assert hits[setting, 0, "a", "none"][1].mean() < 0.6
    plain = [_row("geometric", 1500, "A", 0.80, 0.90), _row("geometric", 1500, "B", 0.70, 0.8)]
    assert pick(plain + rows, "A", "B", "none")["acc_1"] == 0.70


def test_an_ensemble_of_one_seed_is_refused_with_exit_2(tmp_path):
    assert main(["experiment", "embedding-search", "--a", str(tmp_path), "--b", str(tmp_path),
                 "--cache-dir", str(tmp_path), "--ensemble", "--seed", "0"]) == 2
    assert not list(tmp_path.iterdir())
