"""Issue 47 item 9, on the graph: a simulated 3-trial session held through the explorer's
operator services (``std_srvs/srv/Trigger`` ``/explorer/pause|resume|skip|redo``): trial 1
paused (no new press while paused) and resumed, trial 2 skipped, trial 3 redone. Every press
is recorded once (in the trial's record, or in the superseded record of a redo), each action
is in the session's events with who asked, and the session ends with its result."""

from __future__ import annotations

import json
import os
import threading
import time
from pathlib import Path

import pytest

from tactex_ros.ros.devrun.session_runner import run_session
from tactex_ros.ros.graph import describe
from tactex_ros.trial import session as sess
from tactex_ros.trial.record import read_record

pytestmark = [pytest.mark.ros, pytest.mark.slow]

THREE = Path(__file__).parents[1] / "data" / "session_three_small.yaml"   # 1 + 2 platforms


def _lines(f: Path) -> int:
    return len(f.read_text().splitlines()) if f.is_file() else 0


def test_pause_resume_skip_and_redo_through_the_services(tmp_path: Path, domain_id, listener,
                                                         small_scene: str) -> None:
    from std_srvs.srv import Trigger
    d = tmp_path / "sess"
    nodes = describe(True, small_scene, explorer={
        "trial": {"rounds": 2, "stop_confidence": 0.0}, "seed": 3,
        "record_dir": str(tmp_path), "session_file": str(THREE)})
    seen: dict = {"answers": []}
    lst = listener
    from std_msgs.msg import String

    from tactex_ros.ros import adapter
    from tactex_ros.ros.settings import PROGRESS_TOPIC
    progress = lst.collect(String, PROGRESS_TOPIC, adapter.latched_qos())

    def call(action: str) -> None:
        cli = lst.node.create_client(Trigger, f"/explorer/{action}")
        assert cli.wait_for_service(timeout_sec=60.0)
        fut = cli.call_async(Trigger.Request())
        end = time.monotonic() + 30.0
        while not fut.done() and time.monotonic() < end:
            time.sleep(0.05)
        seen["answers"].append((action, fut.done() and fut.result().success))

    def wait_touches(f: Path, n: int, deadline: float) -> int:
        while _lines(f) < n:
            assert time.monotonic() < deadline, f"{f}: fewer than {n} touches"
            time.sleep(0.05)
        return _lines(f)

    def drive(graph) -> None:
        def watch() -> None:
            try:
                end = time.monotonic() + 800
                t1 = d / "trial_1" / "touches.jsonl"
                wait_touches(t1, 1, end)
                call("pause")
                time.sleep(5.0)             # the press under way ends, then nothing
                held = _lines(t1)
                time.sleep(6.0)
                seen["while_paused"] = (held, _lines(t1))
                call("resume")
                wait_touches(d / "trial_2" / "touches.jsonl", 1, end)
                call("skip")
                t3 = d / "trial_3" / "touches.jsonl"
                wait_touches(t3, 1, end)
                call("redo")
            except AssertionError as exc:
                seen["error"] = str(exc)
        threading.Thread(target=watch, daemon=True).start()

    lines: list[str] = []
    run = run_session(nodes, tmp_path / "logs", d, confirm="yes", timeout_s=900,
                      domain_id=domain_id, on_start=drive,
                      out=lambda text, kind: lines.append(text))
    assert "error" not in seen, seen
    said = [m.data for m in progress]
    assert [t.split(":")[0] for t in said] == ["trial 1", "trial 2", "trial 3", "trial 3"]
    assert all("of 3 in this run" in t for t in said) and "left" in said[-1], said
    ready = [k for k, t in enumerate(lines) if t.startswith("ready: every node is active")]
    assert len(ready) == 1, lines                  # one ready line, the whole session
    prompts = [k for k, t in enumerate(lines) if t.endswith("): place")]
    assert prompts and ready[0] < prompts[0], lines   # ready, then the first placement
    shown = [t for t in lines if t.startswith("trial ") and " by service" in t]
    assert len(shown) == 4, lines                  # each action shown in the terminal
    assert run.result is not None, (run.failure, tmp_path / "logs" / "explorer.log")
    assert seen["answers"] == [("pause", True), ("resume", True), ("skip", True),
                               ("redo", True)]
    held, later = seen["while_paused"]
    assert later == held                         # no press started while paused
    assert (run.result["done"], run.result["skipped"]) == (3, 1)
    ev = sess.events(d)
    ops = [(e["action"], e["trial"], e["by"]) for e in ev if e["event"] == "operator"]
    assert ops == [("pause", "1", "service"), ("resume", "1", "service"),
                   ("skip", "2", "service"), ("redo", "3", "service")]
    old = d / "trial_3.superseded.1"
    assert [e["record"] for e in ev if e["event"] == "superseded"] == [old.name]
    for rec_dir in (d / "trial_1", d / "trial_2", old, d / "trial_3"):
        rec = read_record(rec_dir, images=False)
        seqs = [t["seq"] for t in rec["touches"]]
        assert seqs and seqs == list(range(1, len(seqs) + 1)), rec_dir  # each press once
    res1 = json.loads((d / "trial_1" / "result.json").read_text())
    rec1 = read_record(d / "trial_1", images=False)
    assert res1["touches"] == sum(bool(t.get("accepted")) for t in rec1["touches"])
    assert res1.get("paused_s", 0) > 5.0           # the pause is not the trial's time
    assert json.loads((d / "trial_2" / "result.json").read_text())["skipped"] is True
    assert "prediction" in json.loads((d / "trial_3" / "result.json").read_text())
    t1_ops = [e["action"] for e in rec1["events"] if e.get("event") == "operator"]
    assert t1_ops == ["pause", "resume"]          # in the trial's events too
    page = (d / sess.REPORT_FILE).read_text()
    assert page.count("class='operator'") == 4 and "skipped" in page
    assert os.path.getsize(d / sess.RESULT_FILE) > 0


