"""Start the described graph as real ROS 2 processes without ``launch`` (not installable here).

Each node of ``graph.describe`` runs as its own process (``python -m tactex_ros.ros.nodes.<exe>``,
the same code as the installed executable) with ``--ros-args -r __node:=<name>
--params-file <file>``; logs go to ``<log_dir>/<name>.log``. The explorer runs with
``exit_when_done``.

Supervision (``run_graph``): every process is polled every ``poll_s`` (0.1 s) while the trial
runs. The trial ends at the first of: the explorer exits (done, or failed); any other node
exits or crashes (the result names the node and its exit status); SIGINT, SIGTERM or SIGHUP
reaches the runner; the deadline. Then every remaining node gets SIGINT (rclpy's clean
shutdown), SIGKILL after a grace period. Children run in their own sessions, so a terminal's
Ctrl-C reaches only the runner, which stops them in order; and each child asks the kernel for
SIGTERM when the runner dies (``PR_SET_PDEATHSIG`` on Linux), so even a runner killed with
SIGKILL leaves no node behind. What ended the trial is appended to the record's
``events.jsonl`` when the record is this run's (``is_this_runs``: the explorer gets the run's
``run_id``), never to another run's record.
"""

from __future__ import annotations

import contextlib
import ctypes
import os
import signal
import subprocess
import sys
import threading
import time
from dataclasses import dataclass, field
from pathlib import Path
from collections.abc import Callable

from ...core.errors import InputError, TrialError
from ..graph import NodeSpec, params_file

_PR_SET_PDEATHSIG = 1
try:
    _LIBC = ctypes.CDLL(None, use_errno=True) if sys.platform.startswith("linux") else None
except OSError:  # pragma: no cover - no libc symbols
    _LIBC = None


def exit_text(code: int | None) -> str:
    """A process exit status in words: 'exit status 1', 'killed by SIGKILL', 'running'."""
    if code is None:
        return "still running"
    if code < 0:
        try:
            return f"killed by {signal.Signals(-code).name}"
        except ValueError:
            return f"killed by signal {-code}"
    return f"exit status {code}"


@dataclass
class GraphRun:
    exit_code: int                     # explorer's exit status (-1: still running at the end)
    result: dict | None                # result.json of the trial, if written
    record: Path | None                # the trial record folder
    logs: Path
    timed_out: bool
    node_exit: dict[str, int | None]   # every node's exit status after shutdown
    failure: str | None = None         # why the trial ended without a result (None: it did not)
    failed_node: str | None = None     # the node whose exit ended the trial, if one did
    signal: int | None = None          # the signal that interrupted the runner, if one did
    elapsed_s: float = 0.0             # start of the nodes -> end of the trial [s]
    stop_s: float = 0.0                # end of the trial -> every node stopped [s]
    left_running: list[str] = field(default_factory=list)  # nodes alive after stop (goal: none)
    pids: dict[str, int] = field(default_factory=dict)     # process id of every node
    reason: str | None = None          # the failed node's first error line (its log)
    not_noted: str | None = None       # why the end could not be noted in the record's events


def node_command(n: NodeSpec, params: Path) -> list[str]:
    # -P: no current directory on sys.path (a local inspect.py would shadow the library's)
    cmd = [sys.executable, "-P", "-m", f"tactex_ros.ros.nodes.{n.executable}", "--ros-args",
           "-r", f"__node:={n.name}", "--params-file", str(params)]
    for src, dst in n.remappings:
        cmd += ["-r", f"{src}:={dst}"]
    return cmd


def ros_env(domain_id: int | None = None) -> dict[str, str]:
    """Environment for the node processes: loopback-only discovery, optional domain id."""
    env = dict(os.environ)
    env.setdefault("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")
    if domain_id is not None:
        env["ROS_DOMAIN_ID"] = str(domain_id)
    env["PYTHONUNBUFFERED"] = "1"
    env["PYTHONSAFEPATH"] = "1"     # also for whatever the nodes start: no cwd on sys.path
    return env


