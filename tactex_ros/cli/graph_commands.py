"""``tactex graph describe|run``: the ROS 2 node graph without ``launch``."""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

from .options import add_setting_option, bounded, builds
from ..core.errors import InputError

# the explorer settings that are `tactex graph` options (graph.OPTIONS)
EXPLORER_OPTIONS = ("config", "strategy", "model", "rounds", "seed", "record_dir", "trial_id",
                    "session", "session_dir", "trials")
DEVICE_OPTIONS = ("source", "sensor", "device")     # mock image; GelSight node
# [s, monotonic] when ``tactex`` loaded this module to build its parser: the command's start
# where /proc cannot tell (``command_started``)
LOADED = time.monotonic()


def command_started() -> float:
    """When this command's process started (time.monotonic [s]): "in this run" and an
    interruption's "s into the session" count from it, the Python start-up and imports
    included (9 s at load 11 on 2 cores)."""
    import os
    from ..ros.devrun.launcher import process_age_s
    try:
        return time.monotonic() - process_age_s(os.getpid())
    except (OSError, ValueError, IndexError):
        return LOADED


def _nodes(args: argparse.Namespace, explorer: dict | None = None):
    """The graph these options ask for, as ``launch/explore.launch.py`` builds it from its
    arguments: the run's settings resolved once (``ros.run_settings.resolve_run``: the
    options, ``explorer`` (more explorer settings, nested), ``--settings`` (the launch's
    ``settings:=``) and ``--set`` (its ``explorer_set:=``) over config/explorer.yaml; a
    resume's from its record), then the nodes. The options the record gave are put into
    ``args``."""
    from ..core.schema import merge
    from ..ros.graph import describe, node_params_file, option_overrides
    from ..ros.run_settings import RUN_OPTIONS, resolve_run
    more = node_params_file(args.node_params) if getattr(args, "node_params", None) else {}
    names = EXPLORER_OPTIONS + DEVICE_OPTIONS + RUN_OPTIONS + ("resume",)
    options = {k: getattr(args, k, None) for k in names}
    options["robot"] = (more.get("motion") or {}).get("robot")
    run = resolve_run(options, explorer)
    for k in names:
        if k in run.options:
            setattr(args, k, run.options[k])
    args.run = run
    if run.options.get("node_params") != getattr(args, "node_params", None):
        more = node_params_file(run.options["node_params"])     # the record's
    given = option_overrides({k: run.options.get(k) for k in DEVICE_OPTIONS})
    return describe(bool(args.sim), run.scene, explorer=run.explorer,
                    mock_image=merge(more.get("mock_image"), given.get("mock_image")),
                    gelsight=merge(more.get("gelsight"), given.get("gelsight")),
                    motion=more.get("motion"), mock_arm=more.get("mock_arm"))


def cmd_describe(args: argparse.Namespace) -> int:
    nodes = _nodes(args)
    from ..core.outputs import dumps
    print(dumps([{"executable": n.executable, "name": n.name,
                  "parameters": n.parameters, "remappings": n.remappings} for n in nodes]))
    return 0


def preflight(nodes: list, logs: Path) -> Path:
    """Before any node starts: the log folder can be written, and the explorer's record is a
    new one (trial id a plain name, no record there, record folder writable) or, for a resume,
    one that can be continued (``record.check_new_record`` / ``check_resumable``). Returns
    the record folder; InputError (exit status 2) naming the path otherwise."""
    from ..core.outputs import check_dir
    from ..trial.record import check_new_record, check_resumable
    check_dir(logs, "--log-dir")
    ex = next(n for n in nodes if n.executable == "explorer_node")
    p = ex.parameters
    if p.get("resume"):
        check_resumable(p["resume"])
        return Path(p["resume"])
    if not p.get("trial_id"):
        p["trial_id"] = time.strftime("trial_%Y%m%d_%H%M%S")
    return check_new_record(p.get("record_dir") or "runs/trials", p["trial_id"])


