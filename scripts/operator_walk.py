#!/usr/bin/env python3
"""operator_walk: issue 47's done-when walked end to end in simulation, as an operator would.

    .venv/bin/python scripts/operator_walk.py --out /tmp/walk [--trials 1,2,3] [--rounds 2] [--keys]

A simulated session of ``--session`` (default the thesis's ``human_study``) picked with
``--trials`` (three ids) is started with ``tactex graph run --sim ... --yes``; after the ready
line the first trial is paused and resumed (``/explorer/pause``, ``/explorer/resume``,
``std_srvs/srv/Trigger``), the second skipped (``/explorer/skip``), the third redone
(``/explorer/redo``); in the redone third trial the command gets SIGINT (the operator's
Ctrl-C), and the ``continue with:`` line it prints on stderr is run as printed, nothing
added. With ``--keys`` the walk is the terminal's instead: the commands run without ``--yes``
on a pseudo-terminal as their standard input, every placement is confirmed by Enter once the
prompt asks for it, and the actions are the keys ``p``, ``r``, ``s``, ``d`` (each then Enter),
answered by the command's ``trial N: <action> by key`` line. Then it checks, and prints as JSON:

- ``presses``: every trial record (the redo's superseded one too) holds each press once
  (``seq`` 1..n), the presses on disk before the Ctrl-C are kept unchanged, a result's touches
  are its accepted presses, the superseded record is marked so;
- ``report``: the session report names pause, resume, skip, redo (one ``operator`` row each,
  ``by`` service, or key with ``--keys``) and the interruption;
- ``checks``: the ready line before the first placement prompt; no press while paused;
- ``diagnostics``: every ``/diagnostics`` status seen, its highest level per status name; the
  ERRORs in the whole walk and outside the stop of the interrupted run (SIGINT to restart);
  the WARNs naming a simulation behind;
- ``clocks``: the terminal's times against the recorded ones: each trial's last decision
  line ``[m:ss elapsed`` against the record's trial time (``report.timing.time_split``), the
  progress topic's mean trial time against the results' ``elapsed_s``, ``interrupted by
  SIGINT N s into the session`` and ``m:ss in this run`` against this script's own clock and
  the session's events; ``ok`` within 10 % (or the printed value's rounding, whichever is
  larger).

Every wait has a deadline (``--deadline-s`` for each command). Exit status 0 when every check
passes, 1 otherwise, 2 for a bad option. One simulated graph at a time on a small machine.
"""

from __future__ import annotations

import argparse
import contextlib
import json
import os
import pty
import re
import shlex
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

TOLERANCE = 0.10        # the done-when's 10 %


class Stream:
    """The lines of one pipe of a process, each with its arrival time (monotonic s)."""

    def __init__(self, pipe) -> None:
        self.lines: list[tuple[float, str]] = []
        self._lock = threading.Lock()
        self._thread = threading.Thread(target=self._read, args=(pipe,), daemon=True)
        self._thread.start()

    def _read(self, pipe) -> None:
        for line in pipe:
            with self._lock:
                self.lines.append((time.monotonic(), line.rstrip("\n")))

    def join(self, timeout_s: float) -> None:
        self._thread.join(timeout=timeout_s)

    def find(self, pattern: str) -> tuple[float, re.Match] | None:
        with self._lock:
            for t, line in self.lines:
                m = re.search(pattern, line)
                if m:
                    return t, m
        return None

    def text(self) -> list[str]:
        with self._lock:
            return [line for _, line in self.lines]

    def timed(self, t0: float) -> str:
        """Every line after its arrival [s since ``t0``], for the files the walk leaves."""
        with self._lock:
            return "\n".join(f"{t - t0:8.2f} {line}" for t, line in self.lines)


