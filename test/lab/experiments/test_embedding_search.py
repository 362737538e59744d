"""``experiment embedding-search``: the network is chosen on one direction and judged on the
other (``pick``), and a bad grid is refused at the edge (exit 2)."""

import pytest

from tactex_ros.cli.main import main
from tactex_ros.core.errors import InputError
from tactex_lab.experiments.embedding_search import pick


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
