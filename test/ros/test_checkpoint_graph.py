"""The CNN learner's checkpoint through the graph: `tactex graph run --sim --config cnn` stopped
with Ctrl-C after two decisions (every node exits 0, also an explorer stopped in the middle of
a training round) leaves `checkpoint.json` (round 2) in the record; `--resume`
restores it (the `resumed` event names the round, no decision before it is made again) and
finishes the trial (exit 0, all rounds)."""

from __future__ import annotations

import json
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from tactex_ros.core.errors import InputError
from tactex_ros.trial.record import read_checkpoint, read_record
from tactex_ros.ros.devrun.launcher import ros_env

pytestmark = [pytest.mark.ros, pytest.mark.slow]

ROUNDS = 4


def _cmd(domain_id: int, args: list[str]) -> list[str]:
    script = Path(sys.executable).parent / "tactex"
    entry = [str(script)] if script.is_file() else [sys.executable, "-P", "-m",
                                                    "tactex_ros.cli.main"]
    return entry + ["graph", "run", "--sim", "--domain-id", str(domain_id),
                    "--timeout", "400"] + args


def _decisions(d: Path) -> int:
    try:
        return len((d / "decisions.jsonl").read_text().splitlines())
    except OSError:
        return 0


def _checkpoint_round(rec: Path) -> int:
    """Round of the record's checkpoint (0: none yet, or being replaced)."""
    try:
        got = read_checkpoint(rec)
    except InputError:
        return 0
    return int(got[0]["round"]) if got else 0


# 68 s of CNN training in the graph (make test-soak); the checkpoint's resume without the graph:
# test/lab/cnn/test_ladder_climbs_to_cnn.py
@pytest.mark.soak
def test_resume_restores_the_learner_checkpoint(tmp_path: Path, domain_id: int,
                                                small_scene: str) -> None:
    rec = tmp_path / "rec" / "t"
    first = subprocess.Popen(_cmd(domain_id, [
        "--scene", small_scene, "--config", "cnn", "--rounds", str(ROUNDS), "--seed", "2", "--record-dir",
        str(rec.parent), "--trial-id", "t", "--log-dir", str(tmp_path / "l1")]),
        env=ros_env(domain_id), stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    end = time.monotonic() + 400
    # the checkpoint is written just after its round's decision: wait for it, not only for
    # the decision (a loaded machine stopped it between the two, one round behind)
    while (_decisions(rec) < 2 or _checkpoint_round(rec) < 2) and first.poll() is None \
            and time.monotonic() < end:
        time.sleep(0.2)
    assert _checkpoint_round(rec) >= 2, first.communicate(timeout=60)
    first.send_signal(signal.SIGINT)
    first.communicate(timeout=120)
    assert first.returncode != 0 and not (rec / "result.json").exists()
    ended = [e for e in read_record(rec, images=False)["events"]
             if e.get("event") == "trial_ended"]
    assert ended and set(ended[-1]["node_exit"].values()) == {0}   # Ctrl-C: a clean stop
    state, after, blob = read_checkpoint(rec)
    k = state["round"]
    assert 2 <= k < ROUNDS and len(blob) > 1000
    on_disk = read_record(rec, images=False)
    assert after <= len(on_disk["touches"])

    again = subprocess.run(_cmd(domain_id, ["--resume", str(rec), "--log-dir",
                                            str(tmp_path / "l2")]),
                           env=ros_env(domain_id), capture_output=True, text=True, timeout=500)
    assert again.returncode == 0, again.stderr
    res = json.loads((rec / "result.json").read_text())
    assert len(res["rounds"]) == ROUNDS and res["stop_reason"] == "rounds"
    resumed = [e for e in read_record(rec, images=False)["events"]
               if e.get("event") == "resumed"]
    assert resumed and resumed[-1]["checkpoint_round"] == k
    assert "Traceback" not in again.stderr
    # each decision once in the record: none before the checkpoint was made again
    assert [d["round"] for d in read_record(rec, images=False)["decisions"]] == \
        list(range(1, ROUNDS + 2))
