"""Run a study session on the graph without ``launch`` (``tactex graph run --session``).

The graph starts once; the explorer runs the session's trials (``trial/session_run.py``).
This runner supervises the processes as ``launcher.run_graph`` does (a node that exits ends
the run, named; SIGINT/SIGTERM/SIGHUP stop every node; the deadline), follows the session
folder (``session_events.jsonl``) and, for every placement the explorer awaits, shows the
operator what to place where and confirms through the explorer's ``~/confirm_by`` service
(``tactex/srv/Confirm``, saying how: ``yes_flag`` or ``enter``, and the caller): at once with
``confirm='yes'`` (scripted), after Enter on a terminal with ``confirm='key'``, or never
(``'none'``: someone else calls ``~/confirm``). A confirmation from elsewhere (Foxglove's
button, ``ros2 service call``) is shown as such and the terminal stops asking for Enter.
Once every node is active (each one's ``get_state``), one ``ready`` line says so. With
``confirm='key'`` a line with one of ``trial.control.KEYS`` (``p`` pause, ``r`` resume,
``a`` abort, ``s`` skip, ``d`` redo, then Enter) asks the explorer's ``~/<action>_by`` for
it, recorded as by ``key``; every operator action, wherever it came from, is shown.
"""

from __future__ import annotations

import json
import sys
import threading
import time
from dataclasses import dataclass, field
from pathlib import Path
from collections.abc import Callable

from ...core.errors import InputError
from ..graph import NodeSpec
from .launcher import Graph, exit_text, supervise


@dataclass
class SessionRun:
    exit_code: int                   # the explorer's exit status (-1: still running)
    result: dict | None              # session_result.json, once every trial is done; with
    #                                  ``trials`` the session's summary once those are done
    session_dir: Path
    logs: Path
    failure: str | None = None       # why the session ended without its result
    signal: int | None = None
    elapsed_s: float = 0.0
    node_exit: dict[str, int | None] = field(default_factory=dict)
    confirmations: int = 0           # placements this runner confirmed


def caller_name() -> str:
    """This runner as a confirmation's caller: ``tactex graph run (pid N, user@host)``."""
    import getpass
    import os
    import socket
    try:
        user = getpass.getuser()
    except (KeyError, OSError):
        user = "?"
    return f"tactex graph run (pid {os.getpid()}, {user}@{socket.gethostname()})"


