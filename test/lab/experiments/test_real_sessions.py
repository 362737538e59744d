"""`tactex experiment real-sessions`: the same real scenes replayed as recorded and moved onto
one session, paired per setting."""

import json

import pytest

from tactex_ros.cli.main import main


def test_real_sessions_end_to_end(octopi_dir, tmp_path):
    out = tmp_path / "rs"
    args = ["experiment", "real-sessions", "--real", str(octopi_dir), "--scenes", "3",
            "--budget", "1", "--workers", "1", "--out", str(out),
            "--setting", "d=default", "--setting", "off=default:learner.descriptor_no_contact=false"]
    assert main(args) == 0
    s = json.loads((out / "summary.json").read_text())
    assert set(s["settings"]) == {"d", "off"}
    for row in s["settings"].values():
        for side in ("recorded", "one_session"):
            r = row[side]
            assert len(r["correct_at_budget"]) == 3 and r["failed_trials"] == 0
            assert r["accuracy_at"]["1"] == pytest.approx(sum(r["correct_at_budget"]) / 3)
        p = row["paired_at_budgets"]["1"]
        assert p["reference"] == row["recorded"]["accuracy_at"]["1"]
        assert p["setting"] == row["one_session"]["accuracy_at"]["1"]
        assert 0.0 <= p["p"] <= 1.0
    # the default subtracts each press's own no-contact frame: moving a press onto another
    # background leaves its contact difference, so its outcomes do not change
    d = s["settings"]["d"]
    assert d["recorded"]["correct_at_budget"] == d["one_session"]["correct_at_budget"]


def test_real_sessions_refuses_duplicate_labels(octopi_dir, tmp_path):
    code = main(["experiment", "real-sessions", "--real", str(octopi_dir), "--setting",
                 "a=default", "--setting", "a=default:trial.strategy=random", "--out", str(tmp_path)])
    assert code == 2 and not (tmp_path / "summary.json").exists()
