"""Issue 47, item 4: a trial that stopped without reaching its stop rule (out of rounds or
touches, belief below the stop confidence) is "not sure": the terminal's line never calls it
correct, the session's accuracy does not count it as correct (it is counted apart), and the
session report's stop column says "not sure" instead of the stop reason ``rounds``."""

from __future__ import annotations

import json
import re
from pathlib import Path

from tactex_ros.trial import session as sess
from tactex_ros.trial.report import regenerate
from tactex_ros.trial.session_run import SessionRun, trial_done_text

from test_session_trials import IDS, THREE, _Operator     # noqa: I001 - sibling test module


def test_the_terminal_line_of_a_not_sure_trial_never_says_correct() -> None:
    e = {"event": "trial_done", "trial": "17", "prediction": "c1", "touches": 9,
         "stop_reason": "rounds", "correct": True, "not_sure": True, "confidence": 0.52}
    line = trial_done_text(e)
    assert "not sure" in line and "correct" not in line and "rounds" not in line
    assert "0.52" in line
    sure = trial_done_text({**e, "not_sure": False, "stop_reason": "confident"})
    assert sure.endswith("correct") and "not sure" not in sure
    assert trial_done_text({**e, "not_sure": False, "correct": False}).endswith("wrong")


def _session(d: Path) -> None:
    """Trial 1 sure and right, trial 2 out of rounds below the stop confidence (its best guess
    right), trial 3 sure and wrong."""
    def run_trial(trial, resume):
        r = d / trial.record_name
        r.mkdir(parents=True, exist_ok=True)
        (r / "config.json").write_text(json.dumps({"trial": {"stop_confidence": 0.9}}))
        wrong = next(i for i in IDS[1:] if i not in trial.truth)
        pred, sure, conf, why = {"1": (trial.truth[0], True, 0.95, "confident"),
                                 "2": (trial.truth[0], False, 0.52, "rounds"),
                                 "3": (wrong, True, 0.93, "confident")}[trial.id]
        res = {"prediction": pred, "touches": 9, "stop_reason": why, "sure": sure,
               "confidence": conf, "correct": pred in trial.truth}
        (r / "result.json").write_text(json.dumps(res))
        return res
    s = sess.load_session(THREE, IDS)
    assert SessionRun(s, d, {"seed": 0}, 60.0).run(_Operator(), run_trial, lambda: False) == 0


def test_a_not_sure_trial_is_counted_apart_never_as_correct(tmp_path: Path) -> None:
    d = tmp_path / "s"
    _session(d)
    out = sess.summary(d)
    assert out["done"] == 3 and out["not_sure"] == 1
    assert out["accuracy"] == 1 / 3                       # trial 1 only
    rows = {r["id"]: r for r in out["trials"]}
    assert rows["2"]["not_sure"] and rows["2"]["correct"] is None
    assert rows["2"]["guess_correct"] is True
    assert rows["1"]["correct"] is True and rows["3"]["correct"] is False
    done = {e["trial"]: e for e in sess.events(d) if e["event"] == "trial_done"}
    assert done["2"]["not_sure"] is True and done["1"]["not_sure"] is False
    assert "correct" not in trial_done_text(done["2"])


def test_the_session_report_shows_not_sure_instead_of_the_stop_reason(tmp_path: Path) -> None:
    d = tmp_path / "s"
    _session(d)
    regenerate(d)            # each trial's report (what links to it), then the session's
    html = (d / "report.html").read_text()
    rows = re.findall(r"<tr>(.*?)</tr>", html, flags=re.S)
    row = {k: next(r for r in rows if f"{sess.record_name(k)}/report.html" in r)
           for k in ("1", "2", "3")}
    cells = [re.sub(r"<[^>]+>", "", c).strip()
             for c in re.findall(r"<td[^>]*>(.*?)</td>", row["2"], flags=re.S)]
    assert "rounds" not in cells and cells[-2:] == ["not sure", "not sure"]
    assert "not sure" not in row["1"] and "not sure" not in row["3"]
    acc = re.search(r"id='accuracy'>accuracy <b>([0-9.]+)</b>", html).group(1)
    assert float(acc) == round(1 / 3, 3)
    assert re.search(r"id='not-sure-count'>1<", html)


def test_the_trial_report_of_a_not_sure_trial_never_says_correct(tmp_path: Path) -> None:
    from test_scene_truth import _scene
    from test_trial_run import FakePress, _inputs, _spec
    from tactex_ros.trial.run import TrialRun
    spec = _spec(rounds=2, stop_confidence=0.999)          # two rounds: not sure
    fab = {"reference": "satin", "c1": "satin", "c2": "wide_wale_cord", "c3": "rib_2x2",
           "c4": "polar_fleece"}
    for c in ("c1", "c2"):          # the best guess right, then wrong, on the same touches
        truth = {**fab, "c1": fab["c2"], "c2": "satin"} if c == "c2" else fab
        res = TrialRun(spec, tmp_path, c, press=FakePress(), inputs=_inputs(spec),
                       scene_file=_scene(tmp_path, f"{c}.yaml", truth, "sim_fabric")).run()
        assert res["sure"] is False and res["stop_reason"] == "rounds"
        html = (tmp_path / c / "report.html").read_text()
        stop = re.search(r"id='stop-reason'>([^<]*)<", html).group(1)
        verdict = re.search(r"id='verdict'[^>]*>([^<]*)<", html).group(1)
        assert stop == "not sure" and verdict != "correct"
        assert verdict == ("not sure" if res["prediction"] == c else "wrong")


def test_the_sessions_last_line_counts_the_not_sure_apart(tmp_path: Path) -> None:
    from tactex_ros.cli.graph_commands import session_done_text
    d = tmp_path / "s"
    _session(d)
    res = json.loads((d / sess.RESULT_FILE).read_text())      # what cmd_session prints from
    assert res["not_sure"] == 1
    nums = [float(x) for x in re.findall(r"\d+(?:\.\d+)?", session_done_text(res, 125.0))]
    assert nums[-5:] == [3.0, round(1 / 3, 3), 1.0, 2.0, 5.0]  # trials, accuracy, not sure, m:ss
    # to the second (the operator walk: a 20.7 s run printed as 0.3 min, 18 s)
    assert re.search(r"(\d+):(\d\d) in this run", session_done_text(res, 20.7)).groups() == (
        "0", "21")
