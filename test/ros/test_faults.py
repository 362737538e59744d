"""Faults in the running graph: a node killed mid-trial, a frozen mock arm, Ctrl-C of the explorer
or of the runner itself. Each run has a deadline; after each: every touch the explorer used is
on disk (byte for byte), ``result.json`` is valid or absent, no node process is left; then the
interrupted trial is resumed and ends with the prediction of an uninterrupted one."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import numpy as np
import pytest
from sensor_msgs.msg import Image

from tactex_ros.ros import adapter
from tactex_ros.ros.bag import TOUCH_TOPIC, read_bag
from tactex_ros.cli.graph_commands import summarise_bag
from tactex_ros.ros.graph import describe
from tactex_ros.ros.settings import TOUCH_IMAGE_TOPIC
from tactex_ros.trial.record import read_record, read_result
from tactex_ros.ros.devrun.launcher import ros_env, run_graph
from tactex_ros.robot.scene import load_scene

pytestmark = pytest.mark.ros

ROUNDS = 4                      # on the small scene: 3 baseline touches + 4 rounds = 7
DEADLINE_S = 150.0              # per graph run
CLEAR_S = 15.0                  # fault -> the runner has a clear result and every node stopped


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    try:                                   # a zombie not yet reaped counts as gone
        return Path(f"/proc/{pid}/stat").read_text().split(") ")[1][0] != "Z"
    except (OSError, IndexError):
        return False


def _touches_on_disk(record: Path) -> int:
    try:
        return len((record / "touches.jsonl").read_text().splitlines())
    except OSError:
        return 0


class Presses:
    """The press goals the motion node executes, from the action's status topic
    (``/tactex/press/_action/status``, rclpy's action status QoS): each goal id with the wall
    time it was first seen executing."""

    def __init__(self, listener) -> None:
        from action_msgs.msg import GoalStatusArray
        from rclpy.qos import qos_profile_action_status_default
        self.seen: dict[bytes, float] = {}
        listener.node.create_subscription(GoalStatusArray, "/tactex/press/_action/status",
                                          self._on, qos_profile_action_status_default)

    def _on(self, msg) -> None:
        from action_msgs.msg import GoalStatus
        for st in msg.status_list:
            if st.status == GoalStatus.STATUS_EXECUTING:
                self.seen.setdefault(bytes(st.goal_info.goal_id.uuid), time.time())

    def started_after(self, wall_t: float) -> bool:
        """A goal began executing after wall time ``wall_t``."""
        return any(t > wall_t for t in list(self.seen.values()))


def next_press(record: Path, after: int, presses: Presses, graph, deadline_s: float) -> bool:
    """Wait until the record holds ``after`` touch lines and the press after the last of
    them is executing (a goal first seen after the touch file was written); False at the
    deadline or when a node of ``graph`` exited."""
    end = time.monotonic() + deadline_s
    while time.monotonic() < end:
        if any(p.poll() is not None for p in graph.procs.values()):
            return False
        if _touches_on_disk(record) >= after and \
                presses.started_after((record / "touches.jsonl").stat().st_mtime):
            return True
        time.sleep(0.05)
    return False


class Fault:
    """Injects ``action(graph)`` during the press after the record's ``after``-th touch line
    (``next_press``; own deadline)."""

    def __init__(self, record: Path, after: int, action, presses: Presses) -> None:
        self.record, self.after, self.action, self.presses = record, after, action, presses
        self.t: float | None = None

    def __call__(self, graph) -> None:
        def watch() -> None:
            if next_press(self.record, self.after, self.presses, graph, DEADLINE_S):
                self.t = time.monotonic()
                self.action(graph)
        threading.Thread(target=watch, daemon=True).start()


def kill(name: str, sig: int = signal.SIGKILL):
    return lambda g: os.kill(g.procs[name].pid, sig)


def freeze(name: str, seconds: float):
    def act(g) -> None:
        pid = g.procs[name].pid
        os.kill(pid, signal.SIGSTOP)
        time.sleep(seconds)
        os.kill(pid, signal.SIGCONT)
    return act


def _check_record(record: Path, used: list[np.ndarray]) -> dict:
    """Every line whole, every image readable, every touch the explorer used on disk byte for
    byte, result.json valid or absent (read_result raises on a torn one)."""
    lines = (record / "touches.jsonl").read_text().splitlines()
    for line in lines:
        json.loads(line)                                     # no torn line
    rec = read_record(record)
    assert len(rec["touches"]) == len(lines)
    with_image = [t for t in rec["touches"] if t.get("image")]
    for t in with_image:
        assert t["array"] is not None and t["array"].shape == (240, 320, 3), t["image"]
    named = {t["image"] for t in with_image}
    assert {f.name for f in record.glob("touch_*.png")} == named   # no image without its line
    for img in used:
        assert any(np.array_equal(img, t["array"]) for t in with_image), \
            "a touch the explorer used is not on disk"
    read_result(record)
    for bag in sorted(record.glob("topics*.mcap")):          # the MCAP copy, crashed or closed
        for topic, _, m in read_bag(bag):
            if topic == TOUCH_TOPIC:
                arr = adapter.image_to_array(m.image, "bag touch")
                assert any(np.array_equal(arr, t["array"]) for t in with_image), bag.name
    return rec


def _run(tmp: Path, listener, name: str, fault: Fault | None, resume: Path | None = None,
         scene: str | None = None, trace=None, **explorer) -> tuple:
    ex = {"trial": {"rounds": ROUNDS, "stop_confidence": 0.0}, "seed": 0,
          "record_dir": str(tmp), "trial_id": "trial", **explorer}
    if resume is not None:
        ex["resume"] = str(resume)
    nodes = describe(True, scene, explorer=ex)
    used = listener.collect(Image, TOUCH_IMAGE_TOPIC)
    t0 = time.monotonic()
    run = run_graph(nodes, tmp / f"logs_{name}", timeout_s=DEADLINE_S,
                    domain_id=listener.domain_id, on_start=fault)
    t_end = time.monotonic()
    if trace is not None:                 # the force limit held at every sample of this run
        trace.check(load_scene(nodes[0].parameters["scene_file"]).press.max_force, t0, name)
    assert not run.timed_out, run.failure
    assert run.left_running == []
    assert len(run.pids) == 4 and not any(_alive(p) for p in run.pids.values())
    clear = None if fault is None or fault.t is None else t_end - fault.t
    imgs = [adapter.image_to_array(m, "touch") for m in list(used)]
    used.clear()
    rec = _check_record(tmp / "trial", imgs)
    print(f"\n{name}: {run.failure or 'finished'}; fault -> result and all stopped "
          f"{clear if clear is None else round(clear, 2)} s; run {t_end - t0:.1f} s; "
          f"touches on disk {len(rec['touches'])}")
    return run, rec, clear


# 71 s of graph (make test-soak); make test keeps a kill -9 (test_session), a Ctrl-C
# (test_runner_outcome) and a killed press server (below), each resumed or ended
@pytest.mark.soak
def test_kills_freeze_and_ctrl_c_then_resume(tmp_path: Path, listener, small_scene: str,
                                              force_trace) -> None:
    """One trial, interrupted four times and resumed each time: kill -9 of the motion node
    (after the mock arm was frozen for 5 s), of the mock camera, of the mock arm, SIGINT of
    the explorer mid-round; the last resume finishes it. No touch lost, none twice."""
    scene = load_scene(small_scene)
    truth = next(p.id for p in scene.comparisons if p.sim_fabric == scene.reference.sim_fabric)
    trace = force_trace
    presses = Presses(listener)
    record = tmp_path / "trial"

    # 1. the mock arm frozen 5 s mid-press (stale state), then, once it publishes again,
    # kill -9 of the motion node
    def freeze_then_kill(g) -> None:
        freeze("mock_arm", 5.0)(g)
        n, end = len(trace.forces()), time.monotonic() + 30.0
        while len(trace.forces()) == n and time.monotonic() < end:
            time.sleep(0.02)
        f.t = time.monotonic()
        kill("motion")(g)
    f = Fault(record, 2, freeze_then_kill, presses)
    run, rec, clear = _run(tmp_path, listener, "freeze_arm_5s_then_kill_motion", f,
                           scene=small_scene, trace=trace)
    assert run.failed_node == "motion" and run.node_exit["motion"] == -signal.SIGKILL
    assert run.result is None and clear is not None and clear < CLEAR_S
    n = len(rec["touches"])

    steps = [("kill_mock_camera", "mock_image", kill("mock_image")),
             ("kill_mock_arm", "mock_arm", kill("mock_arm")),
             ("sigint_explorer", "explorer", kill("explorer", signal.SIGINT))]
    for name, node, act in steps:
        f = Fault(record, n + 1, act, presses)
        run, rec, clear = _run(tmp_path, listener, name, f, resume=record, scene=small_scene,
                               trace=trace)
        if run.result is not None:            # the trial ended before the fault could land
            break
        assert run.failed_node == node, run.failure
        assert clear is not None and clear < CLEAR_S
        assert len(rec["touches"]) > n             # the resumed run made new touches
        n = len(rec["touches"])

    if run.result is None:
        run, rec, _ = _run(tmp_path, listener, "resume_to_the_end", None, resume=record,
                           scene=small_scene, trace=trace)
    res = run.result
    assert res is not None and "error" not in res, res
    assert res["prediction"] == truth and res["stop_reason"] == "rounds"
    accepted = [t for t in rec["touches"] if t["accepted"]]
    assert res["touches"] == len(accepted) == 3 + ROUNDS      # none lost, none twice
    assert len(rec["decisions"]) == ROUNDS + 1                # every decision once
    assert [d["round"] for d in rec["decisions"]] == list(range(1, ROUNDS + 2))
    assert len(res["resumed"]) >= 2
    # one bag for the trial: every run's messages merged into topics.mcap when it ended
    assert [f.name for f in record.glob("topics*.mcap*")] == ["topics.mcap"]
    assert summarise_bag(read_bag(record / "topics.mcap"))["prediction"] == truth


def _node_pids(tag: str) -> list[int]:
    """Processes whose command line contains ``tag`` (a unique log folder of this test)."""
    out = []
    for d in Path("/proc").iterdir():
        if d.name.isdigit():
            try:
                cmd = (d / "cmdline").read_bytes().replace(b"\0", b" ").decode()
            except OSError:
                continue
            if tag in cmd and "tactex_ros.ros.nodes." in cmd and _alive(int(d.name)):
                out.append(int(d.name))
    return out


@pytest.mark.parametrize("sig", [signal.SIGTERM, signal.SIGKILL])
def test_runner_signalled_leaves_no_node(tmp_path: Path, domain_id: int, sig: int) -> None:
    """`tactex graph run` gets SIGTERM (or SIGKILL) mid-trial: every node is stopped."""
    logs = tmp_path / f"logs_{sig}"
    cmd = [sys.executable, "-m", "tactex_ros.cli.main", "graph", "run", "--sim", "--rounds", "3",
           "--record-dir", str(tmp_path), "--trial-id", "t", "--log-dir", str(logs),
           "--domain-id", str(domain_id), "--timeout", "120"]
    proc = subprocess.Popen(cmd, env=ros_env(domain_id), stdout=subprocess.PIPE,
                            stderr=subprocess.STDOUT)
    try:
        end = time.monotonic() + 90
        while _touches_on_disk(tmp_path / "t") < 1 and time.monotonic() < end:
            assert proc.poll() is None, proc.stdout.read().decode()
            time.sleep(0.1)
        assert len(_node_pids(str(logs))) == 4
        t0 = time.monotonic()
        proc.send_signal(sig)
        code = proc.wait(timeout=30)
        while _node_pids(str(logs)) and time.monotonic() - t0 < 15:
            time.sleep(0.1)
        gone_s = time.monotonic() - t0
        left = _node_pids(str(logs))
    finally:
        if proc.poll() is None:
            proc.kill()
        for pid in _node_pids(str(logs)):
            os.kill(pid, signal.SIGKILL)
    assert left == [], f"nodes left after {signal.Signals(sig).name}: {left}"
    assert code == (128 + sig if sig != signal.SIGKILL else -sig)
    print(f"\nrunner {signal.Signals(sig).name}: all nodes gone after {gone_s:.2f} s")
    _check_record(tmp_path / "t", [])


#: [s] press_silence_s of the test below: above the motion node's start on a loaded machine (the
#: explorer's first goal can reach it during its pre-flight, with no executor spinning to answer
#: yet: with 3 s a loaded run once ended the trial before its first press)
SILENCE_S = 6.0


def test_explorer_gives_up_on_a_press_server_that_is_gone(tmp_path: Path, listener,
                                                          small_scene: str) -> None:
    """Without the runner's supervision (as under `launch`): the motion node is killed during a
    press; the explorer ends the trial within press_silence_s (not press_timeout_s, 120 s) with
    an error result, and the cut-off press is recorded as interrupted."""
    from tactex_ros.ros.devrun.launcher import Graph
    nodes = describe(True, small_scene,
                     explorer={"trial": {"rounds": 2, "stop_confidence": 0.0},
                               "record_dir": str(tmp_path), "trial_id": "gone",
                               "exit_when_done": True, "press_silence_s": SILENCE_S})
    record = tmp_path / "gone"
    presses = Presses(listener)
    with Graph(nodes, tmp_path / "logs", listener.domain_id) as g:
        assert next_press(record, 2, presses, g, 90.0), "no third press within 90 s"
        t0 = time.monotonic()
        os.kill(g.procs["motion"].pid, signal.SIGKILL)
        code = g.wait("explorer", 30.0)
        gone_s = time.monotonic() - t0
    assert code == 1, f"explorer still running {gone_s:.1f} s after the motion node died"
    print(f"\nexplorer: press server gone -> error result after {gone_s:.2f} s")
    assert gone_s < SILENCE_S + 10.0
    res = read_result(record)
    assert res is not None and "error" in res
    last = read_record(record, images=False)["touches"][-1]
    assert last["interrupted"] is True and last["accepted"] is False
    _check_record(record, [])


# 47 s of graph (make test-soak); a press result kept past the action's timeout: test_goal_loss
@pytest.mark.soak
def test_stalled_explorer_keeps_the_press_that_arrived(tmp_path: Path, listener,
                                                       small_scene: str) -> None:
    """SIGSTOP of the explorer during its 4th press for more than press_silence_s, then
    SIGCONT: the press server was healthy, so the trial goes on and ends with its result; the
    press whose result arrived during the stall is used, none is marked interrupted."""
    # 22 s: longer than press_silence_s (10 s) and than Fast DDS's default participant lease
    # (20 s), after which the other nodes forget the stalled one until it announces itself again
    f = Fault(tmp_path / "trial", 3, freeze("explorer", 22.0), Presses(listener))
    run, rec, _ = _run(tmp_path, listener, "stall_explorer", f, scene=small_scene)
    assert f.t is not None                                 # the stall happened
    assert run.result is not None and "error" not in run.result, run.failure
    assert not [t for t in rec["touches"] if t.get("interrupted")]
    assert run.result["touches"] == 3 + ROUNDS