def resume_hint(run, args: argparse.Namespace) -> str | None:
    """``tactex graph run --resume <record>`` when a resume of this run can work: the record
    exists and can be continued, and no node refused its input (exit status 2: the same
    input would be refused again). Nothing else: the record keeps the run's options."""
    from ..trial.settings import RUN_FILE
    from ..trial.record import check_resumable
    if run.record is None or 2 in run.node_exit.values():
        return None
    d = Path(run.record)
    if (d / RUN_FILE).is_file() and not (d / "config.json").is_file():
        pass                  # nothing recorded yet: the resume starts the trial (``_nodes``)
    else:
        try:
            check_resumable(d)
        except InputError:
            return None
    import shlex
    return f"tactex graph run --resume {shlex.quote(str(run.record))}"


def session_resume_hint(folder: str | Path, args: argparse.Namespace) -> str:
    """The command that continues an interrupted session in ``folder``: ``tactex graph run
    --session-dir FOLDER`` with this run's ``--trials`` (so the interrupted trial comes
    first, not the session's first trial not done) and ``--domain-id`` (the nodes' DDS
    domain; ``run.json`` keeps it too, so giving it again is never a contradiction)."""
    import shlex
    words = ["tactex", "graph", "run", "--session-dir", str(folder)]
    if getattr(args, "trials", None):
        words += ["--trials", str(args.trials)]
    if getattr(args, "domain_id", None) is not None:
        words += ["--domain-id", str(args.domain_id)]
    return shlex.join(words)


def session_done_text(result: dict, elapsed_s: float) -> str:
    """The terminal's last line of a finished session (``result``: its result.json): trials,
    accuracy (sure right answers over the trials done) and the not-sure answers counted
    apart; ``elapsed_s`` [s] of this run, as m:ss (to the second: a short run's tenth of a
    minute was 6 s)."""
    from ..trial.progress import clock_text
    acc = "n/a" if result.get("accuracy") is None else f"{result['accuracy']:.3f}"
    skipped = f", {result['skipped']} skipped" if result.get("skipped") else ""
    return (f"session {result['name']}: {result['done']} trials, accuracy "
            f"{acc}, {result.get('not_sure', 0)} not sure{skipped}; "
            f"{clock_text(elapsed_s)} in this run")


def session_dir(args: argparse.Namespace, nodes: list) -> str:
    """The session folder: ``--session-dir``, or ``record_dir/<trial file>_<time>``."""
    if args.session_dir:
        return args.session_dir
    ex = next(n for n in nodes if n.name == "explorer")
    if not getattr(args, "_session_dir", None):
        args._session_dir = str(Path(ex.parameters.get("record_dir") or "runs/trials") /
                                f"{Path(args.session).stem}_{time.strftime('%Y%m%d_%H%M%S')}")
    return args._session_dir


def default_logs(args: argparse.Namespace, nodes: list) -> Path:
    """The nodes' logs beside the record they belong to: ``<session folder>/logs/<time>``
    for a session, ``<record_dir>/logs/<trial id>_<time>`` for one trial."""
    stamp = time.strftime("%Y%m%d_%H%M%S")
    if args.session:
        return Path(session_dir(args, nodes)) / "logs" / stamp
    ex = next(n for n in nodes if n.name == "explorer").parameters
    return (Path(ex.get("record_dir") or "runs/trials") / "logs" /
            f"{ex.get('trial_id') or 'trial'}_{stamp}")


def cmd_session(args: argparse.Namespace, nodes: list, logs: Path) -> int:
    """``tactex graph run --session FILE``: the session's trials in one graph start."""
    from ..ros.devrun.session_runner import run_session
    from ..ros.run_settings import save_run_file
    if getattr(args, "resume", None):
        raise InputError("--resume continues one trial; a session continues with "
                          "--session-dir <its folder>")
    d = session_dir(args, nodes)
    save_run_file(d, args.run)
    print(f"starting {', '.join(n.name for n in nodes)} (logs: {logs})", file=sys.stderr)
    confirm = "yes" if args.yes else ("key" if sys.stdin.isatty() else "none")
    started = command_started()
    run = run_session(nodes, logs, d, confirm=confirm,
                      timeout_s=args.timeout if args.timeout is not None else 86400.0,
                      domain_id=args.domain_id, started=started)
    if run.result is None or run.failure is not None:
        how = ("before its last trial" if run.result is None else
               "with its result, but the run failed")
        return run_failed(run, logs, f"session ended {how}",
                          session_resume_hint(run.session_dir, args))
    r = run.result
    from ..trial.progress import clock_text
    took = time.monotonic() - started       # the command's time, start-up and stop included
    if r["done"] < r["total"]:          # --trials: a part of the session
        import shlex
        print(f"session {r['name']}: {r['done']} of {r['total']} trials done; "
              f"{clock_text(took)} in this run; the rest with: tactex graph run "
              f"--session-dir {shlex.quote(str(run.session_dir))}")
        return 0
    print(session_done_text(r, took))
    print(f"session folder: {run.session_dir} (report: {run.session_dir / 'report.html'})")
    return 0


