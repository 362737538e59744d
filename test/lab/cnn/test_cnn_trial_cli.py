"""`tactex trial --config cnn` end to end on the real octopi-dev recordings: the product's command
line finds the lab's CNN learner through its entry point."""

import json

import pytest

from tactex_ros.cli.main import main


@pytest.mark.slow
def test_short_replayed_trial_end_to_end(tmp_path, octopi_dir):
    """The CNN setting, fixed rounds: every field of the trial JSON."""
    out = tmp_path / "trial.json"
    rc = main(["trial", "--source", f"replay:{octopi_dir}", "--classes",
               "basket,rice,steel_wool,bubble_wrap", "--reference", "steel_wool",
               "--config", "cnn", "--rounds", "3", "--seed", "1", "--json", str(out),
               "--quiet"])
    assert rc == 0
    d = json.loads(out.read_text())
    assert d["truth"] == "c3" and d["touches"] == 5 + 3 and d["stop_reason"] == "rounds"
    assert d["correct"] == (d["prediction"] == d["truth"])
    assert len(d["rounds"]) == 3
    for r in d["rounds"]:
        assert r["platform"] in {"c1", "c2", "c3", "c4"}
        assert len(r["probs"]) == 4 and abs(sum(r["probs"]) - 1) < 1e-6
        assert len(r["scores"]) == 4 and r["detail"]["train_s"] > 0 and r["score_s"] > 0
        assert r["detail"]["kind"] == "training" and r["detail"]["input_size"] == 48
    assert d["classes"]["c3"] == "steel_wool" == d["truth_class"]