@pytest.mark.soak   # 125 s of graph (make test-soak); test_operator_control covers the record side
def test_an_abort_from_the_terminal_loses_no_press_and_the_session_resumes(
        tmp_path: Path, domain_id, listener, small_scene: str) -> None:
    """``/explorer/abort_by`` (tactex/srv/Confirm, as the terminal's ``a`` key calls it) in
    trial 1: the session ends with trial 1 resumable; a second start of the folder finishes
    it with every press of the first run kept once."""
    from tactex.srv import Confirm
    d = tmp_path / "sess"
    nodes = describe(True, small_scene, explorer={
        "trial": {"rounds": 1, "stop_confidence": 0.0}, "seed": 3,
        "record_dir": str(tmp_path), "session_file": str(THREE)})
    seen: dict = {}

    def drive(graph) -> None:
        def watch() -> None:
            f = d / "trial_1" / "touches.jsonl"
            end = time.monotonic() + 600
            while _lines(f) < 2 and time.monotonic() < end:
                time.sleep(0.05)
            cli = listener.node.create_client(Confirm, "/explorer/abort_by")
            if cli.wait_for_service(timeout_sec=60.0):
                fut = cli.call_async(Confirm.Request(by="key", caller="test terminal"))
                while not fut.done() and time.monotonic() < end:
                    time.sleep(0.05)
                seen["ok"] = fut.done() and fut.result().success
        threading.Thread(target=watch, daemon=True).start()

    first = run_session(nodes, tmp_path / "logs1", d, confirm="yes", timeout_s=900,
                        domain_id=domain_id, on_start=drive, out=lambda *_: None)
    assert seen.get("ok") is True, (seen, tmp_path / "logs1" / "explorer.log")
    assert first.result is None and first.exit_code == 0
    ended = [e for e in sess.events(d) if e["event"] == "session_ended"]
    assert len(ended) == 1 and ended[0]["aborted"] and ended[0]["by"] == "key"
    assert ended[0]["caller"] == "test terminal"
    before = read_record(d / "trial_1", images=False)["touches"]
    assert len(before) >= 2 and not (d / "trial_1" / "result.json").exists()
    assert not (d / "trial_2").exists()
    second = run_session(nodes, tmp_path / "logs2", d, confirm="yes", timeout_s=900,
                         domain_id=domain_id, out=lambda *_: None)
    assert second.result is not None, (second.failure, tmp_path / "logs2" / "explorer.log")
    rec = read_record(d / "trial_1", images=False)
    seqs = [t["seq"] for t in rec["touches"]]
    assert seqs == list(range(1, len(seqs) + 1))
    assert [t["seq"] for t in rec["touches"][:len(before)]] == [t["seq"] for t in before]
    assert rec["result"]["touches"] == sum(bool(t.get("accepted")) for t in rec["touches"])