class Ros:
    """This script's own rclpy node: Trigger calls, /diagnostics and the progress topic."""

    def __init__(self, domain_id: int) -> None:
        import rclpy
        from diagnostic_msgs.msg import DiagnosticArray
        from rclpy.executors import SingleThreadedExecutor
        from std_msgs.msg import String

        from tactex_ros.ros import adapter
        from tactex_ros.ros.settings import PROGRESS_TOPIC
        os.environ.setdefault("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")
        self.ctx = rclpy.Context()
        rclpy.init(context=self.ctx, domain_id=domain_id)
        self.node = rclpy.create_node("operator_walk", context=self.ctx)
        self.diag: list[tuple[float, str, int, str]] = []     # (t, name, level, message)
        self.progress: list[tuple[float, str]] = []
        self.node.create_subscription(DiagnosticArray, "/diagnostics", self._on_diag, 100)
        self.node.create_subscription(String, PROGRESS_TOPIC,
                                      lambda m: self.progress.append((time.monotonic(), m.data)),
                                      adapter.latched_qos())
        self.ex = SingleThreadedExecutor(context=self.ctx)
        self.ex.add_node(self.node)
        self.thread = threading.Thread(target=self._spin, daemon=True)
        self.thread.start()

    def _on_diag(self, msg) -> None:
        now = time.monotonic()
        for s in msg.status:
            level = s.level if isinstance(s.level, int) else int.from_bytes(s.level, "little")
            self.diag.append((now, s.name, level, s.message))

    def _spin(self) -> None:
        while self.ctx.ok():
            try:
                self.ex.spin_once(timeout_sec=0.1)
            except Exception:  # noqa: BLE001 - the context shut down, or one bad message
                if not self.ctx.ok():
                    return

    def trigger(self, service: str, timeout_s: float = 30.0) -> tuple[bool, str]:
        """(success, message) of one std_srvs/Trigger call; (False, why) past the deadline."""
        from std_srvs.srv import Trigger
        cli = self.node.create_client(Trigger, service)
        try:
            if not cli.wait_for_service(timeout_sec=timeout_s):
                return False, f"{service} not available within {timeout_s} s"
            fut = cli.call_async(Trigger.Request())
            end = time.monotonic() + timeout_s
            while not fut.done() and time.monotonic() < end:
                time.sleep(0.05)
            if not fut.done():
                return False, f"no answer from {service} within {timeout_s} s"
            return bool(fut.result().success), str(fut.result().message)
        finally:
            self.node.destroy_client(cli)

    def close(self) -> None:
        self.ctx.try_shutdown()
        self.thread.join(timeout=5.0)


class Keys:
    """An operator at the terminal: a pseudo-terminal as a command's standard input; Enter
    for each placement prompt that asks for it, a key for each action."""

    ASKS = r"^press Enter once the fabrics are in place"

    def __init__(self) -> None:
        self.master, self.slave = pty.openpty()
        self.stream: Stream | None = None
        self.entered = 0
        self._stop = threading.Event()

    def follow(self, stream: Stream) -> None:
        """Answer every prompt of ``stream`` (the command's stdout) with Enter."""
        self.stream = stream
        threading.Thread(target=self._answer, daemon=True).start()

    def _answer(self) -> None:
        while not self._stop.wait(0.2):
            asks = sum(bool(re.search(self.ASKS, t)) for t in (self.stream.text()
                                                                if self.stream else []))
            while self.entered < asks:
                os.write(self.master, b"\n")
                self.entered += 1

    def act(self, action: str, trial: str, timeout_s: float = 60.0) -> tuple[bool, str]:
        """Type the action's key and Enter; True once the command shows it taken."""
        from tactex_ros.trial.control import KEYS
        key = next(k for k, a in KEYS.items() if a == action)
        n_before = len(self.stream.text()) if self.stream else 0
        os.write(self.master, f"{key}\n".encode())
        end = time.monotonic() + timeout_s
        want = re.compile(rf"^trial {re.escape(trial)}: {action} by key")
        while time.monotonic() < end:
            for t in (self.stream.text() if self.stream else [])[n_before:]:
                if want.search(t):
                    return True, t
                if t.startswith(f"{action} refused"):
                    return False, t
            time.sleep(0.1)
        return False, f"no '{action} by key' line within {timeout_s:g} s"

    def close(self) -> None:
        self._stop.set()
        for fd in (self.master, self.slave):
            with contextlib.suppress(OSError):
                os.close(fd)


