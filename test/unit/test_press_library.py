"""Issue 51: a lab's library pressed by the robot (``trial/press_library.py``) without ROS: the
press files are what ``replay:DIR`` reads (the contact frame, the no-contact frame and the
further in-contact frames come back bit for bit), ``tactex prepare`` takes the folder, a run
cut off keeps every press and the next one presses only what is missing, a press the contact
guard refuses is pressed again, and a foreign folder or a bad name is refused (exit 2)."""

from __future__ import annotations

import numpy as np
import pytest

from tactex_ros.cli.main import main
from tactex_ros.core.errors import InputError
from tactex_ros.core.guards import press_verdict
from tactex_ros.core.touch import Touch
from tactex_ros.trial import press_library as plib
from tactex_ros.trial.control import OperatorStop


class _Operator:
    """Confirms every placement at once; remembers what it was told and placed."""

    def __init__(self) -> None:
        self.told: list[str] = []
        self.placed: list[dict] = []

    def expect(self, trial_id: str) -> None:
        pass

    def tell(self, text: str) -> None:
        self.told.append(text)

    def wait(self):
        return "yes_flag", "test"

    def place(self, trial) -> None:
        self.placed.append(dict(trial.placement))


class _Press:
    """Simulated presses of whatever the operator placed last (sim renderer, RGB)."""

    def __init__(self, op: _Operator, blank: int = 0) -> None:
        from tactex_ros.sources import open_source
        self.src, self.op, self.blank = open_source("sim"), op, blank
        self.rng = np.random.default_rng(0)
        self.nc = self.src.renderer.no_contact(self.rng)
        self.calls = 0
        self.made: list[Touch] = []

    def __call__(self, meta: dict) -> Touch:
        self.calls += 1
        meta["force_n"] = 4.0
        if self.blank:                  # a press without contact: the guard refuses it
            self.blank -= 1
            return Touch(self.nc.copy(), self.nc)
        fabric = next(iter(self.op.placed[-1].values()))
        frames = [self.src.press(fabric, self.rng, depth_mm=d) for d in (0.4, 0.35, 0.3)]
        t = Touch(frames[0], self.nc, extra=np.stack(frames[1:]))
        self.made.append(t)
        return t


def _accept(touch: Touch) -> tuple[bool, str]:
    return press_verdict(touch)


def test_a_press_file_replays_bit_for_bit_and_prepare_takes_the_library(tmp_path) -> None:
    from tactex_ros.sources.replay import ReplaySource, load_touch
    out = tmp_path / "lib"
    op = _Operator()
    press = _Press(op)
    run = plib.LibraryPressing(out, ["denim", "satin"], 3, "reference", sim=True)
    assert run.run(op, press, lambda: False, accept=_accept) == 0
    assert plib.counts(out, ["denim", "satin"]) == {"denim": 3, "satin": 3}
    assert op.placed == [{"reference": "denim"}, {"reference": "satin"}]
    src = ReplaySource(out)                   # .logs or .superseded are no class
    (out / ".logs").mkdir()
    assert src.classes == ["denim", "satin"] == ReplaySource(out).classes
    back, score = load_touch(str(plib.press_files(out, "satin")[2]))
    t = press.made[5]
    assert np.array_equal(back.frame, t.frame) and np.array_equal(back.no_contact, t.no_contact)
    assert back.extra is not None and len(back.extra) == 2 and score > 0.8
    assert {tuple(x.reshape(-1)[:64]) for x in back.extra} == \
        {tuple(x.reshape(-1)[:64]) for x in t.extra}
    saved = [e for e in plib.events(out) if e["event"] == "press_saved"]
    assert [(e["trial"], e["press"]) for e in saved] == [("denim", 1), ("denim", 2),
                                                         ("denim", 3), ("satin", 1),
                                                         ("satin", 2), ("satin", 3)]
    assert saved[0]["meta"]["force_n"] == 4.0
    npz = tmp_path / "lab.npz"
    assert main(["prepare", "--library", f"replay:{out}", "--out", str(npz)]) == 0
    from tactex_ros.core import representation
    rep = representation.load(str(npz))
    assert rep.classes == 2 and rep.presses == 6


