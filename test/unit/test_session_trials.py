"""Issue 29: ``--trials`` (the explorer's ``trials``, launch ``trials:=``) runs part of a
session: an unknown id is refused before anything starts with the session's ids (exit 2), the
session's events say which trials were asked for, and a later run of the same folder with
other trials (or none: every trial left) continues the session; the ones done stay done."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from tactex_ros.cli.main import main
from tactex_ros.core.errors import InputError
from tactex_ros.trial import session as sess
from tactex_ros.trial.session_run import SessionRun

IDS = ["reference", "c1", "c2", "c3", "c4"]
THREE = Path(__file__).parents[1] / "data" / "session_three.yaml"


def test_select_trials_keeps_the_session_order_and_refuses_unknown_ids() -> None:
    s = sess.load_session(THREE, IDS)
    assert sess.select_trials(s, "") is None and sess.select_trials(s, "  ") is None
    for text in (",", " , ", "1,,3"):          # an empty id is not "every trial" (issue 49)
        with pytest.raises(InputError, match="empty id"):
            sess.select_trials(s, text)
    assert sess.select_trials(s, "3, 1") == ["1", "3"]
    with pytest.raises(InputError) as err:
        sess.select_trials(s, "1,7")
    assert "'7'" in str(err.value) and "1, 2, 3" in str(err.value)


def test_graph_run_refuses_an_unknown_trial_before_any_node(tmp_path, capsys) -> None:
    logs = tmp_path / "logs"
    code = main(["graph", "run", "--sim", "--yes", "--log-dir", str(logs), "--timeout", "60",
                 "--session", str(THREE), "--session-dir", str(tmp_path / "s"),
                 "--trials", "2,x"])
    err = capsys.readouterr().err
    assert code == 2 and "'x'" in err and "1, 2, 3" in err and "Traceback" not in err
    assert not logs.exists() and not (tmp_path / "s").exists()
    code = main(["graph", "run", "--sim", "--yes", "--log-dir", str(logs), "--timeout", "60",
                 "--trials", "1"])                       # no session to pick from
    assert code == 2 and "session" in capsys.readouterr().err


class _Operator:
    """Confirms every placement at once; remembers what it was told."""

    def __init__(self) -> None:
        self.told: list[str] = []

    def expect(self, trial_id: str) -> None:
        pass

    def tell(self, text: str) -> None:
        self.told.append(text)

    def wait(self):
        return "yes_flag", "test"

    def place(self, trial) -> None:
        pass


def _run(d: Path, only, ran: list[str]) -> int:
    """One run of the session in ``d`` whose trials write a record with a result at once."""
    def run_trial(trial, resume):
        ran.append(trial.id)
        r = d / trial.record_name
        r.mkdir(parents=True, exist_ok=True)
        (r / "config.json").write_text("{}")
        (r / "result.json").write_text(json.dumps({"prediction": trial.truth[0],
                                                   "touches": 3, "stop_reason": "rounds"}))
        return {"prediction": trial.truth[0], "touches": 3}
    s = sess.load_session(THREE, IDS)
    run = SessionRun(s, d, {"seed": 0}, 60.0, only=sess.select_trials(s, only))
    return run.run(_Operator(), run_trial, lambda: False)


def test_a_part_of_a_session_then_the_rest_from_the_same_folder(tmp_path) -> None:
    d, ran = tmp_path / "s", []
    assert _run(d, "2", ran) == 0 and ran == ["2"]
    assert not (d / sess.RESULT_FILE).exists()            # the session is not done
    ev = sess.events(d)
    assert ev[0]["event"] == "started" and ev[0]["trials_asked"] == ["2"]
    part = [e for e in ev if e["event"] == "part_done"]
    assert part and part[-1]["done"] == 1 and part[-1]["of"] == 3
    assert [sess.trial_state(d, t) for t in sess.load_session(THREE, IDS).trials] == \
        ["pending", "done", "pending"]
    assert _run(d, "1,2", ran) == 0 and ran == ["2", "1"]  # 2 stays done: not run again
    assert _run(d, "", ran) == 0 and ran == ["2", "1", "3"]
    res = json.loads((d / sess.RESULT_FILE).read_text())
    assert res["done"] == 3 and res["accuracy"] == 1.0
    asked = [e["trials_asked"] for e in sess.events(d) if e["event"] in ("started", "resumed")]
    assert asked == [["2"], ["1", "2"], None]


def test_the_session_reports_continue_command_keeps_the_interrupted_part(tmp_path) -> None:
    """The report of a session stopped in trial 3 of ``--trials 2,3`` continues with those
    trials; once they are done, with the rest (no ``--trials``)."""
    import html as _html
    import re
    import shlex

    from tactex_ros.trial.report import session_html
    from tactex_ros.trial.session_run import SessionRun

    d = tmp_path / "s"
    s = sess.load_session(THREE, IDS)

    def run_trial(trial, resume):
        r = d / trial.record_name
        r.mkdir(parents=True, exist_ok=True)
        (r / "config.json").write_text("{}")
        if trial.id == "3":
            return None                           # Ctrl-C in trial 3
        (r / "result.json").write_text(json.dumps({"prediction": trial.truth[0],
                                                   "touches": 3, "stop_reason": "confident"}))
        return {"prediction": trial.truth[0], "touches": 3}

    def command() -> list[str]:
        got = re.search(r"id='resume-command'>([^<]*)<", session_html(d)).group(1)
        return shlex.split(_html.unescape(got))

    SessionRun(s, d, {"seed": 0}, 60.0, only=sess.select_trials(s, "2,3")).run(
        _Operator(), run_trial, lambda: True)
    words = command()
    assert words[words.index("--trials") + 1] == "2,3"
    assert Path(words[words.index("--session-dir") + 1]) == d.resolve()
    (d / s.trials[2].record_name / "result.json").write_text(json.dumps(
        {"prediction": "c1", "touches": 3, "stop_reason": "confident"}))
    SessionRun(s, d, {"seed": 0}, 60.0, only=sess.select_trials(s, "2,3")).run(
        _Operator(), run_trial, lambda: False)
    assert "--trials" not in command()                  # trial 1 left: every trial left