def lines_of(path: Path) -> int:
    try:
        return len(path.read_text().splitlines())
    except OSError:
        return 0


def wait_for(cond, deadline: float, what: str, proc: subprocess.Popen | None = None) -> float:
    """Wait (50 ms steps) until ``cond()``; the monotonic time it held. RuntimeError past
    ``deadline`` or when ``proc`` ended first."""
    while not cond():
        if time.monotonic() > deadline:
            raise RuntimeError(f"not within the deadline: {what}")
        if proc is not None and proc.poll() is not None:
            raise RuntimeError(f"the command ended (exit {proc.returncode}) before: {what}")
        time.sleep(0.05)
    return time.monotonic()


def clock_s(text: str) -> float:
    m, s = text.split(":")
    return 60.0 * int(m) + int(s)


def within(printed: float, recorded: float, resolution: float) -> dict:
    """A printed time [s] against a recorded one: ``ok`` within 10 % or the printed value's
    rounding (``resolution`` [s], half of its last digit), whichever is larger."""
    err = abs(printed - recorded)
    return {"printed_s": round(printed, 2), "recorded_s": round(recorded, 2),
            "error": round(err / recorded, 3) if recorded > 0 else None,
            "ok": err <= max(TOLERANCE * recorded, resolution)}


def trial_clocks(stdout: list[str], trial_records: dict[str, Path]) -> dict:
    """Each trial's last decision line ``[m:ss elapsed`` (the terminal's time of the trial,
    printed as it follows the trial's record) against the record's trial time: from the
    first request to the last recorded activity (``report.timing.time_split``'s ``total``)."""
    from tactex_ros.trial.record import read_record
    from tactex_ros.trial.report.timing import time_split
    out: dict = {}
    current = None
    last: dict[str, str] = {}
    for line in stdout:
        m = re.match(r"trial (\S+) \(\d+/\d+\): place", line)
        if m:
            current = m.group(1)
        m = re.search(r"\[(\d+:\d\d) elapsed", line)
        if m and current is not None:
            last[current] = m.group(1)
    for tid, rec_dir in trial_records.items():
        if tid not in last or not (rec_dir / "result.json").is_file():
            out[tid] = {"ok": None, "why": "no decision line or no result"}
            continue
        rec = read_record(rec_dir, images=False)
        total = time_split(rec)["total"]
        out[tid] = within(clock_s(last[tid]), float(total), 0.5)
    return out


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--out", required=True, help="a new folder for the session and the logs")
    p.add_argument("--session", default="human_study", help="trial file (default human_study)")
    p.add_argument("--trials", default="1,2,3", help="three trial ids of it (default 1,2,3)")
    p.add_argument("--rounds", type=int, default=2, help="rounds cap per trial (default 2)")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--pause-s", type=float, default=10.0, help="how long trial 1 stays paused")
    p.add_argument("--domain-id", type=int, default=200 + os.getpid() % 30)
    p.add_argument("--node-params", help="a ROS 2 parameters file for the other nodes")
    p.add_argument("--deadline-s", type=float, default=1200.0,
                   help="deadline of each of the two commands [s]")
    p.add_argument("--keys", action="store_true",
                   help="the terminal's walk: Enter and the action keys instead of services")
    args = p.parse_args(argv)
    ids = [t for t in args.trials.split(",") if t]
    if len(ids) != 3:
        p.error("--trials: three trial ids")
    out = Path(args.out).resolve()
    if out.exists() and any(out.iterdir()):
        p.error(f"--out {out}: not empty")
    out.mkdir(parents=True, exist_ok=True)
    d = out / "sess"

    from tactex_ros.ros.devrun.launcher import ros_env
    from tactex_ros.trial import session as sess
    from tactex_ros.trial.record import read_record
    env = ros_env(args.domain_id)
    env["PATH"] = f"{Path(sys.executable).parent}{os.pathsep}{env.get('PATH', '')}"
    ros = Ros(args.domain_id)
    summary: dict = {"date": time.strftime("%Y-%m-%d %H:%M"), "load_before": os.getloadavg(),
                     "out": str(out)}
    command = ["tactex", "graph", "run", "--sim", "--session", args.session, "--trials",
               args.trials, "--session-dir", str(d), *([] if args.keys else ["--yes"]),
               "--rounds", str(args.rounds), "--seed", str(args.seed),
               "--domain-id", str(args.domain_id)]
    keys = Keys() if args.keys else None
    by = "key" if keys else "service"

    def act(action: str, trial: str) -> tuple[bool, str]:
        return keys.act(action, trial) if keys else ros.trigger(f"/explorer/{action}")
    if args.node_params:
        command += ["--node-params", str(Path(args.node_params).resolve())]
    summary["command"] = shlex.join(command)
    t_start = time.monotonic()
    stdin = keys.slave if keys else subprocess.DEVNULL
    proc = subprocess.Popen(command, env=env, cwd=out, stdin=stdin,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    so, se = Stream(proc.stdout), Stream(proc.stderr)
    if keys:
        keys.follow(so)
    actions: dict = {}
    checks: dict = {}
    second: subprocess.Popen | None = None
    try:
        end = t_start + args.deadline_s
        a, b, c = (d / sess.record_name(t) for t in ids)
        wait_for(lambda: so.find(r"^ready: every node is active") is not None, end,
                 "the ready line", proc)
        t_ready = so.find(r"^ready: every node is active")
        summary["ready_after_s"] = round(t_ready[0] - t_start, 1)
        first_prompt = so.find(r"\): place$")
        checks["ready_before_prompt"] = first_prompt is None or first_prompt[0] >= t_ready[0]
        # 1: paused after its first press, held, resumed
        wait_for(lambda: lines_of(a / "touches.jsonl") >= 1, end, f"a press of trial {ids[0]}",
                 proc)
        actions["pause"] = act("pause", ids[0])
        time.sleep(min(5.0, args.pause_s / 2))       # the press under way ends
        held = lines_of(a / "touches.jsonl")
        time.sleep(args.pause_s - min(5.0, args.pause_s / 2))
        checks["no_press_while_paused"] = lines_of(a / "touches.jsonl") == held
        actions["resume"] = act("resume", ids[0])
        # 2: skipped after its first press
        wait_for(lambda: lines_of(b / "touches.jsonl") >= 1, end, f"a press of trial {ids[1]}",
                 proc)
        actions["skip"] = act("skip", ids[1])
        # 3: redone after its first press; Ctrl-C after two presses of the new run
        wait_for(lambda: lines_of(c / "touches.jsonl") >= 1, end, f"a press of trial {ids[2]}",
                 proc)
        actions["redo"] = act("redo", ids[2])
        old = d / f"{sess.record_name(ids[2])}.superseded.1"
        wait_for(lambda: old.is_dir() and lines_of(c / "touches.jsonl") >= 2, end,
                 f"two presses of the redone trial {ids[2]}", proc)
        t_cut = time.monotonic()
        proc.send_signal(signal.SIGINT)
        before_cut = {str(r): [t["seq"] for t in read_record(r, images=False)["touches"]]
                      for r in (c,)}
        try:
            proc.wait(timeout=max(1.0, end - time.monotonic()))
        except subprocess.TimeoutExpired as exc:
            raise RuntimeError("the command did not end after SIGINT") from exc
        so.join(10.0)
        se.join(10.0)
        summary["first_exit"] = proc.returncode
        hint = se.find(r"continue with: (.+)$")
        if hint is None:
            raise RuntimeError("no 'continue with:' line on stderr")
        summary["hint"] = hint[1].group(1)
        # the hint as printed, nothing added
        t_restart = time.monotonic()
        second = subprocess.Popen(shlex.split(summary["hint"]), env=env, cwd=out,
                                  stdin=stdin, stdout=subprocess.PIPE,
                                  stderr=subprocess.PIPE, text=True)
        so2, se2 = Stream(second.stdout), Stream(second.stderr)
        if keys:
            keys.entered = 0
            keys.follow(so2)
        try:
            second.wait(timeout=args.deadline_s)
        except subprocess.TimeoutExpired as exc:
            raise RuntimeError("the resumed command did not end in time") from exc
        t_end = time.monotonic()
        so2.join(10.0)
        se2.join(10.0)
        summary["second_exit"] = second.returncode
    except RuntimeError as exc:
        summary["error"] = str(exc)
    finally:
        for pr in (proc, second):
            if pr is not None and pr.poll() is None:
                pr.send_signal(signal.SIGINT)
                try:
                    pr.wait(timeout=60)
                except subprocess.TimeoutExpired:
                    pr.kill()
        time.sleep(1.0)
        ros.close()
        if keys:
            keys.close()
    (out / "stdout1.txt").write_text(so.timed(t_start))
    (out / "stderr1.txt").write_text(se.timed(t_start))
    if second is not None:
        (out / "stdout2.txt").write_text(so2.timed(t_restart))
        (out / "stderr2.txt").write_text(se2.timed(t_restart))
    summary["actions"] = {k: v[0] for k, v in actions.items()}
    if "error" in summary:
        summary["stderr_tail"] = (se2.text() if second is not None else se.text())[-8:]
        print(json.dumps(summary, indent=1))
        return 1

    # presses: each once, the ones before the cut kept, results = accepted presses
    recs = {ids[0]: a, ids[1]: b, ids[2]: c}
    press: dict = {}
    for name, r in [*((t, r) for t, r in recs.items()), ("superseded", old)]:
        rec = read_record(r, images=False)
        seqs = [t["seq"] for t in rec["touches"]]
        row = {"presses": len(seqs), "each_once": seqs == list(range(1, len(seqs) + 1))}
        if rec.get("result"):
            row["result_touches_are_accepted"] = rec["result"]["touches"] == sum(
                bool(t.get("accepted")) for t in rec["touches"])
        if name == "superseded":
            row["marked"] = any(e.get("event") == "superseded" for e in rec["events"])
        press[name] = row
    kept = read_record(c, images=False)["touches"]
    press["kept_across_ctrl_c"] = ([t["seq"] for t in kept[:len(before_cut[str(c)])]]
                                   == before_cut[str(c)])
    press["ok"] = bool(press["kept_across_ctrl_c"] and all(
        all(v for k, v in row.items() if k != "presses") for k, row in press.items()
        if isinstance(row, dict)))
    summary["presses"] = press

    # the session report names each action and the interruption
    ev = sess.events(d)
    page = (d / sess.REPORT_FILE).read_text() if (d / sess.REPORT_FILE).is_file() else ""
    ops = [(e["action"], e["trial"], e["by"]) for e in ev if e.get("event") == "operator"]
    named = {act: f"class='operator'>{act}<" in page for act in
             ("pause", "resume", "skip", "redo")}
    interrupted = "interrupted" in page and "SIGINT" in page
    summary["report"] = {"operator_events": ops, "named": named, "interruption": interrupted,
                         "ok": all(named.values()) and interrupted and ops == [
                             ("pause", ids[0], by), ("resume", ids[0], by),
                             ("skip", ids[1], by), ("redo", ids[2], by)]}

    # /diagnostics
    diag = ros.diag
    worst: dict[str, int] = {}
    for _, name, level, _ in diag:
        worst[name] = max(worst.get(name, 0), level)
    err_all = sorted({f"{n}: {m}" for _, n, lv, m in diag if lv >= 2})
    err_run = sorted({f"{n}: {m}" for t, n, lv, m in diag if lv >= 2
                      and not t_cut <= t <= t_restart})
    behind = sorted({f"{n}: {m}" for _, n, lv, m in diag if lv == 1 and "behind" in m})
    warns: dict[str, int] = {}         # each status's WARN texts (numbers left out), counted
    for _, n, lv, m in diag:
        if lv == 1:
            key = f"{n}: " + re.sub(r"\d+(\.\d+)?", "#", m)[:160]
            warns[key] = warns.get(key, 0) + 1
    summary["diagnostics"] = {"messages": len(diag), "worst_level": worst, "warn": warns,
                              "errors": err_all[:10], "errors_outside_the_stop": err_run[:10],
                              "warn_simulation_behind": behind[:5], "ok": not err_run}

    # clocks
    clocks: dict = {"trials": trial_clocks(so.text() + so2.text(), recs)}
    cut = se.find(r"interrupted by SIGINT (\d+\.\d) s into the session")
    if cut is not None:
        clocks["sigint_into_the_session"] = within(float(cut[1].group(1)), t_cut - t_start, 0.05)
        clocks["sigint_into_the_session"]["recorded_by"] = "this script, from the command's start"
    done_line = so2.find(r"; (\d+:\d\d) in this run")
    runs = [e for e in ev if e.get("event") in ("started", "resumed")]
    part = [e for e in ev if e.get("event") == "part_done"]
    if done_line is not None and runs and part:
        printed = clock_s(done_line[1].group(1))
        clocks["in_this_run"] = within(printed, t_end - t_restart, 0.5)
        clocks["in_this_run"]["recorded_by"] = "this script, from the command's start"
        clocks["in_this_run"]["events_start_to_part_done_s"] = round(
            part[-1]["time"] - runs[-1]["time"], 1)
    mean = [m for _, m in ros.progress if "the mean of" in m]
    if mean:
        m = re.search(r"about (\d+:\d\d) left \((\d+) trial\(s\) at (\d+) s, the mean of (\d+)",
                      mean[-1])
        if m:
            rows = sess.summary(d)["trials"]
            times = [float(r["elapsed_s"]) for r in rows if r["done"]
                     and isinstance(r.get("elapsed_s"), (int, float))][:int(m.group(4))]
            if times:
                clocks["progress_mean_trial"] = within(float(m.group(3)),
                                                       sum(times) / len(times), 0.5)
                clocks["progress_mean_trial"]["text"] = mean[-1]
    clocks["ok"] = all(v.get("ok") is not False for k, v in clocks.items()
                       if isinstance(v, dict) and "ok" in v) and all(
        v.get("ok") is not False for v in clocks["trials"].values())
    summary["clocks"] = clocks
    summary["progress"] = [m for _, m in ros.progress]
    summary["load_after"] = os.getloadavg()
    summary["exit_codes_ok"] = (summary["first_exit"] == 128 + signal.SIGINT
                                and summary["second_exit"] == 0)
    summary["ok"] = bool(summary["exit_codes_ok"] and press["ok"] and summary["report"]["ok"]
                         and summary["diagnostics"]["ok"] and clocks["ok"]
                         and checks["no_press_while_paused"] and checks["ready_before_prompt"]
                         and all(v[0] for v in actions.values()))
    summary["checks"] = checks
    (out / "walk.json").write_text(json.dumps(summary, indent=1))
    print(json.dumps(summary, indent=1))
    return 0 if summary["ok"] else 1


if __name__ == "__main__":
    sys.exit(main())