def test_a_run_cut_off_keeps_its_presses_and_the_next_makes_only_the_missing(tmp_path) -> None:
    out = tmp_path / "lib"
    op = _Operator()
    press = _Press(op)
    stop_after = {"n": 3}

    def stopping() -> bool:
        return press.calls >= stop_after["n"]
    assert plib.LibraryPressing(out, ["denim", "satin"], 2, "c1").run(
        op, press, stopping, accept=_accept) == 0        # stopped: resumable, no result
    assert plib.counts(out, ["denim", "satin"]) == {"denim": 2, "satin": 1}
    assert not (out / plib.RESULT_FILE).exists()
    op2, calls = _Operator(), press.calls
    press.op = op2
    again = plib.LibraryPressing(out, ["denim", "satin"], 2, "c1")
    assert again.resumed and again.run(op2, press, lambda: False, accept=_accept) == 0
    assert press.calls - calls == 1 and again.made == 1     # only satin's second press
    assert op2.placed == [{"c1": "satin"}]                   # asked again for satin only
    assert plib.counts(out, ["denim", "satin"]) == {"denim": 2, "satin": 2}
    res = (out / plib.RESULT_FILE).read_text()
    assert '"complete": true' in res


def test_a_press_without_contact_is_pressed_again_and_too_many_end_the_run(tmp_path) -> None:
    out = tmp_path / "lib"
    op = _Operator()
    press = _Press(op, blank=2)
    assert plib.LibraryPressing(out, ["linen"], 2, "reference").run(
        op, press, lambda: False, accept=_accept) == 0
    assert press.calls == 4 and plib.counts(out, ["linen"]) == {"linen": 2}
    refused = [e for e in plib.events(out) if e["event"] == "press_refused"]
    assert [e["in_a_row"] for e in refused] == [1, 2]
    out2 = tmp_path / "lib2"
    press = _Press(op, blank=plib.MAX_FAILED)
    assert plib.LibraryPressing(out2, ["linen"], 2, "reference").run(
        op, press, lambda: False, accept=_accept) == 1
    assert press.calls == plib.MAX_FAILED and plib.counts(out2, ["linen"]) == {"linen": 0}


def test_redo_sets_the_presses_aside_and_skip_moves_on(tmp_path) -> None:
    out = tmp_path / "lib"
    op = _Operator()
    inner = _Press(op)
    asked = iter([None, "redo", None, None, "skip"])

    def press(meta: dict) -> Touch:
        action = next(asked)
        if action:
            raise OperatorStop(action, "key", "")
        return inner(meta)
    assert plib.LibraryPressing(out, ["denim", "satin"], 2, "reference").run(
        op, press, lambda: False, accept=_accept) == 0
    assert plib.counts(out, ["denim", "satin"]) == {"denim": 2, "satin": 0}
    assert len(list((out / ".superseded" / "denim.1").glob("press_*"))) == 1
    kinds = [e["event"] for e in plib.events(out)]
    assert "superseded" in kinds and "material_skipped" in kinds
    assert '"complete": false' in (out / plib.RESULT_FILE).read_text()


def test_bad_names_counts_and_foreign_folders_are_refused(tmp_path, capsys) -> None:
    for text, why in (("", "give the materials"), ("a,,b", "empty"), ("a,a", "twice"),
                      ("a/b", "'/'"), (".x", "hidden"), (" a ", None)):
        if why is None:
            assert plib.parse_materials(text) == ["a"]
            continue
        with pytest.raises(InputError, match=why):
            plib.parse_materials(text)
    with pytest.raises(InputError, match="denim, gabardine"):      # the allowed ones named
        plib.parse_materials("cork", ["denim", "gabardine"])
    for bad in (0, 1001, True):
        with pytest.raises(InputError, match="1..1000"):
            plib.check_presses(bad)
    foreign = tmp_path / "foreign"
    foreign.mkdir()
    (foreign / "notes.txt").write_text("mine")
    with pytest.raises(InputError, match="not empty"):
        plib.check_library_dir(foreign, sim=False)
    (tmp_path / "empty").mkdir()
    assert plib.open_library(tmp_path / "empty", sim=True) is False
    with pytest.raises(InputError, match="never mix"):             # simulated vs robot
        plib.check_library_dir(tmp_path / "empty", sim=False)
    assert plib.check_library_dir(tmp_path / "empty", sim=True) is True
    # at the command's edge: exit 2, nothing written, no node started
    code = main(["graph", "library", "--sim", "--materials", "denim,cork", "--presses", "2",
                 "--out", str(tmp_path / "new")])
    err = capsys.readouterr().err
    assert code == 2 and "cork" in err and "gabardine" in err and "Traceback" not in err
    code = main(["graph", "library", "--sim", "--materials", "denim", "--presses", "2",
                 "--out", str(foreign)])
    assert code == 2 and "not empty" in capsys.readouterr().err
    code = main(["graph", "library", "--sim", "--materials", "denim", "--presses", "2",
                 "--platform", "c9", "--out", str(tmp_path / "new")])
    assert code == 2 and "reference, c1" in capsys.readouterr().err
    assert not (tmp_path / "new").exists()
    assert [f.name for f in foreign.iterdir()] == ["notes.txt"]
