"""`tactex experiment classify|explore|humans` end to end on tiny settings; outputs checked."""

import json

import numpy as np
import pytest
import yaml

from tactex_ros.cli.main import main
from tactex_ros.core.config import TrialConfig
from tactex_ros.core.errors import InputError
from tactex_lab.experiments.common import decision_at_budget
from tactex_lab.experiments.humans import load_humans
from tactex_lab.experiments.runner import TrialJob, run_job
from tactex_lab.experiments.trials import find_trial_file, load_trials
from tactex_ros.core.paths import config_dir

TINY = ["--set", "learner.input_size=32", "--set", "learner.mc_passes=4",
        "--set", "learner.steps=2",
        "--set", "learner.bn_recalibrate=8"]
TINY_OVR = dict(input_size=32, mc_passes=4, steps=2, bn_recalibrate=8)


def _pngs_ok(paths):
    for p in paths:
        with open(p, "rb") as f:
            assert f.read(8) == b"\x89PNG\r\n\x1a\n", p


def test_human_study_trial_file_matches_the_thesis():
    tf = load_trials(find_trial_file("human_study"))
    assert len(tf["trials"]) == 32
    t = {x["id"]: x for x in tf["trials"]}
    assert t["1"] == {"id": "1", "reference": 23, "comparisons": [4, 8, 23, 7]}
    assert t["13"] == {"id": "13", "reference": 17, "comparisons": [11, 18, 21, 17]}
    assert t["32"] == {"id": "32", "reference": 21, "comparisons": [4, 7, 11, 21]}
    assert all(x["reference"] in x["comparisons"] for x in tf["trials"])
    used = {c for x in tf["trials"] for c in x["comparisons"]}
    assert used == {4, 7, 8, 11, 17, 18, 21, 23}


def test_budget_readout_equals_a_capped_run():
    """The decision at budget k read from a full run is the final decision of a run capped at k."""
    classes = ["chino", "cotton_canvas", "chino", "wool_serge"]
    for strategy, k in (("variance", 7), ("yoto", 6), ("variance", 5)):
        trial = TrialConfig(strategy=strategy, rounds=4, stop_confidence=0.0)
        full = TrialJob(source="sim", seed=4, trial=trial, preset="cnn", overrides=TINY_OVR,
                        platform_classes=classes)
        capped = TrialJob(source="sim", seed=4, trial=trial.replace(max_touches=k),
                          preset="cnn", overrides=TINY_OVR, platform_classes=classes)
        rf, rc = run_job(full), run_job(capped)
        decisions = [{"probs": r.probs, "total": sum(r.touches) + 1} for r in rf.decisions]
        d = decision_at_budget(decisions, k)
        np.testing.assert_allclose(d["probs"], rc.outcome.final.probs, rtol=0, atol=1e-12)
        assert d["total"] == sum(rc.outcome.final.touches) + 1


@pytest.fixture(scope="module")
def explore_out(tmp_path_factory):
    out = tmp_path_factory.mktemp("explore")
    rc = main(["experiment", "explore", "--trials", "1,2", "--strategies", "variance",
               "random", "yoto", "--rounds", "3", "--budgets", "5", "6", "7", "--workers", "2",
               "--seeds", "0", "--out", str(out), "--quiet", *TINY])
    assert rc == 0
    return out


