"""The benchmark environment's seeded evaluation of tactex's default agent equals
``tactex experiment real`` on the same scenes of recorded presses (octopi-dev): per scene the
same answer and the same touches after the baseline, hence the same accuracy and mean
touches."""

import json

import pytest

from tactex_ros.cli.main import main
from tactex_lab.experiments.curves import BeliefCurve, at_stop

pytestmark = pytest.mark.slow

SCENES, BUDGET = 4, 3


def test_env_evaluation_equals_experiment_real(octopi_dir, tmp_path):
    src = f"replay:{octopi_dir}"
    out = tmp_path / "real"
    assert main(["experiment", "real", "--source", src, "--scenes", str(SCENES), "--budget",
                 str(BUDGET), "--folds", "1", "--workers", "1", "--quiet", "--out", str(out),
                 "--setting", "default=default", "--thresholds", "0.9"]) == 0
    summary = json.loads((out / "summary.json").read_text())
    row = next(r for r in summary["report_rows"] if r["setting"] == "default"
               and r["theta"] == 0.9)
    curves = json.loads((out / "runs.json").read_text())["default"]
    f = tmp_path / "env.json"
    assert main(["bench", "env", "--source", src, "--seeds", f"0-{SCENES - 1}", "--budget",
                 str(BUDGET), "--agent", "default=default", "--json", str(f)]) == 0
    env = json.loads(f.read_text())["agents"]["default"]
    for c, ep in zip(curves, env["episodes"], strict=True):
        assert ep["classes"] == c["classes"]                  # the same scene
        correct, touches, _ = at_stop(BeliefCurve.from_json(c), 0.9)
        assert (ep["correct"], ep["touches"]) == (correct, touches)
    assert env["accuracy"] == pytest.approx(row["accuracy"])
    assert env["touches"] == pytest.approx(row["touches"])


def test_bench_env_refuses_bad_seeds(octopi_dir):
    assert main(["bench", "env", "--source", f"replay:{octopi_dir}", "--seeds", "9-3"]) == 2
    assert main(["bench", "env", "--source", f"replay:{octopi_dir}", "--seeds", "x"]) == 2
