"""Study sessions without ROS: the trial file checked against the scene, the session folder."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from tactex_ros.trial import session as sess
from tactex_ros.core.errors import InputError
from tactex_ros.core.paths import config_dir

IDS = ["reference", "c1", "c2", "c3", "c4"]


def _write(tmp_path: Path, text: str) -> Path:
    p = tmp_path / "trials.yaml"
    p.write_text(text)
    return p


def test_human_study_places_32_trials_with_their_truth() -> None:
    s = sess.load_session("human_study", IDS, seed=5)
    assert len(s.trials) == 32
    t1 = s.trials[0]
    names = sess.catalogue_names()
    # trial 1: reference 23, comparisons [4, 8, 23, 7] -> the match is on c3
    assert t1.placement == {"reference": names[22], "c1": names[3], "c2": names[7],
                            "c3": names[22], "c4": names[6]}
    assert t1.truth == ["c3"] and t1.seed == 5 and s.trials[31].seed == 5 + 31
    assert [t.id for t in s.trials] == [str(i) for i in range(1, 33)]
    assert all(len(t.truth) == 1 for t in s.trials)


@pytest.mark.parametrize("text, words", [
    ("trials:\n  - {id: 1, reference: 99, comparisons: [99, 2, 3, 4]}\n",
     ["entry 1", "id 1", "unknown fabric 99"]),
    ("trials:\n  - {id: 1, reference: 1, comparisons: [1, 2, 3, 4]}\n"
     "  - {id: 7, reference: felt_x, comparisons: [felt_x, 2, 3, 4]}\n",
     ["entry 2", "id 7", "'felt_x'"]),
    ("trials:\n  - {id: 1, reference: 1, comparisons: [1, 2, 3]}\n",
     ["entry 1", "4 fabrics", "5 platforms"]),
    ("trials:\n  - {id: 3, reference: 1, comparisons: [1, 2, 3, 4]}\n"
     "  - {id: 3, reference: 2, comparisons: [1, 2, 3, 4]}\n",
     ["entry 2", "duplicate id '3'"]),
])
def test_bad_session_files_are_refused_with_the_row_named(tmp_path, text, words) -> None:
    with pytest.raises(InputError) as err:
        sess.load_session(_write(tmp_path, text), IDS)
    for w in words:
        assert w in str(err.value)


def test_placement_text_round_trip_and_unknown_platform() -> None:
    pl = {"reference": "satin", "c1": "oxford"}
    assert sess.parse_placement(sess.placement_text(pl), IDS) == pl
    with pytest.raises(InputError, match="unknown platform 'c9'"):
        sess.parse_placement("c9=satin", IDS)
    with pytest.raises(InputError, match="platform=fabric"):
        sess.parse_placement("c1", IDS)


def test_placed_scene_sets_each_platforms_fabric() -> None:
    import yaml
    text = sess.placed_scene(config_dir() / "scene_sim.yaml", {"c2": "oxford"})
    doc = yaml.safe_load(text)
    got = {p["id"]: p["sim_fabric"] for p in doc["platforms"]}
    assert got["c2"] == "oxford" and got["c1"] == "satin"


def test_session_folder_states_and_summary(tmp_path: Path) -> None:
    s = sess.load_session(Path(__file__).parents[1] / "data" / "session_short.yaml", IDS)
    d = tmp_path / "s"
    assert sess.open_session(d, s, {"seed": 0}) is False
    assert sess.open_session(d, s, {"seed": 0}) is True           # the same session: continued
    other = sess.load_session(Path(__file__).parents[1] / "data" / "session_short.yaml", IDS,
                              seed=1)
    with pytest.raises(InputError, match="another session"):
        sess.open_session(d, other, {})
    t1, t2 = s.trials
    assert sess.trial_state(d, t1) == "pending"
    r1 = d / t1.record_name
    r1.mkdir()
    (r1 / "config.json").write_text("{}")
    assert sess.trial_state(d, t1) == "started"
    (r1 / "result.json").write_text(json.dumps({"prediction": "c3", "touches": 6,
                                                "stop_reason": "confident"}))
    assert sess.trial_state(d, t1) == "done"
    r2 = d / t2.record_name
    r2.mkdir()
    (r2 / "config.json").write_text("{}")
    (r2 / "result.json").write_text(json.dumps({"error": "boom"}))
    assert sess.trial_state(d, t2) == "started"         # a failed trial is resumable
    out = sess.summary(d)
    assert out["done"] == 1 and out["total"] == 2 and out["accuracy"] == 1.0
    (r2 / "result.json").write_text(json.dumps({"prediction": "c2", "touches": 9,
                                                "stop_reason": "rounds"}))
    out = sess.summary(d)
    assert out["accuracy"] == 0.5 and [r["correct"] for r in out["trials"]] == [True, False]
    sess.add_event(d, {"event": "x"})
    assert sess.events(d)[-1] == {"event": "x"}


def test_the_graph_refuses_a_bad_session_before_anything_starts(tmp_path: Path) -> None:
    from tactex_ros.ros.graph import describe
    bad = _write(tmp_path, "trials:\n  - {id: 1, reference: 23, comparisons: [4, 8, 23, 7]}\n"
                           "  - {id: 9, reference: 23, comparisons: [4, 8, 23, 7, 1]}\n")
    with pytest.raises(InputError, match=r"entry 2 \(id 9\)"):
        describe(True, explorer={"session_file": str(bad)})
    with pytest.raises(InputError, match="entry 2 \\(id 9\\)"):
        describe(False, explorer={"session_file": str(bad)})
    nodes = describe(True, explorer={"session_file": "human_study"})
    ex = next(n for n in nodes if n.name == "explorer")
    assert ex.parameters["placement_service"] == "/mock_image/set_parameters"
    hw = next(n for n in describe(False, explorer={"session_file": "human_study"})
              if n.name == "explorer")
    assert not hw.parameters.get("placement_service")      # the operator places the fabrics
    with pytest.raises(InputError, match="source"):
        describe(True, explorer={"session_file": "human_study"},
                 mock_image={"source": "replay:/nonexistent"})