def test_explore_outputs(explore_out):
    s = json.loads((explore_out / "summary.json").read_text())
    runs = json.loads((explore_out / "runs.json").read_text())
    assert len(runs) == 2 * 3
    assert json.loads((explore_out / "config.json").read_text())["config"]["rounds"] == 3
    m = s["models"]["small_inception"]
    strategies = ["variance", "random", "yoto"]
    def right(d, truth):
        return int(np.argmax(d["probs"])) + 1 == truth

    for st in strategies:
        mine = [r for r in runs if r["strategy"] == st]
        assert m["fixed_rounds"][st]["n"] == 2
        assert m["fixed_rounds"][st]["accuracy"] == np.mean([r["correct"] for r in mine])
        assert set(m["budget"][st]["per_budget"]) == {"5", "6", "7"}
        # budget k: the first decision made with >= k touches (the last one past the run)
        at = {k: [right(next((d for d in r["decisions"] if d["total"] >= k),
                             r["decisions"][-1]), r["truth"]) for r in mine] for k in (5, 6, 7)}
        for k in (5, 6, 7):
            assert m["budget"][st]["per_budget"][str(k)]["accuracy"] == np.mean(at[k])
        assert m["budget"][st]["matched"]["accuracy"] == pytest.approx(
            np.mean([np.mean([at[k][i] for k in (5, 6, 7)]) for i in range(2)]))
        assert len(m["curves"][st]["accuracy"]) == 4        # 3 rounds + the final decision
        assert m["curves"][st]["accuracy"] == [
            np.mean([right(r["decisions"][j], r["truth"]) for r in mine]) for j in range(4)]
        assert m["curves"][st]["entropy_mean"] == pytest.approx(
            [np.mean([r["decisions"][j]["entropy"] for r in mine]) for j in range(4)], abs=1e-5)
        assert set(m["per_trial"][st]) == {"1", "2"}
        cm = np.array(m["confusion"][st]["matrix"])
        assert cm.shape == (7, 7) and cm.sum() == 2
    assert len(m["tests"]["fixed_rounds"]) == 3 and len(m["tests"]["matched_budget"]) == 3
    assert all(0 <= t["p"] <= 1 and 0 <= t["p_holm"] <= 1 for t in m["tests"]["fixed_rounds"])
    for r in runs:
        assert len(r["decisions"]) == 4
        assert r["decisions"][0]["total"] == 5
        # rejected touches (contact guard) are not counted: at most one touch per round
        assert r["touches"] == r["decisions"][-1]["total"]
        assert r["touches"] == 5 if r["strategy"] == "yoto" else 5 < r["touches"] <= 8
    assert s["timing"]["decisions"] == 6 * 4 and s["timing"]["decision_s_median"] > 0
    _pngs_ok(s["figures"])
    assert {p.split("/")[-1] for p in s["figures"]} >= {
        "accuracy.png", "accuracy_vs_round.png", "uncertainty_vs_round.png",
        "accuracy_vs_budget.png", "per_trial.png", "confusion.png"}


def test_humans_with_robot(explore_out, tmp_path):
    out = tmp_path / "humans"
    assert main(["experiment", "humans", "--robot", str(explore_out), "--out", str(out),
                 "--quiet"]) == 0
    s = json.loads((out / "summary.json").read_text())
    assert s["n_participants"] == 3 and s["n_trials"] == 4 and s["n_records"] == 11
    assert s["accuracy"]["overall"] == pytest.approx(7 / 11)
    assert np.array(s["confusion"]["matrix"]).sum() == 11
    js = s["js_distance"]
    # the human-human distances recomputed from the human trial file (scipy, base 2): the mean
    # over pairs of participants per trial, and over trials
    from itertools import combinations

    from scipy.spatial.distance import jensenshannon
    recs = load_humans(config_dir() / "humans" / "example.yaml")["records"]
    want = {}
    for t in {r["trial"] for r in recs}:
        rt = [np.asarray(r["time"], float) for r in recs if r["trial"] == t]
        want[t] = np.mean([jensenshannon(a / a.sum(), b / b.sum(), base=2.0)
                           for a, b in combinations(rt, 2)])
    assert set(js["human_human"]["per_trial"]) == {"1", "2", "3", "4"}
    assert js["human_human"]["per_trial"] == pytest.approx(want)
    assert js["human_human"]["mean"] == pytest.approx(np.mean(list(want.values())))
    for kind in ("human_robot_final", "human_robot_matched"):
        for st in ("variance", "random", "yoto"):
            per = js[kind][st]["per_trial"]
            assert set(per) == {"1", "2"}   # trials the robot ran
            assert js[kind][st]["mean"] == pytest.approx(np.mean(list(per.values())))
    mt = s["most_touched_is_answer"]
    # the answer is the uniquely most-touched platform in this share of human trials
    hits = [float(np.argmax(r["time"]) == r["answer"] - 1
                  and np.sum(np.isclose(r["time"], max(r["time"]))) == 1) for r in recs]
    assert mt["humans"] == pytest.approx(np.mean(hits)) and mt["robot"]["yoto"] == \
        pytest.approx(0.25)
    _pngs_ok(s["figures"])


