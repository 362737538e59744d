"""Issue 47 item 9: the operator's pause, resume, abort, skip and redo of the running trial
(``trial/control.py``) and what a session makes of them (``trial/session_run.py``): each
action recorded with who asked, a pause holds the next press, an abort ends the session with
the trial resumable, a skip is recorded as skipped (never counted in the accuracy), a redo
starts the trial again with its earlier presses kept as superseded."""

from __future__ import annotations

import json
import threading
import time
from pathlib import Path

import pytest

from tactex_ros.core.errors import TrialError
from tactex_ros.trial import session as sess
from tactex_ros.trial.control import ACTIONS, KEYS, OperatorControl, OperatorStop
from tactex_ros.trial.session_run import SessionRun, trial_done_text

IDS = ["reference", "c1", "c2", "c3", "c4"]
THREE = Path(__file__).parents[1] / "data" / "session_three.yaml"


def test_requests_are_refused_without_a_trial_and_recorded_with_who_asked() -> None:
    got: list[dict] = []
    c = OperatorControl(got.append)
    ok, msg = c.request("pause", "key")
    assert not ok and "no trial" in msg and got == []
    with pytest.raises(ValueError, match="stop"):
        c.request("stop", "key")
    c.start("7")
    assert c.request("resume", "service") [0] is False      # not paused: changes nothing
    assert c.request("pause", "key", "tactex graph run (pid 1)")[0]
    assert c.request("pause", "service")[0] is False         # paused already
    assert c.request("resume", "service")[0]
    assert [(e["action"], e["trial"], e["by"], e["caller"]) for e in got] == \
        [("pause", "7", "key", "tactex graph run (pid 1)"), ("resume", "7", "service", None)]
    assert all(e["event"] == "operator" and isinstance(e["time"], float) for e in got)
    assert set(KEYS.values()) == set(ACTIONS)


def test_a_pause_holds_the_next_press_until_resume_and_its_time_is_measured() -> None:
    c = OperatorControl(lambda e: None)
    c.start("1")
    c.gate(1.0, lambda: False)                # not paused: passes at once
    c.request("pause", "key")
    passed: list[float] = []
    t0 = time.monotonic()
    th = threading.Thread(target=lambda: (c.gate(10.0, lambda: False),
                                          passed.append(time.monotonic() - t0)))
    th.start()
    time.sleep(0.4)
    assert not passed                          # held while paused
    c.request("resume", "service")
    th.join(timeout=5.0)
    assert passed and 0.35 < passed[0] < 3.0
    assert 0.35 < c.paused_s < 3.0
    c.request("pause", "key")
    with pytest.raises(TrialError, match="pause_timeout_s"):
        c.gate(0.3, lambda: False)             # every wait has a deadline
    with pytest.raises(TrialError, match="stopping"):
        c.gate(10.0, lambda: True)


@pytest.mark.parametrize("action", ["abort", "skip", "redo"])
def test_an_ending_action_stops_the_next_press_even_from_a_pause(action) -> None:
    c = OperatorControl(lambda e: None)
    c.start("2")
    c.request("pause", "service")
    assert c.request(action, "key", "me")[0]
    assert not c.paused
    assert c.request("skip" if action != "skip" else "abort", "key")[0] is False
    with pytest.raises(OperatorStop) as err:
        c.gate(1.0, lambda: False)
    assert (err.value.action, err.value.by, err.value.caller) == (action, "key", "me")
    c.end()
    assert c.request("pause", "key")[0] is False    # between trials: nothing to hold
    c.start("3")
    c.gate(1.0, lambda: False)                      # a new trial: nothing pending


class _Operator:
    def expect(self, trial_id: str) -> None:
        pass

    def tell(self, text: str) -> None:
        pass

    def wait(self):
        return "yes_flag", "test"

    def place(self, trial) -> None:
        pass


def _press(r: Path, n: int) -> None:
    path = r / "touches.jsonl"
    seq = len(path.read_text().splitlines()) if path.exists() else 0
    with open(path, "a") as f:
        for k in range(n):
            f.write(json.dumps({"seq": seq + k + 1,
                                "platform_id": "c1", "accepted": True}) + "\n")


