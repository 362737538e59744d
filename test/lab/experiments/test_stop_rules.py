"""`tactex experiment stop-rules` (first cut) end to end on the simulator: both rules run on the
same scenes; the summary's figures are those of its rows."""

import json

import pytest

from tactex_ros.cli.main import main
from tactex_ros.core.errors import InputError


def test_stop_rules_paired_on_the_simulator(tmp_path):
    f = tmp_path / "s.json"
    assert main(["experiment", "stop-rules", "--source", "sim", "--scenes", "2",
                 "--comparisons", "3", "--rounds", "3", "--file", str(f)]) == 0
    out = json.loads(f.read_text())
    for name in ("threshold", "evalue"):
        rows, r = out["rows"][name], out["arms"][name]
        assert len(rows) == 2
        assert r["accuracy"] == sum(x["correct"] for x in rows) / 2
        assert r["sure_and_wrong"] == sum(x["sure"] and not x["correct"] for x in rows) / 2
        assert all(0 <= x["extra"] <= 3 for x in rows)
    assert 0 <= out["mcnemar_p"] <= 1


def test_stop_rules_refuses_a_bad_count(capsys):
    assert main(["experiment", "stop-rules", "--source", "sim", "--scenes", "0",
                 "--file", "x.json"]) == 2
    assert "--scenes" in capsys.readouterr().err


def test_two_strategies_paired_on_the_simulator(tmp_path):
    f = tmp_path / "s.json"
    assert main(["experiment", "stop-rules", "--source", "sim", "--scenes", "2",
                 "--comparisons", "3", "--rounds", "3", "--strategies", "infogain",
                 "lookahead", "--file", str(f)]) == 0
    out = json.loads(f.read_text())
    assert list(out["arms"]) == ["infogain", "lookahead"]
    for name, r in out["arms"].items():
        rows = out["rows"][name]
        assert r["touches"] == sum(x["extra"] for x in rows) / 2
    assert out["wilcoxon_touches"]["n"] == 2


@pytest.mark.parametrize("extra, word", [
    (["--scene-protocol", "hard"], "--metric-library"),
    (["--strategies", "infogain", "infogain"], "--strategies"),
    (["--strategies", "infogain", "nope"], "--strategies")])
def test_stop_rules_refuses_bad_scene_and_strategy_options(extra, word, capsys, tmp_path):
    assert main(["experiment", "stop-rules", "--source", "sim", "--scenes", "1",
                 "--file", str(tmp_path / "x.json")] + extra) == 2
    assert word in capsys.readouterr().err


def _renamed(root, names, into):
    """A replay folder ``into`` whose classes are ``root``'s ``names`` under new names."""
    into.mkdir()
    for n in names:
        (into / f"other_{n}").symlink_to(root / n, target_is_directory=True)
    return into


def test_hard_scenes_are_the_nearest_classes_by_the_other_librarys_metric(octopi_dir,
                                                                          tmp_path):
    from tactex_ros.core.config import preset
    from tactex_ros.sources import open_source
    from tactex_lab.experiments.scenes import SceneDraw, nearest_classes
    classes = sorted(d.name for d in octopi_dir.iterdir() if d.is_dir())
    other = _renamed(octopi_dir, classes[:2], tmp_path / "other")
    src = tmp_path / "src"
    src.mkdir()
    for n in classes[2:6]:
        (src / n).symlink_to(octopi_dir / n, target_is_directory=True)
    draw = SceneDraw("hard", open_source(f"replay:{src}"), 2, preset("default"),
                     f"replay:{other}", f"replay:{src}")
    assert sorted(draw.means) == classes[2:6]
    for seed in range(3):
        scene, truth = draw.draw(seed)
        assert scene[truth] == scene[0]
        assert set(scene[1:]) == {scene[0], *nearest_classes(draw.means, draw.weights,
                                                             scene[0], 1)}
    with pytest.raises(InputError, match="shares classes"):
        SceneDraw("hard", open_source(f"replay:{src}"), 2, preset("default"),
                  f"replay:{src}", f"replay:{src}")
