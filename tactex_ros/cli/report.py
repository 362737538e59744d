"""``tactex report FOLDER``: (re)write the HTML reports of a trial, a session, or every record
under a folder and its ``index.html``.
``tactex layout --robot PROFILE``: the operator's Foxglove layout for a robot profile."""

from __future__ import annotations

import argparse

from .options import builds


def cmd_report(args: argparse.Namespace) -> int:
    from ..trial.report import regenerate
    for p in regenerate(args.folder):
        print(p)
    return 0


def cmd_layout(args: argparse.Namespace) -> int:
    from pathlib import Path

    from ..core.outputs import check_dir
    from ..ros.viewer_layout import layout_text
    text = layout_text(args.robot)
    if args.output in (None, "-"):
        print(text, end="")
        return 0
    out = Path(args.output)
    check_dir(out.parent, "--output")
    out.write_text(text)
    print(out)
    return 0


def add_commands(sub: argparse._SubParsersAction, command: str | None = None) -> None:
    lay = sub.add_parser("layout", help="write the operator's Foxglove layout for a robot "
                                        "profile (Layouts -> Import from file)")
    if builds(command, "layout"):
        lay.add_argument("--robot", default="fr3_crisp",
                         help="robot profile: a name from config/robots/ (fr3_crisp, "
                              "panda_crisp, sim) or a path (default fr3_crisp)")
        lay.add_argument("--output", "-o", default=None,
                         help="file to write (default: standard output)")
        lay.set_defaults(func=cmd_layout)
    p = sub.add_parser("report", help="write report.html of a trial record, or of a session "
                                      "folder and each of its trials, or of every record "
                                      "under a folder and its index.html")
    if not builds(command, "report"):
        return
    p.add_argument("folder", help="a trial record folder, a session folder or a folder "
                                  "holding them (at any depth)")
    p.set_defaults(func=cmd_report)