class Confirmer:
    """Calls the explorer's ``~/confirm_by`` (``tactex/srv/Confirm``) from the runner's own
    rclpy context."""

    def __init__(self, service: str, domain_id: int | None, timeout_s: float = 30.0) -> None:
        self.service, self.domain_id, self.timeout_s = service, domain_id, timeout_s
        self.caller = caller_name()
        self._node = None
        self._clients: dict = {}
        self._lock = threading.Lock()

    def _ensure(self):
        if self._node is None:
            import os

            import rclpy
            from rclpy.signals import SignalHandlerOptions
            os.environ.setdefault("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")
            self._ctx = rclpy.Context()
            kw = {} if self.domain_id is None else {"domain_id": self.domain_id}
            rclpy.init(context=self._ctx, signal_handler_options=SignalHandlerOptions.NO, **kw)
            self._node = rclpy.create_node("tactex_operator", context=self._ctx)
            self._clients = {}
        return self._node

    def _client(self, srv_type: type, service: str):
        """The client of ``service`` (made once). Call with the lock held."""
        if service not in self._clients:
            self._clients[service] = self._ensure().create_client(srv_type, service)
        return self._clients[service]

    def _call(self, srv_type: type, service: str, request, timeout_s: float):
        """``request`` to ``service``: (response or None, '' or why not) within ``timeout_s``
        [s] for the service to show up and as long again for the answer. Call with the lock
        held."""
        from rclpy.executors import SingleThreadedExecutor
        client = self._client(srv_type, service)
        if not client.wait_for_service(timeout_sec=timeout_s):
            return None, f"service {service} not available within {timeout_s} s"
        fut = client.call_async(request)
        ex = SingleThreadedExecutor(context=self._ctx)
        node = self._ensure()
        ex.add_node(node)
        try:
            ex.spin_until_future_complete(fut, timeout_sec=timeout_s)
        finally:
            ex.remove_node(node)
            ex.shutdown()
        if not fut.done() or fut.result() is None:
            return None, f"no answer from {service} within {timeout_s} s"
        return fut.result(), ""

    def confirm(self, by: str, service: str | None = None) -> tuple[bool, str]:
        """(success, message) of one call saying ``by`` (``yes_flag`` | ``enter`` | ``key``)
        to ``service`` (a ``tactex/srv/Confirm`` service; default: the confirm service);
        (False, why) on a deadline."""
        from tactex.srv import Confirm
        with self._lock:
            r, why = self._call(Confirm, service or self.service,
                                Confirm.Request(by=by, caller=self.caller), self.timeout_s)
            return (False, why) if r is None else (bool(r.success), str(r.message))

    def states(self, names: list[str], timeout_s: float = 2.0) -> dict[str, str]:
        """Each node's lifecycle state label (``/<name>/get_state``,
        ``lifecycle_msgs/srv/GetState``): 'active', 'inactive', ...; '' when it did not
        answer within ``timeout_s`` [s]."""
        from lifecycle_msgs.srv import GetState
        out: dict[str, str] = {}
        with self._lock:
            for name in names:
                r, _ = self._call(GetState, f"/{name}/get_state", GetState.Request(), timeout_s)
                out[name] = "" if r is None else str(r.current_state.label)
        return out

    def close(self) -> None:
        if self._node is not None:
            self._node.destroy_node()
            self._ctx.try_shutdown()
            self._node = None


def _stamp(p: Path) -> tuple[int, int] | None:
    """(inode, mtime [ns]) of a file, None when absent: tells a rewritten file apart."""
    try:
        st = p.stat()
    except OSError:
        return None
    return st.st_ino, st.st_mtime_ns


