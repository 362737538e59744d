"""``tactex report RECORD_OR_SESSION``: (re)write the HTML reports of a trial or a session."""

from __future__ import annotations

import argparse

from .options import builds


def cmd_report(args: argparse.Namespace) -> int:
    from ..trial.report import regenerate
    for p in regenerate(args.folder):
        print(p)
    return 0


def add_commands(sub: argparse._SubParsersAction, command: str | None = None) -> None:
    p = sub.add_parser("report", help="write report.html of a trial record, or of a session "
                                      "folder and each of its trials")
    if not builds(command, "report"):
        return
    p.add_argument("folder", help="a trial record folder or a session folder")
    p.set_defaults(func=cmd_report)