def run_failed(run, logs: Path, what: str, hint: str) -> int:
    """A session's or a library's run that ended without its result (``run``:
    ``session_runner.SessionRun``), on the console: ``what`` and why, each refusing or
    failing node's reason from its log, then (no node refused its input) how to continue,
    ``hint``. The exit status: 2 for a refusal (continuing the same way would fail again),
    128 + the signal that stopped it, else 1."""
    print(f"tactex: {what}: {run.failure}; logs in {logs}", file=sys.stderr)
    from ..ros.devrun.launcher import node_reason
    refused = [n for n, c in run.node_exit.items() if c == 2]
    failed = [n for n, c in run.node_exit.items() if c == 1]
    for n in refused + failed:   # the node's reason on the console, not only in its log
        why = node_reason(Path(logs) / f"{n}.log")
        if why:
            print(f"tactex: {n}: {why} (from {Path(logs) / f'{n}.log'})", file=sys.stderr)
    if refused:
        return 2
    print(f"tactex: continue with: {hint}", file=sys.stderr)
    return 128 + run.signal if run.signal else 1


def library_command(args: argparse.Namespace) -> str:
    """The ``tactex graph library`` command of these options: run again, it presses only
    what is missing."""
    import shlex
    words = ["tactex", "graph", "library", "--materials", args.materials, "--presses",
             str(args.presses), "--out", str(args.out)]
    for flag, value in (("--scene", args.scene), ("--platform", args.platform),
                        ("--settings", args.settings), ("--node-params", args.node_params),
                        ("--domain-id", args.domain_id)):
        if value is not None:
            words += [flag, str(value)]
    for item in args.set or []:
        words += ["--set", item]
    return shlex.join(words + (["--sim"] if args.sim else []) + (["--yes"] if args.yes else []))


def cmd_library(args: argparse.Namespace) -> int:
    """``tactex graph library``: the robot presses the lab's materials into a library folder
    ``tactex prepare`` reads (``trial/press_library.py``), in one graph start; the operator
    places each material and confirms, as in a session."""
    from ..core.outputs import check_dir
    from ..ros.devrun.session_runner import run_session
    from ..trial import press_library as plib
    from ..trial.session import catalogue_names
    materials = plib.parse_materials(args.materials, catalogue_names() if args.sim else None)
    out = Path(args.out).resolve()
    plib.check_library_dir(out, args.sim)     # a foreign folder: refused, nothing written
    nodes = _nodes(args, explorer={"library_materials": ",".join(materials),
                                   "library_presses": args.presses, "library_dir": str(out),
                                   "library_platform": args.platform or ""})
    plib.open_library(out, args.sim)
    logs = Path(args.log_dir) if args.log_dir else out / ".logs" / time.strftime(
        "%Y%m%d_%H%M%S")
    check_dir(logs, "--log-dir")
    print(f"starting {', '.join(n.name for n in nodes)} (logs: {logs})", file=sys.stderr)
    confirm = "yes" if args.yes else ("key" if sys.stdin.isatty() else "none")
    run = run_session(nodes, logs, out, confirm=confirm,
                      timeout_s=args.timeout if args.timeout is not None else 86400.0,
                      domain_id=args.domain_id)
    if run.result is None or run.failure is not None:
        return run_failed(run, logs, "library run ended before every press was made",
                          library_command(args) + " (presses only what is missing)")
    r = run.result
    import shlex
    print(f"library {out}: {len(r['materials'])} materials x {r['presses']} presses "
          f"({r['made']} pressed in this run, {run.elapsed_s / 60:.1f} min)"
          + ("" if r["complete"] else "; some materials were skipped: run again for them"))
    print(f"next: tactex prepare --library {shlex.quote('replay:' + str(out))} --out lab.npz")
    return 0


