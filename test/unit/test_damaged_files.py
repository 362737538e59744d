"""Issue 31, item 6: damaged record, session and representation files are refused with the
file and the field named (exit status 2), never a traceback."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from tactex_ros.cli.main import main
from tactex_ros.trial import session as sess
from tactex_ros.trial.record import TrialRecord

IDS = ["reference", "c1", "c2", "c3", "c4"]
SHORT = Path(__file__).parents[1] / "data" / "session_short.yaml"


def _trial(root: Path, name: str = "t") -> Path:
    rec = TrialRecord(root, name, min_free_mb=0)
    rec.save_inputs(None, {"trial": {"strategy": "ucb", "stop_confidence": 0.9}})
    rec.add_touch(np.zeros((4, 4, 3), np.uint8), {"platform_id": "c1", "platform_index": 1,
                                                  "accepted": True})
    rec.add_decision({"round": 1, "next": "c2", "belief": [0.4, 0.2, 0.2, 0.2],
                      "touches": [1, 0, 0, 0], "done": True, "prediction": "c1"})
    rec.finish({"prediction": "c1", "touches": 1, "stop_reason": "confident"})
    return rec.dir


def _session(root: Path) -> Path:
    d = root / "s"
    s = sess.load_session(SHORT, IDS)
    sess.open_session(d, s, {"seed": 0})
    for t in s.trials:
        _trial(d, t.record_name)
    return d


def _edit_json(p: Path, fn) -> None:
    doc = json.loads(p.read_text())
    fn(doc)
    p.write_text(json.dumps(doc))


CASES = [
    ("result touches a string", _trial,
     lambda d: _edit_json(d / "result.json", lambda r: r.update(touches="six")),
     "result.json", "'touches'"),
    ("result a list", _trial, lambda d: (d / "result.json").write_text("[1]"),
     "result.json", "object"),
    ("touch line seq a string", _trial,
     lambda d: (d / "touches.jsonl").write_text('{"seq": "1", "image": null}\n'),
     "touches.jsonl", "'seq'"),
    ("decision belief strings", _trial,
     lambda d: (d / "decisions.jsonl").write_text('{"round": 1, "belief": ["a", "b"]}\n'),
     "decisions.jsonl", "'belief'"),
    ("config trial a string", _trial,
     lambda d: _edit_json(d / "config.json", lambda c: c.update(trial="ucb")),
     "config.json", "'trial'"),
    ("torn session.json", _session,
     lambda d: (d / "session.json").write_text('{"name": "s", "tr'), "session.json", "torn"),
    ("session without trials", _session,
     lambda d: _edit_json(d / "session.json", lambda s: s.pop("trials")),
     "session.json", "trials"),
    ("session trial placement a list", _session,
     lambda d: _edit_json(d / "session.json",
                          lambda s: s["trials"][0].update(placement=["a"])),
     "session.json", "'placement'"),
    ("session trial truth numbers", _session,
     lambda d: _edit_json(d / "session.json", lambda s: s["trials"][1].update(truth=[3])),
     "session.json", "'truth'"),
    ("session trial result prediction a number", _session,
     lambda d: _edit_json(d / "trial_1" / "result.json", lambda r: r.update(prediction=3)),
     "result.json", "'prediction'"),
]


@pytest.mark.parametrize("name, make, damage, file, field", CASES, ids=[c[0] for c in CASES])
def test_report_refuses_damaged_files_naming_file_and_field(tmp_path, capsys, name, make,
                                                             damage, file, field) -> None:
    d = make(tmp_path)
    assert main(["report", str(d)]) == 0
    capsys.readouterr()
    damage(d)
    assert main(["report", str(d)]) == 2
    err = capsys.readouterr().err
    assert file in err and field in err and "Traceback" not in err


@pytest.mark.parametrize("field, value, words", [
    ("temperature", np.array("hot"), ["'temperature'", "number"]),
    ("shrink", np.array([1.0, 2.0]), ["'shrink'", "shape"]),
    ("mean", np.array(["a"] * 4), ["'mean'"]),
    ("calibration", np.array("[1, 2]"), ["'calibration'", "object"]),
])
def test_representation_with_wrong_types_is_refused(tmp_path, field, value, words) -> None:
    from tactex_ros.core import representation as rep
    from tactex_ros.core.errors import InputError
    rng = np.random.default_rng(0)
    r = rep.fit({f"f{k}": rng.normal(size=(4, rep.DIM)) for k in range(3)})
    p = rep.save(r, tmp_path / "r.npz")
    with np.load(p) as z:
        d = {k: z[k] for k in z.files}
    d[field] = value
    np.savez(p, **d)
    with pytest.raises(InputError) as err:
        rep.load(p)
    assert str(p) in str(err.value)
    for w in words:
        assert w in str(err.value)
