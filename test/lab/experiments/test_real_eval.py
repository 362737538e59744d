"""`tactex experiment real` end to end on tiny settings, its pure helpers on constructed cases,
and the replayed press order that its paired scenes rely on."""

import json
import subprocess
import sys

import pytest

from tactex_ros.cli.main import main
from tactex_lab.experiments.curves import BeliefCurve, at_budget, at_stop, parse_setting
from tactex_lab.experiments.protocol import choose, class_folds
from tactex_ros.core.errors import InputError


def _curve(correct, conf):
    return BeliefCurve(tuple(range(len(correct))), tuple(correct), tuple(conf),
                       (0.0,) * len(conf))


def test_stop_and_budget_read_the_belief_curve():
    c = _curve([False, False, True, True], [0.5, 0.91, 0.97, 0.999])
    assert at_stop(c, 0.9) == (False, 1, True)      # stops wrong at +1
    assert at_stop(c, 0.95) == (True, 2, True)
    assert at_stop(c, 1.01) == (True, 3, False)     # never confident: the budget's end
    assert [at_budget(c, k) for k in range(4)] == [False, False, True, True]


def test_a_belief_curve_reads_a_trial_and_keeps_its_runs_json_form():
    """``curve`` of a real trial's decisions; the JSON form has the keys, in the order, and
    the values runs.json always had, and reads back to the same curve."""
    from tactex_ros.core.config import TrialConfig
    from tactex_ros.core.engine import TrialSpec, run_trial
    from tactex_ros.sources import open_source, trial_scene
    from tactex_lab.experiments.curves import curve
    src = open_source("sim")
    classes, truth = trial_scene(src, 3, 2)
    res = run_trial(TrialSpec(3, trial=TrialConfig(rounds=3, stop_confidence=0.0), seed=2),
                    src.trial(classes, 2), truth=truth)
    decisions = res.rounds + [res.final]
    c = curve(decisions, truth, classes=classes)
    assert c.extra == tuple(range(4)) and len(c.conf) == 4
    assert c.correct[-1] == res.correct and c.conf[-1] == max(res.final.probs)
    chosen = [r for r in res.rounds if r.platform not in (None, 0)]     # comparison touches
    assert c.touched == len(chosen)
    assert c.believed == sum(r.platform == max(range(3), key=r.probs.__getitem__) + 1
                             for r in chosen)
    d = c.to_json()
    assert list(d) == ["extra", "correct", "conf", "decision_s", "believed", "touched",
                       "error", "classes"]
    assert d["extra"] == [0, 1, 2, 3] and d["classes"] == classes and d["error"] is None
    text = json.dumps(d)
    assert BeliefCurve.from_json(json.loads(text)) == c
    assert json.dumps(BeliefCurve.from_json(json.loads(text)).to_json()) == text
    with pytest.raises(InputError, match="unknown fields \\['confidence'\\]"):
        BeliefCurve.from_json({**d, "confidence": 1})


def test_choose_takes_the_most_accurate_pair_within_the_touch_target():
    rows = [{"setting": "a", "theta": 0.9, "accuracy": 0.90, "touches": 2.0},
            {"setting": "a", "theta": 0.99, "accuracy": 0.97, "touches": 6.0},
            {"setting": "b", "theta": 0.95, "accuracy": 0.93, "touches": 4.0},
            {"setting": "b", "theta": 0.98, "accuracy": 0.93, "touches": 3.0}]
    assert choose(rows, 5.0) == rows[3]
    assert choose(rows, 6.0) == rows[1]
    assert choose(rows, 1.0) == rows[0]             # none meets it: fewest touches
    assert choose(rows, 5.0, ["a"]) == rows[0]


def test_class_folds_are_disjoint_and_cover():
    classes = [f"k{i}" for i in range(26)]
    f = class_folds(classes, 3, 0)
    assert sorted(sum(f, [])) == sorted(classes) and [len(x) for x in f] == [9, 9, 8]
    assert class_folds(classes, 3, 0) == f and class_folds(classes, 3, 1) != f


def test_parse_setting_names_what_is_wrong():
    assert parse_setting("r=default:trial.strategy=random,learner.match_temperature=0.1") == (
        "r", "default", "random", {"match_temperature": 0.1})
    with pytest.raises(InputError, match="unknown preset"):
        parse_setting("x=nope")
    with pytest.raises(InputError, match=r"unknown setting 'learner.colour'; nearest valid: "
                                         r"'learner.\w+'"):
        parse_setting("x=default:learner.colour=1")
    with pytest.raises(InputError, match=r"trial.rounds: not taken here \(learner.\* settings "
                                         r"and trial.strategy are\)"):
        parse_setting("x=default:trial.rounds=3")


def test_replayed_presses_do_not_depend_on_string_hashing(octopi_dir):
    code = ("import sys; from tactex_ros.sources.replay import ReplaySource\n"
            f"t = ReplaySource({str(octopi_dir)!r}).trial(['rice', 'sponge', 'rice', 'tissue'], 3)\n"
            "[t(p) for p in (0, 1, 2, 3, 1, 1)]\n"
            "print([f for _, f in t.log])")
    outs = {subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                           env={"PYTHONHASHSEED": str(h), "PATH": ""}, check=True).stdout
            for h in (1, 2, 3)}
    assert len(outs) == 1


def test_real_evaluation_end_to_end(octopi_dir, tmp_path):
    out = tmp_path / "real"
    assert main(["experiment", "real", "--source", f"replay:{octopi_dir}", "--scenes", "2",
                 "--budget", "2", "--folds", "2", "--workers", "1", "--out", str(out),
                 "--setting", "d=default", "--setting", "r=default:trial.strategy=random",
                 "--thresholds", "0.9", "1.01"]) == 0
    s = json.loads((out / "summary.json").read_text())
    ho = s["held_out"]
    assert ho["chosen"]["n"] == 4 and len(ho["chosen_pairs"]) == 2
    assert set(ho["settings"]) == {"d", "r"}
    acc = s["per_setting"]["d"]["accuracy_vs_touches"]
    assert [a["touches"] for a in acc] == [0, 1, 2]
    assert all(a["ci95"][0] <= a["accuracy"] <= a["ci95"][1] for a in acc)
    # paired scenes: after the baseline alone the strategy has not acted yet, so both
    # settings saw the same presses and hold the same belief
    p0 = s["paired_at_budgets"]["r"]["0"]
    assert p0["reference"] == p0["setting"] and p0["p"] == 1.0
    assert set(ho["settings"]["r"]["wilcoxon_touches_vs_chosen"]) >= {"p", "mean_difference"}
    assert (out / "accuracy_vs_touches.png").stat().st_size > 0
    assert (out / "pareto.png").stat().st_size > 0
    assert (out / "accuracy_vs_time.png").stat().st_size > 0