def cmd_run(args: argparse.Namespace) -> int:
    from ..ros.devrun.launcher import exit_text, run_graph
    from ..ros.run_settings import save_run_file
    nodes = _nodes(args)
    logs = Path(args.log_dir) if args.log_dir else default_logs(args, nodes)
    if args.session:
        from ..core.outputs import check_dir
        from ..trial.session import check_session_dir
        # a file, unwritable, torn or another session's: refused before anything is written
        check_session_dir(session_dir(args, nodes), args.session)
        check_dir(logs, "--log-dir")
        return cmd_session(args, nodes, logs)
    save_run_file(preflight(nodes, logs), args.run)
    print(f"starting {', '.join(n.name for n in nodes)} (logs: {logs})", file=sys.stderr)
    from ..trial.progress import Progress
    progress = Progress()

    def follow(graph) -> None:
        ex = next(n for n in nodes if n.name == "explorer")
        progress.follow(Path(ex.parameters["record_dir"]) / ex.parameters["trial_id"])
    run = run_graph(nodes, logs, timeout_s=args.timeout, domain_id=args.domain_id,
                    on_start=follow, on_poll=progress.poll, idle_s=args.idle_timeout)
    progress.poll()
    if run.left_running:
        print(f"tactex: nodes still running after the stop: {run.left_running}",
              file=sys.stderr)
    if run.not_noted:
        print(f"tactex: the end of the run is not in the record's events: {run.not_noted}",
              file=sys.stderr)
    if run.result is not None and "error" not in run.result and run.failure is not None:
        # the trial has its result, but the run did not end well: a file that completes the
        # trial (its MCAP copy, report.html, an event) not written, or another node's exit
        print(f"tactex: trial {run.record.name if run.record else ''} has its result "
              f"({run.record / 'result.json' if run.record else ''}: reference matches "
              f"{run.result.get('prediction')}) but the run failed: {run.failure}; logs in "
              f"{logs}", file=sys.stderr)
        if run.reason:
            print(f"tactex: {run.failed_node}: {run.reason} (from "
                  f"{logs / (run.failed_node + '.log')})", file=sys.stderr)
        return 128 + run.signal if run.signal else (2 if 2 in run.node_exit.values() else 1)
    if run.result is None or "error" in run.result:
        why = (run.failure or (run.result or {}).get("error")
               or f"explorer ended without a result ({exit_text(run.exit_code)})")
        print(f"tactex: trial ended without a result: {why}; logs in {logs}", file=sys.stderr)
        if run.reason and run.failed_node:
            print(f"tactex: {run.failed_node}: {run.reason} (from "
                  f"{logs / (run.failed_node + '.log')})", file=sys.stderr)
        hint = resume_hint(run, args)
        if hint is not None:
            from ..trial.record import read_record
            n = len(read_record(run.record, images=False)["touches"])
            print(f"tactex: {n} touches on disk in {run.record}; continue with: {hint}",
                  file=sys.stderr)
        if run.signal:
            return 128 + run.signal
        return 2 if 2 in run.node_exit.values() else 1
    r = run.result
    from ..trial.record import read_record
    from ..trial.report import failed_attempts
    lines = read_record(run.record, images=False)["touches"]
    print(f"reference matches {r['prediction']} after {r['touches']} touches "
          f"({len(r['rounds'])} rounds, strategy {r['strategy']}, model {r['model']}); "
          f"failed touches {len(r['failed_touches'])}, failed press attempts "
          f"{failed_attempts(lines)}")
    print(f"trial record: {run.record}" + (f" (report: {run.record / 'report.html'})"
                                            if (run.record / "report.html").is_file() else ""))
    return 0


