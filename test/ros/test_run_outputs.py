"""Issue 49, items 1 and 6, on real processes. A run refused because its record folder holds
another run's trial leaves that record as it was (no false ``trial_ended``), while a run that
fails on its own record notes how it ended there. A per-file size limit (``ulimit -f``) that
the touch images pass and the MCAP copy and report.html do not: ``tactex graph run`` exits 1
with both files named on the console and no success line; the trial's result is on disk."""

from __future__ import annotations

import json
import resource
import subprocess
import sys
from pathlib import Path

import pytest

from tactex_ros.core.paths import config_dir
from tactex_ros.ros.graph import describe
from tactex_ros.ros.devrun.launcher import ros_env, run_graph
from tactex_ros.trial.record import TrialRecord, read_record

pytestmark = [pytest.mark.ros]


def _explorer(record_dir: Path, trial_id: str, **more) -> list:
    return [n for n in describe(True, str(config_dir() / "scene_sim.yaml"),
                                explorer={"record_dir": str(record_dir), "trial_id": trial_id,
                                          **more})
            if n.executable == "explorer_node"]


def test_a_refused_run_leaves_the_record_of_another_run_alone(tmp_path: Path,
                                                              domain_id: int) -> None:
    done = TrialRecord(tmp_path, "t", min_free_mb=0)      # another run's finished trial
    done.save_inputs(config_dir() / "scene_sim.yaml", {"explorer": {"run_id": "another"}})
    done.finish({"prediction": "c1", "touches": 5, "stop_reason": "confident"})
    events = done.dir / "events.jsonl"
    refused = run_graph(_explorer(tmp_path, "t"), tmp_path / "logs", timeout_s=120,
                        domain_id=domain_id)
    assert refused.node_exit["explorer"] == 2 and refused.failure is not None
    assert "already exists" in (refused.reason or "")
    assert not events.exists()                  # was: a trial_ended of the refused run
    # a run that fails on its own record says there how it ended
    own = run_graph(_explorer(tmp_path, "u", server_timeout_s=2.0), tmp_path / "logs2",
                    timeout_s=120, domain_id=domain_id)
    assert own.node_exit["explorer"] == 1, own.reason
    ended = [e for e in read_record(tmp_path / "u", images=False)["events"]
             if e["event"] == "trial_ended"]
    assert len(ended) == 1 and ended[0]["node_exit"]["explorer"] == 1


LIMIT = 400_000    # [bytes] above a touch image (PNG, 80-100 kB), below the MCAP copy (raw
#                    images, ~1.4 MB a touch) and the trial's self-contained report.html


@pytest.mark.slow
def test_a_file_size_limit_on_the_mcap_copy_and_the_report_ends_the_run_named(
        tmp_path: Path, domain_id: int, quick_scene: str) -> None:
    def limit() -> None:
        resource.setrlimit(resource.RLIMIT_FSIZE,
                           (LIMIT, resource.getrlimit(resource.RLIMIT_FSIZE)[1]))
    script = Path(sys.executable).parent / "tactex"
    entry = [str(script)] if script.is_file() else [sys.executable, "-P", "-m",
                                                    "tactex_ros.cli.main"]
    rec = tmp_path / "t"
    p = subprocess.run(entry + ["graph", "run", "--sim", "--scene", quick_scene, "--rounds",
                                "1", "--record-dir", str(tmp_path), "--trial-id", "t",
                                "--log-dir", str(tmp_path / "logs"),
                                "--set", "trial.stop_confidence=0.0"],
                       env=ros_env(domain_id), capture_output=True, text=True, timeout=900,
                       preexec_fn=limit)
    assert p.returncode == 1, (p.stdout, p.stderr[-3000:])        # was 0, nothing said
    assert "reference matches" not in p.stdout
    assert str(rec / "topics.mcap") in p.stderr and str(rec / "report.html") in p.stderr, \
        p.stderr[-3000:]
    assert "File too large" in p.stderr
    res = json.loads((rec / "result.json").read_text())
    assert "error" not in res and res["touches"] == 6                # nothing lost
    assert max(f.stat().st_size for f in rec.glob("touch_*.png")) < LIMIT
