"""tactex experiment pareto / stability: helpers and tiny end-to-end runs."""

import json
import math

import pytest

from tactex_ros.cli.main import main
from tactex_lab.experiments.common import correct_at, learner_set, parse_set
from tactex_lab.analysis.stats import mcnemar_exact as mcnemar
from tactex_lab.analysis.stats import pareto_front, wilson
from tactex_lab.experiments.stability import condition, failure_mode
from tactex_ros.core.errors import InputError

TINY = ["--set", "learner.input_size=32", "--set", "learner.steps=2",
        "--set", "learner.mc_passes=4",
        "--set", "learner.augment=3", "--set", "learner.bn_recalibrate=8"]


def test_pareto_front_keeps_only_undominated_points():
    pts = [(1.0, 0.5), (2.0, 0.7), (3.0, 0.6), (0.5, 0.4), (2.0, 0.65), (4.0, 0.9)]
    assert pareto_front(pts) == [3, 0, 1, 5]


def test_wilson_and_mcnemar():
    # Wilson score interval by hand: (p + z^2/2n -+ z sqrt(p(1-p)/n + z^2/4n^2)) / (1 + z^2/n)
    z, n, p = 1.959963984540054, 10, 0.8
    mid, half = p + z * z / (2 * n), z * math.sqrt(p * (1 - p) / n + z * z / (4 * n * n))
    assert wilson(8, 10) == pytest.approx(((mid - half) / (1 + z * z / n),
                                           (mid + half) / (1 + z * z / n)), abs=1e-9)
    assert wilson(0, 0) == (0.0, 1.0)                    # the product's: no trial, any rate
    r = mcnemar([True] * 10 + [False] * 5, [False] * 10 + [False] * 5)
    assert r["a_only"] == 10 and r["b_only"] == 0
    assert r["p"] == pytest.approx(2 * 0.5 ** 10)        # 2 * P(X = 0), X ~ Bin(10, 1/2)
    assert mcnemar([True, False], [True, False])["p"] == 1.0


def test_correct_at_budget_reads_the_capped_decision():
    dec = [{"total": 5, "probs": [0.9, 0.1]}, {"total": 6, "probs": [0.2, 0.8]},
           {"total": 7, "probs": [0.1, 0.9]}]
    assert correct_at(dec, 1, 5) and not correct_at(dec, 1, 6)
    assert correct_at(dec, 2, 99)          # past the end: the last decision


def test_parse_set_checks_keys():
    assert parse_set(["learner.input_size=48", "learner.guards=false"]) == \
        {"learner": {"input_size": 48, "guards": False}}
    assert learner_set(["learner.input_size=48"]) == {"input_size": 48}
    with pytest.raises(InputError, match="unknown setting 'nope'"):
        parse_set(["nope=1"])
    with pytest.raises(InputError, match=r"^--set trial.rounds: not taken here"):
        parse_set(["trial.rounds=3"])


def test_condition_maps_axes():
    assert condition("difficulty", 0.9, 0.5) == {"source": "sim:0.9", "perturb": {},
                                                 "overrides": {}}
    assert condition("noise", 10, 0.5)["perturb"] == {"noise": 10}
    assert condition("blank", 0.0, 0.5)["perturb"] == {}
    assert condition("lr", 1.0, 0.3) == {"source": "sim:0.3", "perturb": {},
                                         "overrides": {"lr": 1.0}}


def _run(correct=False, probs=(0.85, 0.05, 0.05, 0.05), degenerate=False, loss=0.5,
         touches_end=(2, 2, 2, 2), error=None):
    r = {"probs": list(probs), "scores": [0.1] * 4, "model": "small_inception",
         "touches": [1, 1, 1, 1], "degenerate": degenerate,
         "detail": {"kind": "training", "train_loss": loss, "skipped_steps": 0,
                    "restored": False}}
    return {"correct": correct, "error": error, "rounds": [r, dict(r), dict(r)],
            "final": dict(r, touches=list(touches_end), scores=None)}


def test_failure_modes_from_round_records():
    assert failure_mode(_run(correct=True)) is None
    assert failure_mode(_run(error="FloatingPointError: nan")) == "error"
    assert failure_mode(_run(loss=float("nan"))) == "diverged"
    assert failure_mode(_run(degenerate=True)) == "degenerate"
    assert failure_mode(_run(touches_end=(5, 1, 1, 1))) == "stuck"
    assert failure_mode(_run()) == "confident_wrong"
    assert failure_mode(_run(probs=(0.4, 0.3, 0.2, 0.1))) == "unsure_wrong"


def test_pareto_command_tiny(tmp_path):
    out = tmp_path / "p"
    rc = main(["experiment", "pareto", "--parts", "grid", "touches", "--grid", "quick",
               "--settings", "default", "32px", "--max-trials", "1", "--seeds", "0",
               "--rounds", "1", "--budget", "6", "--touch-rounds", "1",
               "--strategies", "variance", "yoto", "--workers", "1", "--quiet",
               "--out", str(out), *TINY])
    assert rc == 0
    g = json.loads((out / "grid.json").read_text())
    assert set(g["all_trials"]) == {"default", "32px"}
    row = g["all_trials"]["32px"]
    run, = [r for r in json.loads((out / "grid_runs.json").read_text())
            if r["setting"] == "32px"]
    assert row["n"] == 1 and row["accuracy"] == float(correct_at(run["decisions"],
                                                                run["truth"], 6))
    cpu = sorted(d["cpu_s"] for d in run["decisions"])      # 2 decisions: median = mean
    assert len(cpu) == 2 and row["median_cpu_s"] == pytest.approx(sum(cpu) / 2)
    t = json.loads((out / "touches.json").read_text())
    assert t["curves"]["yoto"]["touches"] == [5, 6]
    for f in ("pareto.png", "touches.png", "config.json"):
        assert (out / f).stat().st_size > 0


def test_stability_command_tiny(tmp_path):
    out = tmp_path / "s"
    rc = main(["experiment", "stability", "--axes", "blank", "--seeds", "0", "1",
               "--rounds", "1", "--strategies", "yoto", "--models", "--guard-strategies",
               "yoto", "--workers", "1", "--quiet", "--out", str(out), *TINY])
    assert rc == 0
    s = json.loads((out / "summary.json").read_text())
    blk = s["table"]["blank"]["yoto/default"]
    assert set(blk) == {"0.0", "0.1", "0.25", "0.5"} and blk["0.0"]["n"] == 2
    # the guard rejected blank touches where they were injected (guards on)
    assert blk["0.5"]["rejected_touches"] > 0 and blk["0.0"]["rejected_touches"] == 0
    ba = {(g["value"], g["strategy"]) for g in s["guards_before_after"]}
    assert ba == {(0.25, "yoto"), (0.5, "yoto")}
    for f in ("axis_blank.png", "failure_modes.png", "guards.png"):
        assert (out / f).stat().st_size > 0
    runs = json.loads((out / "runs.json").read_text())
    assert all(r["mode"] in (None, "error", "diverged", "degenerate", "stuck",
                             "confident_wrong", "unsure_wrong") for r in runs)