def _child_setup(parent_pid: int) -> None:
    """In the child before exec: SIGTERM when the parent dies (Linux), even by SIGKILL."""
    if _LIBC is not None:
        _LIBC.prctl(_PR_SET_PDEATHSIG, signal.SIGTERM, 0, 0, 0)
        if os.getppid() != parent_pid:      # the parent died before prctl took effect
            os._exit(1)


class Graph:
    """The running processes of a graph (context manager: always stopped on exit)."""

    def __init__(self, nodes: list[NodeSpec], log_dir: str | Path,
                 domain_id: int | None = None) -> None:
        self.nodes = nodes
        self.log_dir = Path(log_dir)
        self.log_dir.mkdir(parents=True, exist_ok=True)
        self.env = ros_env(domain_id)
        self.procs: dict[str, subprocess.Popen] = {}

    def start(self) -> Graph:
        params = params_file(self.nodes, self.log_dir / "params.yaml")
        me = os.getpid()
        try:
            for n in self.nodes:
                with open(self.log_dir / f"{n.name}.log", "wb") as log:
                    self.procs[n.name] = subprocess.Popen(
                        node_command(n, params), stdout=log, stderr=subprocess.STDOUT,
                        env=self.env, start_new_session=True,
                        preexec_fn=lambda: _child_setup(me))
        except BaseException:
            self.stop()
            raise
        return self

    @property
    def pids(self) -> dict[str, int]:
        return {k: p.pid for k, p in self.procs.items()}

    def wait(self, name: str, timeout_s: float) -> int | None:
        """Exit status of node ``name``, or None if it is still running at the deadline."""
        try:
            return self.procs[name].wait(timeout=timeout_s)
        except subprocess.TimeoutExpired:
            return None

    def first_exit(self) -> tuple[str, int] | None:
        """(name, exit status) of a node that has exited, explorer first; None if all run."""
        done = [(k, p.returncode) for k, p in self.procs.items() if p.poll() is not None]
        done.sort(key=lambda kv: kv[0] != "explorer")
        return done[0] if done else None

    def stop(self, grace_s: float = 15.0) -> dict[str, int | None]:
        """SIGINT to every running node, SIGKILL to its process group after ``grace_s`` (sized
        for a loaded machine: a node in a CNN training step at load 26 needed more than 5 s)."""
        for p in self.procs.values():
            if p.poll() is None:
                with contextlib.suppress(ProcessLookupError):
                    p.send_signal(signal.SIGINT)
        end = time.monotonic() + grace_s
        for p in self.procs.values():
            try:
                p.wait(timeout=max(0.1, end - time.monotonic()))
            except subprocess.TimeoutExpired:
                with contextlib.suppress(ProcessLookupError):
                    os.killpg(p.pid, signal.SIGKILL)
                p.wait()
        return {k: p.returncode for k, p in self.procs.items()}

    def __enter__(self) -> Graph:
        return self.start()

    def __exit__(self, *exc) -> None:
        self.stop()


class _Signals:
    """While active (main thread only): SIGINT/SIGTERM/SIGHUP are noted, not fatal."""

    SIGNALS = (signal.SIGINT, signal.SIGTERM, signal.SIGHUP)

    def __init__(self) -> None:
        self.received: int | None = None
        self._old: dict[int, object] = {}

    def __enter__(self) -> _Signals:
        if threading.current_thread() is threading.main_thread():
            for s in self.SIGNALS:
                self._old[s] = signal.signal(s, self._note)
        return self

    def _note(self, signum: int, frame) -> None:
        if self.received is None:
            self.received = signum

    def __exit__(self, *exc) -> None:
        for s, h in self._old.items():
            signal.signal(s, h)


@dataclass
class Supervised:
    """How a supervised run of the graph ended (``supervise``): the graph, why it ended early
    (None: the expected end), the signal received, seconds from start to the end and to stop
    every node, every node's exit status."""

    graph: Graph
    failure: str | None
    signal: int | None
    elapsed_s: float
    stop_s: float
    exits: dict[str, int | None]


