"""Issue 31: a session folder holds one session and never reports another trial's result: its
identity (session id, trial file hash), its fixed settings and its trial ids' record folders
are checked before the first trial; every refusal names the path (exit status 2, on the
console, before any node starts)."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import pytest

from tactex_ros.cli.main import main
from tactex_ros.core.errors import InputError
from tactex_ros.trial import session as sess

IDS = ["reference", "c1", "c2", "c3", "c4"]
SHORT = Path(__file__).parents[1] / "data" / "session_short.yaml"


def _file(tmp_path: Path, ids: list[str], name: str = "trials.yaml") -> Path:
    p = tmp_path / name
    rows = "".join(f"  - {{id: {json.dumps(i)}, reference: 23, comparisons: [4, 8, 23, 7]}}\n"
                   for i in ids)
    p.write_text("name: s\ntrials:\n" + rows)
    return p


@pytest.mark.parametrize("ids", [["a b", "a_b"], ["é", "ü"], ["x/1", "x?1"]])
def test_trial_ids_that_share_a_record_folder_are_refused(tmp_path, ids) -> None:
    with pytest.raises(InputError) as err:
        sess.load_session(_file(tmp_path, ["1"] + ids), IDS)
    msg = str(err.value)
    assert repr(ids[0]) in msg and repr(ids[1]) in msg and sess.record_name(ids[0]) in msg


def test_a_session_folder_is_fixed_to_its_trial_file_and_settings(tmp_path) -> None:
    s = sess.load_session(SHORT, IDS)
    d = tmp_path / "s"
    settings = {"seed": 0, "config": "default", "strategy": "ucb"}
    assert sess.open_session(d, s, settings) is False
    was = json.loads((d / sess.SESSION_FILE).read_text())
    assert len(was["session_id"]) == 32 and was["trial_file_sha256"] == sess.file_sha256(SHORT)
    assert sess.open_session(d, s, dict(settings)) is True
    with pytest.raises(InputError) as err:              # a resume with other settings
        sess.open_session(d, s, dict(settings, strategy="greedy"))
    assert "'strategy'" in str(err.value) and "'ucb'" in str(err.value) \
        and "'greedy'" in str(err.value)
    # the same trials from another file (another name, a comment): another session
    other = tmp_path / "other.yaml"
    other.write_text("# another file\n" + SHORT.read_text())
    with pytest.raises(InputError, match="SHA-256"):
        sess.open_session(d, sess.load_session(other, IDS), settings)
    assert json.loads((d / sess.SESSION_FILE).read_text()) == was       # nothing changed


@pytest.mark.parametrize("damage", [
    lambda p: p.write_text('{"name": "s", "trials": ['),              # torn
    lambda p: p.write_text("[1, 2]"),                                   # not an object
    lambda p: p.write_text('{"name": "s", "trials": []}'),             # no session id
    lambda p: p.write_text(json.dumps({"session_id": 3, "trial_file_sha256": "x",
                                       "trials": [], "settings": {}})),   # wrong type
])
def test_a_torn_or_foreign_session_json_is_refused_with_its_path(tmp_path, damage) -> None:
    s = sess.load_session(SHORT, IDS)
    d = tmp_path / "s"
    sess.open_session(d, s, {})
    damage(d / sess.SESSION_FILE)
    with pytest.raises(InputError, match=str(d / sess.SESSION_FILE)):
        sess.open_session(d, s, {})
    with pytest.raises(InputError, match=str(d / sess.SESSION_FILE)):
        sess.check_session_dir(d, SHORT)


def test_session_files_without_session_json_are_not_continued(tmp_path) -> None:
    d = tmp_path / "s"
    (d / "trial_1").mkdir(parents=True)
    (d / sess.RESULT_FILE).write_text("{}")
    with pytest.raises(InputError, match="session_result.json"):
        sess.check_session_dir(d, SHORT)
    assert sess.check_session_dir(tmp_path / "new", SHORT) is False
    (tmp_path / "empty").mkdir()
    assert sess.check_session_dir(tmp_path / "empty", SHORT) is False


def _old_session(root: Path) -> Path:
    """A finished session of session_short.yaml: its result on disk."""
    d = root / "old"
    s = sess.load_session(SHORT, IDS)
    sess.open_session(d, s, {"seed": 0})
    sess.finish_session(d, {"name": "old", "done": 2, "total": 2, "accuracy": 1.0,
                            "trials": []})
    return d


def _torn(root: Path) -> tuple[Path, str]:
    d = _old_session(root)
    (d / sess.SESSION_FILE).write_text('{"name": "old", "tri')
    return d, sess.SESSION_FILE


def _other_trial_file(root: Path) -> tuple[Path, str]:
    d = _old_session(root)
    shutil.copy(SHORT, root / "mine.yaml")
    with open(root / "mine.yaml", "a") as f:
        f.write("  - {id: 3, reference: 1, comparisons: [1, 2, 3, 4]}\n")
    return d, "SHA-256"


def _a_file(root: Path) -> tuple[Path, str]:
    (root / "f").write_text("x")
    return root / "f", "is a file"


def _under_a_file(root: Path) -> tuple[Path, str]:
    (root / "f").write_text("x")
    return root / "f" / "s", "is a file"


@pytest.mark.parametrize("case", [_torn, _other_trial_file, _a_file, _under_a_file])
def test_graph_run_session_refuses_before_any_node(tmp_path, capsys, case) -> None:
    d, named = case(tmp_path)
    trial_file = tmp_path / "mine.yaml" if (tmp_path / "mine.yaml").exists() else SHORT
    before = {p: p.read_bytes() for p in tmp_path.rglob("*") if p.is_file()}
    logs = tmp_path / "logs"
    code = main(["graph", "run", "--sim", "--yes", "--log-dir", str(logs), "--timeout", "60",
                 "--session", str(trial_file), "--session-dir", str(d)])
    err = capsys.readouterr().err
    assert code == 2, err
    assert named in err and "Traceback" not in err and "continue with" not in err
    assert not any(logs.rglob("*.log"))                        # no node was started
    assert {p: p.read_bytes() for p in tmp_path.rglob("*") if p.is_file()} == before
