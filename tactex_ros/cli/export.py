"""``tactex export``: a trial record, a session, a folder of them or a ``replay:DIR`` library
as a Hugging Face dataset (``export/hf.py``; ``datasets`` is imported only when it runs)."""

from __future__ import annotations

import argparse

from .options import builds


def cmd_export(args: argparse.Namespace) -> int:
    from ..export.hf import export
    info = export(args.source, args.out)
    print(f"{info['rows']} touches of {info['trials']} "
          f"{'class folder(s)' if info['kind'] == 'library' else 'trial(s)'} ({info['kind']}) "
          f"-> {args.out} (load_dataset({str(args.out)!r}, split='train'))")
    return 0


def add_commands(sub: argparse._SubParsersAction, command: str | None = None) -> None:
    e = sub.add_parser("export", help="a trial record, a session, a folder of them or a "
                                      "replay:DIR library as a Hugging Face dataset")
    if not builds(command, "export"):
        return
    e.add_argument("source", help="a trial record folder, a session folder, a folder of "
                                  "either, or replay:DIR")
    e.add_argument("--out", required=True, help="new (or empty) folder for the dataset")
    e.set_defaults(func=cmd_export)