def supervise(nodes: list[NodeSpec], log_dir: str | Path, domain_id: int | None, what: str,
              on_exit: Callable[[str, int | None, float], str | None],
              deadline: Callable[[float], str | None],
              poll: Callable[[], None] | None = None,
              on_start: Callable[[Graph], None] | None = None,
              poll_s: float = 0.1, origin: float | None = None) -> Supervised:
    """Start the graph of ``nodes``, ``on_start(graph)`` once, then every ``poll_s``:
    ``poll()``; the first node to exit ends the run (``on_exit(name, code, elapsed_s)`` gives
    the failure, None when that exit is the expected end); a signal ends it (``what``: the trial,
    the session; its time counted from ``origin``, time.monotonic [s], e.g. the command's
    start; default the graph's start); ``deadline(elapsed_s)`` ends it with a failure once
    passed. Every node is stopped in every case, signals are noted (not fatal) meanwhile."""
    with _Signals() as sig:
        g = Graph(nodes, log_dir, domain_id)
        t0 = time.monotonic()
        origin = t0 if origin is None else origin
        failure: str | None = None
        try:
            g.start()
            if on_start is not None:
                on_start(g)
            while True:
                if poll is not None:
                    poll()
                gone = g.first_exit()
                if gone is not None:
                    failure = on_exit(gone[0], gone[1], time.monotonic() - t0)
                    break
                if sig.received is not None:
                    failure = (f"interrupted by {signal.Signals(sig.received).name} "
                               f"{time.monotonic() - origin:.1f} s into the {what}")
                    break
                failure = deadline(time.monotonic() - t0)
                if failure is not None:
                    break
                time.sleep(poll_s)
            elapsed = time.monotonic() - t0
        finally:
            t1 = time.monotonic()
            exits = g.stop()
            stop_s = time.monotonic() - t1
    return Supervised(g, failure, sig.received, elapsed, stop_s, exits)


def append_event(record: Path, event: dict) -> None:
    """One line in ``<record>/events.jsonl`` (fsync'ed), if the record folder exists."""
    from ...trial.record import append_event as _append
    if record.is_dir():
        _append(record, event)


def _result_stamp(path: Path) -> tuple | None:
    """What identifies one version of a file: (inode, size, mtime); None when absent."""
    try:
        st = path.stat()
    except OSError:
        return None
    return (st.st_ino, st.st_size, st.st_mtime_ns)


def new_result(path: Path, before: tuple | None) -> tuple[dict | None, str | None]:
    """The ``result.json`` this run wrote, or None when the file is absent or is the one that
    was there before the run (a run's status never comes from an older file); with a
    reason when the file is there but cannot be read."""
    from ...trial.record import read_result
    now = _result_stamp(path)
    if now is None or now == before:
        return None, None
    try:
        return read_result(path.parent), None
    except InputError as exc:
        return None, str(exc)


def node_reason(log: Path, max_chars: int = 2000) -> str | None:
    """Why a node ended, from its log: the first error line (rclpy's ``[ERROR]``, or the
    node's own ``tactex:`` line), else the last line of a Python traceback; None if the log
    holds neither. Cut at ``max_chars`` (long enough for the files a failure names: a record
    under a deep temporary folder, two paths, ran past 400)."""
    try:
        lines = log.read_text(errors="replace").splitlines()
    except OSError:
        return None
    for ln in lines:
        if "[ERROR]" in ln or "[FATAL]" in ln:
            text = ln.split("]: ", 1)[1] if "]: " in ln else ln
            return text.strip()[:max_chars]
        if ln.startswith("tactex: "):
            return ln[len("tactex: "):].strip()[:max_chars]
    if any(ln.startswith("Traceback") for ln in lines):
        last = next((ln for ln in reversed(lines) if ln.strip()), "")
        return last.strip()[:max_chars]
    return None


def progress_stamp(record: Path) -> tuple:
    """What changes when a trial makes progress: the sizes of its touch and decision files."""
    out = []
    for f in ("touches.jsonl", "decisions.jsonl"):
        try:
            out.append((record / f).stat().st_size)
        except OSError:
            out.append(-1)
    return tuple(out)