def test_humans_file_checked(tmp_path):
    good = yaml.safe_load((config_dir() / "humans" / "example.yaml").read_text())
    bad = dict(good)
    bad["participants"] = [{"id": "X", "trials": [{"trial": 1, "answer": 5,
                                                    "visits": [[0, 1.0]]}]}]
    p = tmp_path / "bad.yaml"
    p.write_text(yaml.safe_dump(bad))
    with pytest.raises(InputError, match="answer 5"):
        load_humans(p)
    bad["participants"] = [{"id": "X", "trials": [{"trial": 99, "answer": 1,
                                                    "visits": [[0, 1.0]]}]}]
    p.write_text(yaml.safe_dump(bad))
    assert main(["experiment", "humans", "--humans", str(p), "--out",
                 str(tmp_path / "o"), "--quiet"]) == 2


def test_classify_sim(tmp_path):
    out = tmp_path / "classify"
    assert main(["experiment", "classify", "--classes", "4,11,21", "--train", "2", "--val", "2",
                 "--test", "3", "--models", "small_inception", "--seeds", "0", "1",
                 "--epochs", "2", "--input-size", "32", "--workers", "1", "--out", str(out),
                 "--quiet", "--set", "learner.bn_recalibrate=8"]) == 0
    s = json.loads((out / "summary.json").read_text())
    m = s["models"]["small_inception"]
    assert m["test_acc"]["n"] == 2
    assert m["test_acc"]["mean"] == pytest.approx(np.mean([r["test_acc"] for r in s["runs"]]))
    assert m["n"] == {"train": 6, "val": 6, "test": 9}
    assert len(m["curves"]["val_acc"]["mean"]) == 2
    cm = np.array(m["confusion"]["matrix"])
    assert cm.shape == (3, 3) and cm.sum() == 2 * 9
    assert m["confusion"]["labels"] == ["cotton_canvas", "oxford", "wide_wale_cord"]
    assert all(1 <= e <= 2 for e in m["best_epoch"])
    _pngs_ok(s["figures"])


def test_classify_replay_splits_by_press(tmp_path, octopi_dir):
    out = tmp_path / "classify_replay"
    assert main(["experiment", "classify", "--source", f"replay:{octopi_dir}",
                 "--classes", "basket,sponge,toilet_paper", "--models", "small_inception",
                 "--seeds", "3", "--epochs", "1", "--input-size", "32", "--fourier",
                 "--workers", "1", "--out", str(out), "--quiet"]) == 0
    s = json.loads((out / "summary.json").read_text())
    run = s["runs"][0]
    assert run["fourier"] is True
    for cls, parts in run["files"].items():
        files = parts["train"] + parts["val"] + parts["test"]
        assert len(files) == len(set(files)) == len(list((octopi_dir / cls).iterdir()))
        assert len(parts["train"]) >= 1 and len(parts["val"]) >= 1 and len(parts["test"]) >= 1
    assert run["files"]["toilet_paper"] and len(run["files"]["toilet_paper"]["test"]) == 3


def test_experiment_bad_inputs_exit_2(tmp_path):
    assert main(["experiment", "explore", "--trials", "99", "--out", str(tmp_path)]) == 2
    assert main(["experiment", "explore", "--strategies", "nope", "--out", str(tmp_path)]) == 2
    assert main(["experiment", "explore", "--models", "inception_v3",
                 "--out", str(tmp_path)]) == 2
    assert main(["experiment", "classify", "--classes", "4,nope", "--out", str(tmp_path)]) == 2
    assert main(["experiment", "classify", "--models", "inception_v3_random",
                 "--inception-input-size", "64", "--out", str(tmp_path)]) == 2
    # the faithful part names the source it needs (no default data path); nothing is written
    out = tmp_path / "pareto"
    assert main(["experiment", "pareto", "--parts", "faithful", "--out", str(out)]) == 2
    assert not out.exists()
    # the job runner's options are checked before any job runs
    assert main(["experiment", "explore", "--address", "auto", "--out", str(tmp_path)]) == 2