def test_a_session_with_redo_skip_and_abort_keeps_every_press_once(tmp_path) -> None:
    """Trial 1 is redone after 2 presses, then answers; trial 2 is skipped after 1 press;
    trial 3 is aborted after 2 presses and finished by a second run of the folder."""
    d = tmp_path / "s"
    s = sess.load_session(THREE, IDS)
    calls: list[tuple[str, str | None]] = []
    control = OperatorControl(lambda e: sess.add_event(d, e))

    def run_trial(trial, resume):
        calls.append((trial.id, resume))
        r = d / trial.record_name
        r.mkdir(parents=True, exist_ok=True)
        (r / "config.json").write_text("{}")
        (r / "touches.jsonl").touch()
        control.start(trial.id)
        n = sum(1 for c in calls if c[0] == trial.id)
        act = {("1", 1): "redo", ("2", 1): "skip", ("3", 1): "abort"}.get((trial.id, n))
        _press(r, 2 if act != "skip" else 1)
        if act:
            assert control.request(act, "key" if act != "skip" else "service", "t")[0]
            with pytest.raises(OperatorStop):
                control.gate(1.0, lambda: False)
            control.end()
            if act == "skip":
                res = {"skipped": True, "prediction": None, "touches": 1,
                       "stop_reason": "skipped", "by": "service"}
                (r / "result.json").write_text(json.dumps(res))
                return res
            return {"operator": act, "by": "key", "caller": "t"}
        control.end()
        res = {"prediction": trial.truth[0], "touches": 4 if resume else 2,
               "stop_reason": "confident"}
        (r / "result.json").write_text(json.dumps(res))
        return res

    run = SessionRun(s, d, {"seed": 0}, 60.0)
    assert run.run(_Operator(), run_trial, lambda: False) == 0
    assert calls == [("1", None), ("1", None), ("2", None), ("3", None)]
    old = d / "trial_1.superseded.1"
    assert len((old / "touches.jsonl").read_text().splitlines()) == 2   # kept, not lost
    assert any(json.loads(x)["event"] == "superseded"
               for x in (old / "events.jsonl").read_text().splitlines())
    assert len((d / "trial_1" / "touches.jsonl").read_text().splitlines()) == 2
    assert sess.trial_state(d, s.trials[2]) == "started"        # aborted: resumable
    assert not (d / sess.RESULT_FILE).exists()
    ev = sess.events(d)
    ops = [(e["action"], e["trial"], e["by"]) for e in ev if e["event"] == "operator"]
    assert ops == [("redo", "1", "key"), ("skip", "2", "service"), ("abort", "3", "key")]
    ended = [e for e in ev if e["event"] == "session_ended"]
    assert ended[-1]["aborted"] and ended[-1]["trial"] == "3"
    done2 = [e for e in ev if e["event"] == "trial_done" and e["trial"] == "2"][0]
    assert done2["skipped"] and "skipped" in trial_done_text(done2)
    assert "correct" not in trial_done_text(done2)

    run = SessionRun(s, d, {"seed": 0}, 60.0)             # the resume: trial 3 goes on
    assert run.run(_Operator(), run_trial, lambda: False) == 0
    assert calls[-1] == ("3", str(d / "trial_3"))
    assert len((d / "trial_3" / "touches.jsonl").read_text().splitlines()) == 4
    res = json.loads((d / sess.RESULT_FILE).read_text())
    assert (res["done"], res["skipped"], res["accuracy"]) == (3, 1, 1.0)
    row2 = [r for r in res["trials"] if r["id"] == "2"][0]
    assert row2["skipped"] and row2["correct"] is None

    from tactex_ros.trial.report import session_html
    page = session_html(d)
    assert "class='muted skipped'>skipped<" in page
    assert page.count("class='operator'") == 3
    assert "(2 of 2 trials correct" in page               # the skip is not in the count
    assert sess.accuracy_text(res) == "1.000 (1 skipped)"


def test_the_layout_has_a_button_for_every_action_out_of_editing_mode() -> None:
    from tactex_ros.ros.viewer_layout import CONFIRM_SERVICE, check_layout, foxglove_layout
    lay = foxglove_layout("sim")
    assert check_layout(lay) == []
    cfg = lay["configById"]
    node = CONFIRM_SERVICE.rpartition("/")[0]
    for action in ACTIONS:
        b = cfg[f"CallService!{action}"]
        assert b["serviceName"] == f"{node}/{action}"
        assert b["datatype"] == "std_srvs/srv/Trigger" and b["editingMode"] is False
    assert cfg["CallService!confirm"]["editingMode"] is False
    placed = json.dumps(lay["layout"])
    assert all(f'"CallService!{a}"' in placed for a in ACTIONS)


def test_plot_titles_are_panel_titles_and_a_plain_title_is_named() -> None:
    """Issue 47 item 8: a plot's title is the panel's ``foxglovePanelTitle``; ``title`` (not
    in the current layout model's PlotConfig) is reported as a key Foxglove ignores."""
    from tactex_ros.ros.viewer_layout import PANEL_TITLE, check_layout, foxglove_layout
    lay = foxglove_layout("sim")
    plots = {k: v for k, v in lay["configById"].items() if k.startswith("Plot!")}
    assert plots and all(v.get(PANEL_TITLE) and "title" not in v for v in plots.values())
    lay["configById"]["Plot!belief"]["title"] = "old"
    assert any("'title'" in p for p in check_layout(lay))


def test_progress_counts_this_runs_trials_and_measured_times() -> None:
    from tactex_ros.trial.session_run import progress_text
    summ = {"trials": [{"id": "1", "done": True, "elapsed_s": 100.0},
                       {"id": "2", "done": True, "elapsed_s": 140.0},
                       {"id": "3", "done": False}, {"id": "4", "done": False}]}
    text = progress_text(summ, None, "3")
    assert text.startswith("trial 3: 3 of 4 in this run")
    assert "about 4:00 left (2 trial(s) at 120 s, the mean of 2 done)" in text
    assert progress_text(summ, ["3", "4"], "4").startswith("trial 4: 2 of 2 in this run")
    fresh = {"trials": [{"id": "1", "done": False}]}
    assert progress_text(fresh, None, "1") == "trial 1: 1 of 1 in this run"   # nothing measured