class Deadlines:
    """The runner's two deadlines: ``total_s`` from the start (None: none) and ``idle_s``
    without progress (None: none). Progress is a new touch or decision in the record, or the
    explorer working: ``cpu()`` (its CPU time [s], ``process_cpu_s``) grew by at least
    ``BUSY_FRACTION`` of the time since the last progress, checked every ``BUSY_WINDOW_S``.
    So a slow method finishes however long one decision takes on a loaded machine (the thesis
    CNN: 27-98 s alone, over 450 s on 2 shared cores) while a stopped or hung explorer (no
    CPU: SIGSTOP, a deadlock, waiting on a silent press server) still ends at ``idle_s``."""

    def __init__(self, record: Path, total_s: float | None, idle_s: float | None,
                 clock=time.monotonic, cpu=None) -> None:
        self.record, self.total_s, self.idle_s, self.clock = record, total_s, idle_s, clock
        self.cpu = cpu
        self.t0 = self.last = self.window = clock()
        self.stamp = progress_stamp(record)
        self.cpu_mark = self._cpu()

    def _cpu(self) -> float | None:
        try:
            return None if self.cpu is None else self.cpu()
        except OSError:
            return None

    def expired(self) -> str | None:
        """Why the trial is out of time, or None."""
        now = self.clock()
        stamp = progress_stamp(self.record)
        if stamp != self.stamp:
            self.stamp, self.last = stamp, now
            self.window, self.cpu_mark = now, self._cpu()
        elif now - self.window >= BUSY_WINDOW_S:
            cpu = self._cpu()
            if cpu is not None and self.cpu_mark is not None and \
                    cpu - self.cpu_mark >= BUSY_FRACTION * (now - self.window):
                self.last = now                      # the explorer is working (training)
            self.window, self.cpu_mark = now, cpu
        if self.total_s is not None and now - self.t0 > self.total_s:
            return f"trial not finished within {self.total_s:g} s"
        if self.idle_s is not None and now - self.last > self.idle_s:
            return (f"trial not finished: no new touch or decision and the explorer not "
                    f"working for {self.idle_s:g} s (idle deadline)")
        return None


#: [s] window over which the explorer's CPU time is compared with the time passed
BUSY_WINDOW_S = 30.0
#: share of one core the explorer must use over a window to count as working (training uses
#: a core or more even niced on a loaded machine, ~0.3; waiting in its 10 ms poll under 0.05)
BUSY_FRACTION = 0.1


def process_cpu_s(pid: int) -> float:
    """CPU time [s] (user + system) of process ``pid`` from ``/proc/<pid>/stat``; OSError
    when it is gone."""
    import os
    fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


def process_age_s(pid: int) -> float:
    """Wall time [s] since process ``pid`` started (``/proc/<pid>/stat`` start time against
    ``/proc/uptime``, 10 ms steps); OSError when it is gone or there is no /proc."""
    import os
    fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    uptime = float(Path("/proc/uptime").read_text().split()[0])
    return max(0.0, uptime - int(fields[19]) / os.sysconf("SC_CLK_TCK"))