def summarise(record: dict) -> dict:
    """Where a trial's time went: press durations [s] (``trial.record.press_durations``: the
    motion node's approach-to-lift-off time, else request -> capture), decision times [s]."""
    import numpy as np
    from ..trial.record import press_durations
    touches = record["touches"]
    press = press_durations(touches)
    dec = [d["decision_s"] for d in record["decisions"]]
    out = {"touches": len(touches), "accepted": sum(bool(t.get("accepted")) for t in touches),
           "decisions": len(dec),
           "press_s_median": float(np.median(press)) if press else None,
           "press_s_total": float(np.sum(press)) if press else 0.0,
           "decision_s_median": float(np.median(dec)) if dec else None,
           "decision_s_total": float(np.sum(dec)) if dec else 0.0}
    res = record.get("result") or {}
    out.update(prediction=res.get("prediction"), error=res.get("error"))
    return out


def summarise_bag(messages: list) -> dict:
    """The same figures from an MCAP file of a trial (``bag.read_bag``): touches, decisions
    and decision times; press times need the request times only the record folder keeps."""
    import numpy as np
    from ..ros.bag import TOUCH_TOPIC
    from ..ros.settings import STATE_TOPIC
    touches = [m for topic, _, m in messages if topic == TOUCH_TOPIC]
    states = [m for topic, _, m in messages if topic == STATE_TOPIC]
    dec = [float(s.decision_s) for s in states]
    done = [s for s in states if s.done]
    return {"touches": len(touches), "accepted": len(touches), "decisions": len(dec),
            "press_s_median": None, "press_s_total": None,
            "decision_s_median": float(np.median(dec)) if dec else None,
            "decision_s_total": float(np.sum(dec)) if dec else 0.0,
            "prediction": done[-1].prediction if done else None, "error": None}


def cmd_summary(args: argparse.Namespace) -> int:
    from ..trial.record import read_record
    if Path(args.record).is_file():
        from ..ros.bag import read_bag
        s = summarise_bag(read_bag(args.record))
    else:
        from ..trial.record import RECORD_FILES
        if not any((Path(args.record) / f).is_file() for f in RECORD_FILES):
            raise InputError(f"{args.record!r} is not a trial record (none of "
                              f"{', '.join(RECORD_FILES)}) nor an MCAP file")
        s = summarise(read_record(args.record, images=False))
    from ..core.outputs import dumps
    print(dumps(s))
    return 0


def add_option(p: argparse.ArgumentParser, name: str) -> None:
    """``--name`` for option ``name`` of ``graph.OPTIONS``, from the node's settings schema;
    not given = None (the node's default)."""
    from ..ros.graph import OPTIONS, option_spec
    spec = option_spec(name)
    add_setting_option(p, "--" + name.replace("_", "-"), spec,
                       f"{OPTIONS[name][0]} {spec.name}: {spec.description}")


