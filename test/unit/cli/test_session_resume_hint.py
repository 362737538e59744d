"""Issue 47, item 1: the hint printed after Ctrl-C in a ``--trials`` session continues the
interrupted trial: run as printed it picks the same trials (so the interrupted one comes first,
not the session's first trial not done) on the same DDS domain, in the same folder."""

from __future__ import annotations

import shlex
from pathlib import Path

from tactex_ros.cli.graph_commands import _nodes, session_resume_hint
from tactex_ros.cli.main import build_parser
from tactex_ros.ros.run_settings import save_run_file
from tactex_ros.trial import session as sess

THREE = Path(__file__).parents[2] / "data" / "session_three.yaml"
IDS = ["reference", "c1", "c2", "c3", "c4"]


def _parsed(argv: list[str]):
    return build_parser("graph").parse_args(argv)


def test_the_hint_resumes_the_same_trials_on_the_same_domain(tmp_path: Path) -> None:
    d = tmp_path / "my session"
    first = _parsed(["graph", "run", "--sim", "--yes", "--session", str(THREE),
                     "--session-dir", str(d), "--trials", "3,2", "--domain-id", "17"])
    _nodes(first)                                       # settings resolved, no node started
    save_run_file(d, first.run)                         # as cmd_session does before any node
    hint = session_resume_hint(d, first)
    words = shlex.split(hint)
    assert words[:3] == ["tactex", "graph", "run"]
    again = _parsed(words[1:])
    _nodes(again)                                       # the record's options put in
    assert Path(again.session_dir) == d and again.domain_id == 17
    s = sess.load_session(THREE, IDS)
    assert sess.select_trials(s, again.trials) == sess.select_trials(s, first.trials) \
        == ["2", "3"]
    assert again.sim and Path(again.session).resolve() == THREE.resolve()


def test_a_whole_session_hint_names_no_trials_and_no_domain(tmp_path: Path) -> None:
    args = _parsed(["graph", "run", "--sim", "--session", str(THREE),
                    "--session-dir", str(tmp_path / "s")])
    again = _parsed(shlex.split(session_resume_hint(tmp_path / "s", args))[1:])
    assert again.trials is None and again.domain_id is None
    assert Path(again.session_dir) == tmp_path / "s"