def run_graph(nodes: list[NodeSpec], log_dir: str | Path, timeout_s: float | None = 600.0,
              domain_id: int | None = None, poll_s: float = 0.1,
              on_start=None, on_poll=None, idle_s: float | None = None) -> GraphRun:
    """Run the graph until the explorer finishes its trial, a node exits, a signal arrives,
    ``timeout_s`` passes (None: no total deadline) or ``idle_s`` passes without a new touch or
    decision (``Deadlines``); then stop every node. ``on_start(graph)`` is called once all
    processes are started (tests use it to inject faults); ``on_poll()`` at every poll
    (progress lines)."""
    if timeout_s is None and idle_s is None:
        raise InputError("run_graph needs a deadline: timeout_s or idle_s")
    ex = next((n for n in nodes if n.executable == "explorer_node"), None)
    if ex is None:
        raise InputError("the graph has no explorer_node")
    ex.parameters["exit_when_done"] = True
    if not ex.parameters.get("run_id"):      # this run's identity: its record says it is its
        import uuid
        ex.parameters["run_id"] = uuid.uuid4().hex
    run_id = str(ex.parameters["run_id"])
    if ex.parameters.get("resume"):
        # a resume writes into its record whatever record_dir and trial_id say (the explorer
        # takes them from the record: run_settings.resolve_run)
        record = Path(ex.parameters["resume"]).resolve()
    else:
        if not ex.parameters.get("trial_id"):
            ex.parameters["trial_id"] = time.strftime("trial_%Y%m%d_%H%M%S")
        ex.parameters["record_dir"] = str(Path(ex.parameters.get("record_dir") or
                                               "runs/trials").resolve())
        record = Path(ex.parameters["record_dir"]) / ex.parameters["trial_id"]
    res_path = record / "result.json"
    before = _result_stamp(res_path)     # a result already there is not this run's
    failed_node = None
    deadlines: list[Deadlines] = []

    def started(g: Graph) -> None:
        if on_start is not None:
            on_start(g)
        ex_pid = g.pids.get(ex.name)                             # its CPU counts as work
        deadlines.append(Deadlines(record, timeout_s, idle_s,   # from here on
                                   cpu=None if ex_pid is None
                                   else (lambda: process_cpu_s(ex_pid))))

    def ended(name: str, code: int | None, elapsed: float) -> str | None:
        nonlocal failed_node
        if name == ex.name and code == 0 and _result_stamp(res_path) not in (None, before):
            return None
        failed_node = name
        return f"node {name} ended ({exit_text(code)}) {elapsed:.1f} s into the trial"

    run = supervise(nodes, log_dir, domain_id, "trial", ended,
                    lambda _: deadlines[0].expired(), poll=on_poll, on_start=started,
                    poll_s=poll_s)
    g, failure, exits = run.graph, run.failure, run.exits
    left = [k for k, p in g.procs.items() if p.poll() is None]
    result, unreadable = new_result(res_path, before)
    if unreadable is not None and failure is None:
        failure, failed_node = unreadable, ex.name
    code = exits.get(ex.name)
    reason = node_reason(g.log_dir / f"{failed_node}.log") if failed_node else None
    not_noted = None
    if failure is not None and is_this_runs(record, run_id):
        try:
            append_event(record, {"event": "trial_ended", "reason": failure,
                                  "node": failed_node, "signal": run.signal, "node_exit": exits,
                                  "run_id": run_id, "time": time.time()})
        except TrialError as exc:      # a full disk: said on the console, not lost silently
            not_noted = str(exc)
    return GraphRun(exit_code=-1 if code is None else code, result=result,
                    record=record if record.exists() else None, logs=g.log_dir,
                    timed_out=failure is not None and failure.startswith("trial not finished"),
                    node_exit=exits, failure=failure, failed_node=failed_node,
                    signal=run.signal, elapsed_s=run.elapsed_s, stop_s=run.stop_s,
                    left_running=left,
                    pids=g.pids, reason=reason, not_noted=not_noted)


def is_this_runs(record: Path, run_id: str) -> bool:
    """Whether the record folder ``record`` belongs to the run ``run_id`` (the explorer's
    ``run_id``): its ``config.json`` was written by that run (a new trial), a resume by that
    run is in its events, or nothing is recorded there yet. A run refused because the record
    is another run's (the same trial id) must not write into it."""
    import json
    from ...trial.record import RECORD_FILES
    cfg = record / "config.json"
    if not cfg.is_file():
        return record.is_dir() and not any((record / f).exists() for f in RECORD_FILES)
    try:
        if json.loads(cfg.read_text()).get("explorer", {}).get("run_id") == run_id:
            return True
        lines = (record / "events.jsonl").read_text().splitlines()
    except (OSError, ValueError, AttributeError):
        return False
    for line in lines:
        try:
            e = json.loads(line)
        except ValueError:
            continue
        if isinstance(e, dict) and e.get("event") == "resumed" and e.get("run_id") == run_id:
            return True
    return False