def add_commands(sub: argparse._SubParsersAction, command: str | None = None) -> None:
    g = sub.add_parser("graph", help="the ROS 2 node graph (runs without `launch`)")
    if not builds(command, "graph"):
        return
    gsub = g.add_subparsers(dest="gcmd", required=True)
    for name, fn, hlp in (("describe", cmd_describe, "print the nodes and parameters"),
                          ("run", cmd_run, "start the graph, run one trial, stop")):
        p = gsub.add_parser(name, help=hlp)
        p.add_argument("--sim", action="store_true", help="mock arm + mock image replace "
                                                          "the hardware")
        p.add_argument("--scene", help="scene YAML (default config/scene_sim.yaml or "
                                       "config/scene.yaml)")
        for option in EXPLORER_OPTIONS + DEVICE_OPTIONS:
            add_option(p, option)
        p.add_argument("--settings", metavar="FILE",
                       help="YAML of explorer parameters over config/explorer.yaml (the "
                            "launch argument settings:=)")
        p.add_argument("--node-params", metavar="FILE",
                       help="ROS 2 parameters YAML (<node>: {ros__parameters: ...}) for "
                            "motion, mock_arm, mock_image or gelsight (e.g. /diagnostics "
                            "thresholds); checked against each node's settings")
        p.add_argument("--set", action="append", metavar="PATH=VALUE",
                       help="an explorer setting, dotted (e.g. trial.stop_confidence=0.95); "
                            "repeatable (the launch argument explorer_set:=)")
        if name == "run":
            p.add_argument("--timeout", type=bounded(float, 1.0, 86400.0), default=None,
                           help="deadline of the whole trial [s], 1..86400 (default: none, "
                                "only --idle-timeout)")
            p.add_argument("--idle-timeout", type=bounded(float, 1.0, 86400.0), default=600.0,
                           help="end the trial when no new touch or decision reaches the "
                                "record and the explorer uses no CPU (a tenth of a core) for "
                                "this long [s], 1..86400 (default 600: a slow method "
                                "finishes as long as it works)")
            p.add_argument("--log-dir", help="the nodes' logs (default: beside the record, "
                                             "<session folder>/logs/<time> or "
                                             "<record_dir>/logs/<trial id>_<time>)")
            p.add_argument("--domain-id", type=bounded(int, 0, 232),
                           help="ROS_DOMAIN_ID for the nodes (0..232)")
            p.add_argument("--resume", metavar="RECORD_DIR",
                           help="continue the interrupted trial recorded in RECORD_DIR with "
                                "the options and settings it keeps (run.json, config.json); "
                                "an option given with another value is refused")
            p.add_argument("--yes", action="store_true",
                           help="with --session: confirm every placement at once (scripted "
                                "sessions, CI); without it a terminal asks for Enter")
        p.set_defaults(func=fn)
    lb = gsub.add_parser("library", help="the robot presses the lab's own materials into a "
                                         "library folder for `tactex prepare`")
    lb.add_argument("--materials", required=True,
                    help="the materials, comma-separated, in the order the operator places "
                         "them (plain folder names; with --sim catalogue fabrics, `tactex sim "
                         "fabrics`)")
    lb.add_argument("--presses", type=bounded(int, 1, 1000), required=True,
                    help="presses kept per material, 1..1000 (a press the contact guard "
                         "refuses is pressed again)")
    lb.add_argument("--out", required=True,
                    help="the library folder: new, empty, or a press library to continue "
                         "(only missing presses are made); a folder holding anything else is "
                         "refused")
    lb.add_argument("--platform", help="the platform the operator places each material on "
                                       "(default: the scene's reference)")
    lb.add_argument("--sim", action="store_true", help="mock arm + mock image replace the "
                                                       "hardware (the presses are simulated)")
    lb.add_argument("--scene", help="scene YAML (default config/scene_sim.yaml or "
                                    "config/scene.yaml)")
    add_option(lb, "sensor")
    add_option(lb, "device")
    lb.add_argument("--settings", metavar="FILE",
                    help="YAML of explorer parameters over config/explorer.yaml")
    lb.add_argument("--node-params", metavar="FILE",
                    help="ROS 2 parameters YAML (<node>: {ros__parameters: ...}) for motion, "
                         "mock_arm, mock_image or gelsight")
    lb.add_argument("--set", action="append", metavar="PATH=VALUE",
                    help="an explorer setting, dotted (e.g. learner.contact_min=1.0, the "
                         "contact guard a press must pass); repeatable")
    lb.add_argument("--timeout", type=bounded(float, 1.0, 86400.0), default=None,
                    help="deadline of the whole run [s], 1..86400 (default: none)")
    lb.add_argument("--log-dir", help="the nodes' logs (default <out>/.logs/<time>)")
    lb.add_argument("--domain-id", type=bounded(int, 0, 232),
                    help="ROS_DOMAIN_ID for the nodes (0..232)")
    lb.add_argument("--yes", action="store_true",
                    help="confirm every placement at once (scripted runs, CI); without it a "
                         "terminal asks for Enter")
    lb.set_defaults(func=cmd_library)
    sm = gsub.add_parser("summary", help="where a recorded trial's time went")
    sm.add_argument("record", help="trial record folder, or an MCAP file of a trial "
                                   "(<record>/topics.mcap; a crashed one is read up to its "
                                   "last whole message)")
    sm.set_defaults(func=cmd_summary)
