"""Start the described graph as real ROS 2 processes without ``launch`` (not installable here).

Each node of ``graph.describe`` runs as its own process (``python -m tactex_ros.nodes.<exe>``,
the same code as the installed executable) with ``--ros-args -r __node:=<name>
--params-file <file>``; logs go to ``<log_dir>/<name>.log``. The explorer runs with
``exit_when_done``; the runner waits for it (deadline), then stops the other nodes with SIGINT
(SIGKILL after a grace period) and returns the trial's result.
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from dataclasses import dataclass
from pathlib import Path

from .core.errors import TactexError
from .graph import NodeSpec, params_file


@dataclass
class GraphRun:
    exit_code: int                     # explorer's exit status (None -> -1 on timeout)
    result: dict | None                # result.json of the trial, if written
    record: Path | None                # the trial record folder
    logs: Path
    timed_out: bool
    node_exit: dict[str, int | None]   # every node's exit status after shutdown


def node_command(n: NodeSpec, params: Path) -> list[str]:
    cmd = [sys.executable, "-m", f"tactex_ros.nodes.{n.executable}", "--ros-args",
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
    return env


class Graph:
    """The running processes of a graph (context manager: always stopped on exit)."""

    def __init__(self, nodes: list[NodeSpec], log_dir: str | Path,
                 domain_id: int | None = None) -> None:
        self.nodes = nodes
        self.log_dir = Path(log_dir)
        self.log_dir.mkdir(parents=True, exist_ok=True)
        self.env = ros_env(domain_id)
        self.procs: dict[str, subprocess.Popen] = {}

    def start(self) -> "Graph":
        params = params_file(self.nodes, self.log_dir / "params.yaml")
        for n in self.nodes:
            log = open(self.log_dir / f"{n.name}.log", "wb")
            self.procs[n.name] = subprocess.Popen(node_command(n, params), stdout=log,
                                                  stderr=subprocess.STDOUT, env=self.env,
                                                  start_new_session=True)
            log.close()
        return self

    def wait(self, name: str, timeout_s: float) -> int | None:
        """Exit status of node ``name``, or None if it is still running at the deadline."""
        try:
            return self.procs[name].wait(timeout=timeout_s)
        except subprocess.TimeoutExpired:
            return None

    def stop(self, grace_s: float = 5.0) -> dict[str, int | None]:
        for p in self.procs.values():
            if p.poll() is None:
                p.send_signal(signal.SIGINT)
        end = time.monotonic() + grace_s
        for p in self.procs.values():
            try:
                p.wait(timeout=max(0.1, end - time.monotonic()))
            except subprocess.TimeoutExpired:
                os.killpg(p.pid, signal.SIGKILL)
                p.wait()
        return {k: p.returncode for k, p in self.procs.items()}

    def __enter__(self) -> "Graph":
        return self.start()

    def __exit__(self, *exc) -> None:
        self.stop()


def run_trial(nodes: list[NodeSpec], log_dir: str | Path, timeout_s: float = 600.0,
              domain_id: int | None = None) -> GraphRun:
    """Run the graph until the explorer finishes its trial (or ``timeout_s``)."""
    ex = next((n for n in nodes if n.executable == "explorer_node"), None)
    if ex is None:
        raise TactexError("the graph has no explorer_node")
    ex.parameters["exit_when_done"] = True
    if not ex.parameters.get("trial_id"):
        ex.parameters["trial_id"] = time.strftime("trial_%Y%m%d_%H%M%S")
    ex.parameters["record_dir"] = str(Path(ex.parameters["record_dir"]).resolve())
    g = Graph(nodes, log_dir, domain_id).start()
    try:
        code = g.wait("explorer", timeout_s)
    finally:
        exits = g.stop()
    record = Path(ex.parameters["record_dir"]) / ex.parameters["trial_id"]
    res_path = record / "result.json"
    result = json.loads(res_path.read_text()) if res_path.exists() else None
    return GraphRun(exit_code=-1 if code is None else code, result=result,
                    record=record if record.exists() else None, logs=g.log_dir,
                    timed_out=code is None, node_exit=exits)
