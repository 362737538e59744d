"""``tactex trial`` runs through ``trial.run.TrialRun``, as the graph's explorer does: every
run leaves a trial record (config, touches, decisions, result, report), and ``--resume RECORD``
continues an interrupted one to the outcome of the uninterrupted trial, on the simulator and on
recorded presses."""

from __future__ import annotations

import json
from pathlib import Path

import cv2
import numpy as np
import pytest

import tactex_ros.cli.main as cli
from tactex_ros import sources
from tactex_ros.cli.main import main
from tactex_ros.trial.record import read_record, read_result

# wall-clock and where-it-ran fields; the rest of a result is the trial's outcome
_TIMES = ("train_s", "score_s", "choose_s", "decision_s", "cpu_s", "grad_norm")


def _outcome(res: dict) -> dict:
    out = {k: v for k, v in res.items() if k not in ("elapsed_s", "record", "trial_id",
                                                    "resumed")}
    for r in out["rounds"] + [out["final"]]:
        for k in _TIMES:
            r.pop(k, None)
    return out


def _touches(folder: Path) -> list[tuple]:
    """What the record holds of each touch: platform, accepted, the image's pixels."""
    return [(t["platform_id"], t.get("accepted"), None if t.get("array") is None
             else t["array"].tobytes()) for t in read_record(folder)["touches"]]


def _library(root: Path) -> Path:
    """Recorded presses of 4 classes (sensor-sized PNGs, each its own no-contact frame)."""
    rng = np.random.default_rng(1)
    for k, cls in enumerate(("a", "b", "c", "d")):
        (root / cls).mkdir(parents=True)
        base = rng.integers(40 + 30 * k, 90 + 30 * k, (240, 320, 3)).astype(np.uint8)
        for i in range(4):
            noise = rng.integers(0, 60, (240, 320, 3)).astype(np.uint8)
            cv2.imwrite(str(root / cls / f"{i}.png"), cv2.add(base, noise))
    return root


def _stop_after(monkeypatch, touches: int) -> None:
    """The source's trial raises KeyboardInterrupt (Ctrl-C) instead of touch ``touches + 1``."""
    real = sources.open_source

    class Stopping:
        def __init__(self, src):
            self.src = src

        def __getattr__(self, name):
            return getattr(self.src, name)

        def trial(self, classes, seed):
            fn, made = self.src.trial(classes, seed), []

            def touch(platform):
                if len(made) >= touches:
                    raise KeyboardInterrupt
                made.append(platform)
                return fn(platform)
            return touch

    monkeypatch.setattr(sources, "open_source", lambda spec: Stopping(real(spec)))


@pytest.mark.parametrize("source", ["sim:easy", "replay"])
def test_an_interrupted_trial_resumed_from_its_record_ends_as_the_uninterrupted_one(
        tmp_path: Path, monkeypatch, source: str, capsys) -> None:
    if source == "replay":
        source = f"replay:{_library(tmp_path / 'lib')}"
    common = ["trial", "--source", source, "--seed", "3", "--rounds", "6", "--quiet",
              "--set", "trial.stop_confidence=0", "--record-dir", str(tmp_path / "r")]
    assert main(common + ["--trial-id", "whole", "--json", str(tmp_path / "whole.json")]) == 0
    whole = json.loads((tmp_path / "whole.json").read_text())
    assert whole["touches"] > 7                          # rounds beyond the baseline

    with monkeypatch.context() as m:
        _stop_after(m, 7)
        assert main(common + ["--trial-id", "cut"]) == 130
    cut = tmp_path / "r" / "cut"
    assert read_result(cut) is None and len(read_record(cut)["touches"]) == 7
    html = (cut / "report.html").read_text()             # the report says how to go on
    assert f"id='resume-command'>tactex trial --resume {cut}<" in html
    capsys.readouterr()

    # a resume takes every option and setting from the record: a contradiction is refused
    assert main(["trial", "--resume", str(cut), "--seed", "4"]) == 2
    assert "seed" in capsys.readouterr().err
    assert len(read_record(cut)["touches"]) == 7          # nothing touched

    assert main(["trial", "--resume", str(cut), "--quiet",
                 "--json", str(tmp_path / "resumed.json")]) == 0
    resumed = json.loads((tmp_path / "resumed.json").read_text())
    assert resumed["resumed"] and resumed["record"] == str(cut.resolve())
    assert _outcome(resumed) == _outcome(whole)           # same prediction, beliefs, touches
    assert _touches(cut) == _touches(tmp_path / "r" / "whole")
    assert read_result(cut)["prediction"] == whole["prediction"]
    assert (cut / "report.html").is_file()
    # the record is finished: nothing left to resume
    assert main(["trial", "--resume", str(cut), "--quiet"]) == 2


def test_a_plain_run_leaves_a_record(tmp_path: Path) -> None:
    out = tmp_path / "t.json"
    assert main(["trial", "--source", "sim:easy", "--rounds", "2", "--quiet",
                 "--json", str(out)]) == 0
    res = json.loads(out.read_text())
    d = Path(res["record"])
    assert d.parent == Path(cli.DEFAULT_RECORD_DIR).resolve() and d.name == res["trial_id"]
    assert read_result(d) == res
    rec = read_record(d, images=False)
    assert len([t for t in rec["touches"] if t["accepted"]]) == res["touches"]
    assert len(rec["decisions"]) == len(res["rounds"]) + 1
    cfg = json.loads((d / "config.json").read_text())
    assert cfg["cli"]["source"] == "sim:easy" and cfg["trial"]["rounds"] == 2
    assert (d / "report.html").is_file()
    # a second run in the same second gets a record of its own
    assert main(["trial", "--source", "sim:easy", "--rounds", "2", "--quiet",
                 "--json", str(out)]) == 0
    assert json.loads(out.read_text())["record"] != res["record"]