def run_session(nodes: list[NodeSpec], log_dir: str | Path, session_dir: str | Path, *,
                confirm: str = "yes", timeout_s: float = 86400.0,
                domain_id: int | None = None, poll_s: float = 0.1,
                ready_hold_s: float = 30.0,
                out: Callable[[str, str], None] | None = None,
                on_start: Callable[[Graph], None] | None = None,
                started: float | None = None) -> SessionRun:
    """Start the graph once, run the explorer's session to its end (or a node's exit, a
    signal, the deadline), stop every node. ``confirm``: 'yes' | 'key' | 'none'.
    ``started``: when the command began (time.monotonic [s]; an interruption's time counts
    from it; default this call). The first placement prompt waits for the "ready" line
    (every node active) up to ``ready_hold_s`` [s], then is shown anyway. An
    explorer with ``library_materials`` presses a library (``trial/press_library.py``) in
    ``session_dir`` instead, followed through its own events and result files, whose
    events are a session's (``trial``: the material) and ``press_saved`` lines."""
    from ...trial import session as sess
    from ...trial import press_library as plib
    from ...trial.progress import Progress, console_printer, tail_jsonl
    from ...trial.control import KEYS
    from ...trial.session_run import trial_done_text
    if confirm not in ("yes", "key", "none"):
        raise InputError(f"confirm {confirm!r}: use yes, key or none")
    ex = next((n for n in nodes if n.executable == "explorer_node"), None)
    library = ex is not None and bool(ex.parameters.get("library_materials"))
    if ex is None or not (ex.parameters.get("session_file") or library):
        raise InputError("the graph has no explorer with a session_file or library_materials")
    d = Path(session_dir).resolve()
    ex.parameters.update(exit_when_done=True, **{"library_dir" if library else "session_dir":
                                                 str(d)})
    events_file, result_file = ((plib.EVENTS_FILE, plib.RESULT_FILE) if library else
                                (sess.EVENTS_FILE, sess.RESULT_FILE))
    out = out or console_printer()
    progress = Progress(out)
    confirmer = Confirmer(f"/{ex.name}/confirm_by", domain_id)
    res_path = d / result_file      # a result from before this start is not this run's
    stale = _stamp(res_path)
    events_path, offset = d / events_file, 0
    if events_path.is_file():                    # a resumed session: only what is new
        offset = events_path.stat().st_size
    start_offset = offset
    n_confirmed = 0
    t_run = time.monotonic()
    waiting_key: threading.Thread | None = None
    awaited: list[str] = []          # the trial whose placement is awaited now (0 or 1)

    ready = threading.Event()            # every node active: said once
    over = threading.Event()             # the session ended: the watch stops

    def watch_ready() -> None:     # one "ready" line once every node is active
        names = [n.name for n in nodes]
        end = time.monotonic() + timeout_s
        while not over.is_set() and time.monotonic() < end:
            states = confirmer.states(names)
            if all(v == "active" for v in states.values()):
                ready.set()
                progress.nodes_up()
                out(f"ready: every node is active ({', '.join(names)}), "
                    f"{time.monotonic() - t_run:.0f} s after the start", "info")
                return
            over.wait(0.5)

    def on_key() -> None:    # one reader for the whole session: Enter confirms what is awaited
        nonlocal n_confirmed
        while True:
            try:
                line = sys.stdin.readline()
                if not line:
                    return
            except (OSError, ValueError):
                return
            action = KEYS.get(line.strip().lower()[:1])
            if action is not None:     # an operator action on the running trial
                ok, msg = confirmer.confirm("key", f"/{ex.name}/{action}_by")
                if not ok:
                    out(f"{action} refused: {msg}", "info")
                continue
            if not awaited:
                continue          # confirmed from elsewhere already: nothing to do
            ok, msg = confirmer.confirm("enter")
            n_confirmed += ok
            if not ok:
                out(f"not confirmed: {msg}", "info")

    held: list[dict] = []      # events from a prompt on, held until the ready line is out
    held_since: list[float] = []

    def poll() -> None:        # the session's events since the last poll, on the console
        nonlocal offset, n_confirmed, waiting_key
        new, offset = tail_jsonl(events_path, offset)
        evs = held + new
        held.clear()
        for k, e in enumerate(evs):
            kind = e.get("event")
            if kind == "awaiting_confirmation" and not (ready.is_set() or over.is_set()):
                # the prompt comes after the "ready" line (a node's state query may lag the
                # explorer's first prompt); at most ready_hold_s [s] later it comes anyway
                held_since[:] = held_since or [time.monotonic()]
                if time.monotonic() - held_since[0] < ready_hold_s:
                    held.extend(evs[k:])
                    break
            if kind == "awaiting_confirmation":
                progress.nodes_up()         # the prompt is not followed by start-up lines
                out(f"{e.get('what', 'trial')} {e['trial']} ({e['number']}/{e['of']}): "
                    "place", "prompt")
                for pid, fab in e["placement"].items():
                    out(f"  platform {pid}: {fab}", "prompt")
                awaited[:] = [str(e["trial"])]
                if over.is_set():
                    pass                    # the run has ended: shown, not confirmed
                elif confirm == "yes":
                    for _ in range(10):     # refused: not awaited (yet); try again
                        ok, msg = confirmer.confirm("yes_flag")
                        if ok:
                            break
                        time.sleep(0.5)
                    n_confirmed += ok
                    if not ok:
                        out(f"not confirmed: {msg}", "info")
                elif confirm == "key":
                    out("press Enter once the fabrics are in place (or confirm in Foxglove / "
                        f"ros2 service call /{ex.name}/confirm std_srvs/srv/Trigger)",
                        "prompt")
                    out("during the trial: " + ", ".join(f"{k} {a}" for k, a in KEYS.items())
                        + " (the letter, then Enter)", "prompt")
                    if waiting_key is None or not waiting_key.is_alive():
                        waiting_key = threading.Thread(target=on_key, daemon=True)
                        waiting_key.start()
                else:
                    out(f"confirm with: ros2 service call /{ex.name}/confirm "
                        "std_srvs/srv/Trigger", "prompt")
            elif kind == "confirmed":
                awaited.clear()
                out(f"{e.get('what', 'trial')} {e['trial']}: placement confirmed by "
                    f"{e.get('by')}"
                    + (f" ({e['caller']})" if e.get("caller") else ""), "info")
            elif kind == "operator":
                out(f"trial {e.get('trial')}: {e.get('action')} by {e.get('by')}"
                    + (f" ({e['caller']})" if e.get("caller") else ""), "info")
            elif kind == "superseded":
                out(f"trial {e.get('trial')}: starts again; its presses so far kept in "
                    f"{e.get('record')}", "info")
            elif kind == "trial_started":
                progress.follow(d / sess.record_name(e["trial"]))
            elif kind == "trial_done":
                progress.poll()
                out(trial_done_text(e), "info")
            elif kind == "press_saved":
                force = (e.get("meta") or {}).get("force_n")
                out(f"{e['trial']}: press {e['press']}/{e['of']} saved ({e['file']}"
                    + (f", {force:.1f} N" if isinstance(force, (int, float)) else "") + ")",
                    "info")
            elif kind == "press_refused":
                out(f"{e['trial']}: press not kept ({e.get('reason')}); pressed again", "info")
            elif kind == "session_ended":
                out(f"session ended: {e.get('reason')}", "info")
            elif kind == "part_done":
                out(f"trials {', '.join(e.get('trials_asked') or [])} done; "
                    f"{e.get('done')} of {e.get('of')} trials of the session done", "info")
            elif kind == "session_done":
                out(f"{'library: every press made' if library else 'session: every trial done'}"
                    f", {time.monotonic() - t_run:.0f} s in this run", "info")
        progress.poll()

    def ended(name: str, code: int | None, elapsed: float) -> str | None:
        if name == ex.name and code == 0 and (fresh_result() or part_done()):
            return None
        evs, _ = tail_jsonl(events_path, start_offset)       # this run's, not an earlier one's
        last = [e for e in evs if e.get("event") == "session_ended"]
        return (last[-1]["reason"] if last and name == ex.name else
                f"node {name} ended ({exit_text(code)}) {elapsed:.1f} s into the session")

    def fresh_result() -> bool:
        return res_path.is_file() and _stamp(res_path) != stale

    def part_done() -> bool:
        """The trials asked for (``trials``) are done in this run, the session is not."""
        evs, _ = tail_jsonl(events_path, start_offset)
        return any(e.get("event") == "part_done" for e in evs)

    def deadline(elapsed: float) -> str | None:
        return f"session not finished within {timeout_s:g} s" if elapsed > timeout_s else None

    watcher = threading.Thread(target=watch_ready, name="ready", daemon=True)
    watcher.start()
    try:
        run = supervise(nodes, log_dir, domain_id, "session", ended, deadline, poll=poll,
                        on_start=on_start, poll_s=poll_s, origin=started)
    finally:
        over.set()
        watcher.join(timeout=10.0)     # a state query under way ends within its deadline
        if held:
            poll()                     # what was held for the ready line, shown now
        confirmer.close()
    failure, exits = run.failure, run.exits
    if failure is not None and d.is_dir():
        (plib.add_event if library else sess.add_event)(
            d, {"event": "run_ended", "reason": failure, "signal": run.signal,
                "node_exit": exits, "time": time.time()})
    result = (json.loads(res_path.read_text()) if fresh_result() else
              sess.summary(d) if failure is None and part_done() else None)
    code = exits.get(ex.name)
    return SessionRun(exit_code=-1 if code is None else code, result=result, session_dir=d,
                      logs=run.graph.log_dir, failure=failure, signal=run.signal,
                      elapsed_s=run.elapsed_s,
                      node_exit=exits, confirmations=n_confirmed)
