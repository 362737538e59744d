"""Replay source and `tactex trial` end to end on the real octopi-dev recordings."""

import json

import cv2
import numpy as np
import pytest

from tactex_ros.cli.main import main
from tactex_ros.core.contact import strongest_contact
from tactex_ros.sources.replay import ReplaySource, load_press


def _frames_of(path):
    cap = cv2.VideoCapture(str(path))
    out = []
    while True:
        ok, f = cap.read()
        if not ok:
            break
        out.append(f)
    return np.stack(out)


def test_contact_frame_is_chosen_deliberately(octopi_dir):
    path = sorted((octopi_dir / "basket").glob("*.mov"))[0]
    frames = _frames_of(path)
    idx, scores = strongest_contact(frames)
    assert 5 < idx < len(frames) - 5          # contact is mid-press, not the first frames
    assert scores[idx] > 3 * np.median(scores[:3] + 1e-3)
    assert scores[idx] >= np.percentile(scores, 90)
    img, score = load_press(str(path))
    assert img.shape == (240, 320, 3) and img.dtype == np.uint8
    np.testing.assert_array_equal(img, cv2.cvtColor(frames[idx], cv2.COLOR_BGR2RGB))


def test_trial_draws_unused_presses_and_keeps_reference_press_out(octopi_dir):
    src = ReplaySource(octopi_dir)
    assert len(src.classes) == 26
    n = len(src.presses("sponge"))
    trial = src.trial(["sponge", "rice", "sponge", "wires"], seed=3)
    trial(0)
    ref_file = trial.log[0][1]
    for _ in range(n - 1):
        trial(2)
    files = [f for p, f in trial.log if p == 2]
    assert len(set(files)) == n - 1 and ref_file not in files  # all fresh, no leak
    trial(2)  # exhausted: cycles, still not the reference press
    assert trial.log[-1][1] != ref_file


def test_bad_replay_inputs_exit_2(tmp_path, octopi_dir, capsys):
    assert main(["trial", "--source", f"replay:{tmp_path / 'nope'}"]) == 2
    assert "does not exist" in capsys.readouterr().err
    assert main(["trial", "--source", f"replay:{tmp_path}"]) == 2
    bad = tmp_path / "broken"
    for c in ("a", "b"):
        (bad / c).mkdir(parents=True)
        (bad / c / "0.mov").write_bytes(b"\x00" * 100)
    assert main(["trial", "--source", f"replay:{bad}", "--comparisons", "2"]) == 2
    assert "0.mov" in capsys.readouterr().err
    src = f"replay:{octopi_dir}"
    assert main(["trial", "--source", src, "--strategy", "greedy"]) == 2
    assert "greedy" in capsys.readouterr().err
    assert main(["trial", "--source", src, "--model", "resnet50"]) == 2
    assert "resnet50" in capsys.readouterr().err
    assert main(["trial", "--source", src, "--classes", "rice,marble"]) == 2
    assert "marble" in capsys.readouterr().err


@pytest.mark.slow
def test_default_trial_command_and_json(tmp_path, octopi_dir):
    """Exactly the owners' command (no other flags): the default stops on its belief and
    writes the fields they read."""
    out = tmp_path / "trial.json"
    assert main(["trial", "--source", f"replay:{octopi_dir}", "--comparisons", "4",
                 "--seed", "3", "--json", str(out)]) == 0
    d = json.loads(out.read_text())
    assert d["model"] == "descriptor" and d["strategy"] == "infogain"
    assert d["correct"] == (d["prediction"] == d["truth"])
    assert d["touches"] == 5 + len(d["rounds"])
    assert d["stop_reason"] in {"confident", "rounds"}
    if d["stop_reason"] == "confident":
        assert max(d["final"]["probs"]) >= 0.9
    for r in d["rounds"]:
        assert r["platform"] in {"reference", "c1", "c2", "c3", "c4"}
        assert len(r["probs"]) == 4 and abs(sum(r["probs"]) - 1) < 1e-6
        assert len(r["scores"]) == 5 and r["detail"] is None and r["score_s"] > 0
        assert max(r["probs"]) < 0.9           # it would have stopped otherwise
