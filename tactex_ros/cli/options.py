"""Option helpers shared by the ``tactex`` command modules (``main`` and one module per
command group) and the lab's plug-in commands: bounded numbers, schema options, command groups,
JSON output. A leaf: it imports no command module, so the command modules import it and
``main`` imports them, one way."""

from __future__ import annotations

import argparse
from typing import Any


def bounded(kind: type, lo: float, hi: float):
    """argparse type: a number of ``kind`` in [lo, hi]; the error names the range."""
    def parse(text: str):
        try:
            v = kind(text)
        except ValueError:
            what = "an integer" if kind is int else "a number"
            raise argparse.ArgumentTypeError(f"{text!r} is not {what}") from None
        if not lo <= v <= hi:     # also refuses nan
            raise argparse.ArgumentTypeError(f"{text} is outside {kind(lo)}..{kind(hi)}")
        return v
    return parse


def builds(command: str | None, name: str) -> bool:
    """Whether ``build_parser(command)`` builds the options of command group ``name`` (all of
    them for None; otherwise only the group asked for, the rest are listed by name and help so
    that start-up imports nothing they need)."""
    return command is None or command == name


def add_setting_option(p: argparse.ArgumentParser, flag: str, spec: Any, help: str) -> None:
    """An option for one schema field (``core.schema.FieldSpec``): numbers out of the schema's
    range are refused by the parser (exit status 2, the option named); a value not among the
    choices by the schema check (exit status 2, the field named); not given = None."""
    kw: dict = {"default": None, "help": help + (f" (one of {', '.join(spec.choices)})"
                                                 if spec.choices else "")}
    if spec.kind in (int, float):
        kw["type"] = (bounded(spec.kind, spec.lo, spec.hi) if spec.lo is not None
                      and spec.hi is not None else spec.kind)
    p.add_argument(flag, **kw)


def add_schema_options(p: argparse.ArgumentParser, cls: type, names: tuple[str, ...]) -> None:
    """One option per dotted schema field of ``cls`` (``trial.stop_confidence`` ->
    ``--stop-confidence``), help from its description; not given = the preset's."""
    from ..core.schema import field_spec
    for name in names:
        spec = field_spec(cls, name)
        add_setting_option(p, "--" + name.rsplit(".", 1)[-1].replace("_", "-"), spec,
                           f"{spec.description} (default: the --config preset's)"
                           if "." in name else spec.description)


def schema_values(args: argparse.Namespace, names: tuple[str, ...]) -> dict:
    """The options of ``add_schema_options`` that were given, as nested settings."""
    from ..core.schema import nest
    values = {n: getattr(args, n.rsplit(".", 1)[-1]) for n in names}
    return nest({n: v for n, v in values.items() if v is not None})


def command_group(sub: argparse._SubParsersAction, name: str,
                  help: str) -> argparse._SubParsersAction:
    """The sub-commands of group ``name`` (``tactex <name> ...``), made on first use, so a
    plug-in can add a command to a group of the product (``sim compare``)."""
    parser = sub.choices.get(name) or sub.add_parser(name, help=help)
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            return action
    return parser.add_subparsers(dest=f"{name}_cmd", required=True)


def write_json(path: str | None, obj: dict) -> None:
    """Write ``obj`` as strict indented JSON to ``path`` atomically (folders made; NaN ->
    null, ``core.outputs``); nothing when None."""
    if path:
        from ..core.outputs import write_json as _write
        _write(path, obj)
