"""`tactex experiment real --report-only --paired-against`: the report scenes without choosing,
paired tests against several settings; and the paired test at a threshold on constructed
curves."""

import json

import pytest

from tactex_ros.cli.main import main
from tactex_lab.experiments.curves import BeliefCurve, paired_at_thresholds


def _curve(correct, conf):
    return BeliefCurve(tuple(range(len(correct))), tuple(correct), tuple(conf),
                       (0.0,) * len(conf))


def test_paired_at_a_threshold_by_hand():
    # three scenes; at theta 0.9 reference A stops right, right, wrong; B wrong, wrong, wrong
    a = [_curve([True, True], [0.95, 0.99]), _curve([False, True], [0.5, 0.92]),
         _curve([False, False], [0.91, 0.95])]
    b = [_curve([False, True], [0.95, 0.99]), _curve([False, False], [0.5, 0.6]),
         _curve([False, False], [0.91, 0.95])]
    out = paired_at_thresholds({"a": a, "b": b}, "a", [0.9])["b"]["0.9"]
    assert out["reference"] == pytest.approx(2 / 3) and out["setting"] == 0.0
    # two discordant pairs, both for A: exact McNemar p = 2 * 0.5**2 = 0.5
    assert out["p"] == pytest.approx(0.5)


def test_report_only_end_to_end(octopi_dir, tmp_path):
    out = tmp_path / "uq"
    args = ["experiment", "real", "--source", f"replay:{octopi_dir}", "--scenes", "2",
            "--budget", "2", "--folds", "2", "--workers", "1", "--out", str(out),
            "--report-only", "--setting", "d=default", "--setting", "r=default:trial.strategy=random",
            "--thresholds", "0.9", "1.01"]
    assert main(args + ["--paired-against", "d", "r"]) == 0
    s = json.loads((out / "summary.json").read_text())
    assert "held_out" not in s and all(f["choose_rows"] == [] for f in s["folds"])
    assert {r["n"] for r in s["report_rows"]} == {4}          # 2 folds x 2 report scenes
    assert all(r["ci95"][0] <= r["accuracy"] <= r["ci95"][1] for r in s["report_rows"])
    assert set(s["paired"]) == {"d", "r"}
    assert set(s["paired"]["d"]["thresholds"]["r"]) == {"0.9", "1.01"}
    assert s["paired"]["d"]["budgets"]["r"]["0"]["p"] == 1.0    # same presses before acting
    assert main(args + ["--paired-against", "nope"]) == 2     # bad input: named, exit 2


def test_calibration_by_hand():
    from tactex_lab.experiments.protocol import calibration
    # bin [0.9, 1.0): confidences 0.95, 0.95, one right -> |0.95 - 0.5| = 0.45, weight 2/4;
    # bin [0.6, 0.7): 0.6 right -> |0.6 - 1| = 0.4, weight 1/4; bin [0.3, 0.4): 0.3 wrong ->
    # 0.3, weight 1/4
    cs = [_curve([True, False], [0.95, 0.95]), _curve([True, False], [0.6, 0.3])]
    out = calibration(cs)
    assert out["ece"] == pytest.approx(0.5 * 0.45 + 0.25 * 0.4 + 0.25 * 0.3)
    assert out["right_at_0.9"] == 0.5 and out["share_at_0.9"] == 0.5
    assert out["accuracy"] == 0.5 and out["mean_confidence"] == pytest.approx(0.7)
