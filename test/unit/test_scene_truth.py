"""Issue 47, item 2: a simulated trial knows its truth. When every platform of the record's
scene names its fabric (``sim_fabric``; ``replay_class`` on a replay scene) the result holds
``truth`` (the comparison whose fabric is the reference's) and whether the answer is correct,
and the report shows the verdict instead of "truth unknown"; a lab scene (no fabric named)
keeps ``truth`` null."""

from __future__ import annotations

import re
from pathlib import Path

import yaml

from tactex_ros.trial.record import read_result
from tactex_ros.trial.report import scene_truth
from tactex_ros.trial.run import TrialRun

from test_trial_run import FakePress, _inputs, _spec     # noqa: I001 - sibling test module

CONFIG = Path(__file__).parents[2] / "config"


def _scene(tmp_path: Path, name: str, fabrics: dict[str, str | None], key: str) -> Path:
    doc = yaml.safe_load((CONFIG / "scene_sim.yaml").read_text())
    for p in doc["platforms"]:
        p.pop("sim_fabric", None)
        if fabrics.get(p["id"]) is not None:
            p[key] = fabrics[p["id"]]
    out = tmp_path / name
    out.write_text(yaml.safe_dump(doc, sort_keys=False))
    return out


def _trial(tmp_path: Path, scene: Path, tid: str) -> dict:
    spec = _spec(rounds=3)
    return TrialRun(spec, tmp_path, tid, press=FakePress(), inputs=_inputs(spec),
                    scene_file=scene).run()


def test_a_scene_that_names_every_fabric_gives_the_result_its_truth(tmp_path: Path) -> None:
    fab = {"reference": "satin", "c1": "rib_2x2", "c2": "wide_wale_cord", "c3": "satin",
           "c4": "polar_fleece"}
    res = _trial(tmp_path, _scene(tmp_path, "sim.yaml", fab, "sim_fabric"), "t")
    assert res == read_result(tmp_path / "t")
    assert res["truth"] == "c3" and res["truth_platforms"] == ["c3"]
    assert res["correct"] is (res["prediction"] == "c3")
    html = (tmp_path / "t" / "report.html").read_text()
    verdict = re.search(r"<span id='verdict'[^>]*>([^<]*)</span>", html).group(1)
    assert verdict == ("correct" if res["correct"] else "wrong")


def test_scene_truth_of_replay_classes_and_of_a_lab_scene(tmp_path: Path) -> None:
    rep = {"reference": "sponge", "c1": "basket", "c2": "sponge", "c3": "rice", "c4": "wires"}
    for name, fab, key, want in (
            ("replay", rep, "replay_class", ["c2"]),
            ("lab", {}, "sim_fabric", None),                          # nothing named
            ("partly", {**rep, "c4": None}, "replay_class", None),    # one platform unnamed
            ("none alike", {**rep, "c2": "cork"}, "replay_class", None)):
        d = tmp_path / name
        d.mkdir()
        (d / "scene.yaml").write_bytes(_scene(tmp_path, f"{name}.yaml", fab, key).read_bytes())
        assert scene_truth(d) == want, name


def test_a_lab_scene_keeps_the_truth_unknown(tmp_path: Path) -> None:
    res = _trial(tmp_path, _scene(tmp_path, "lab.yaml", {}, "sim_fabric"), "lab")
    assert res["truth"] is None and "truth_platforms" not in res and res["correct"] is None
