"""docs/reference.md, generated: every node parameter, launch argument, command-line option and
settings-file field of the product, read from the code that declares them; and
docs/reference_lab.md: the lab's commands and learners (the plug-ins ``setup.cfg`` declares).
Neither page depends on what is installed.

    python -m tactex_ros.cli.reference            # (re)write both pages
    python -m tactex_ros.cli.reference --check    # exit 1 when either page is stale

Sources (walked, never listed by hand): the node settings schemas of the graph description
(``ros.graph.SETTINGS``, through ``core.schema.fields``, which also declares the ROS
parameters), the presets (``TrialSettings`` validated under each ``config``), the launch file's
``arguments()``, the argparse parser of ``tactex`` (``cli.main.build_parser``, every
sub-command) and the pydantic models of the settings files (``FILES``).
"""

from __future__ import annotations

import argparse
import difflib
import importlib
import importlib.util
import inspect
import sys
import types
import typing
from pathlib import Path
from typing import Any, Literal

from pydantic import BaseModel

REGENERATE = "python -m tactex_ros.cli.reference"
DEFAULT_OUT = Path("docs/reference.md")
LAB_OUT = "reference_lab.md"      # beside the product's page

# settings files: (title, where the file lives, module, model) -- the fields are walked
FILES: tuple[tuple[str, str, str, str], ...] = (
    ("Scene file", "config/scene.yaml, config/scene_sim.yaml; `scene:=`, `--scene`",
     "tactex_ros.robot.scene", "SceneFile"),
    ("Robot profile", "config/robots/<name>.yaml; `robot:=`, motion node `robot`",
     "tactex_ros.robot.robots", "ProfileFile"),
    ("Sensor profile", "config/sensors/<name>.yaml; `sensor:=`, gelsight node `sensor`",
     "tactex_ros.robot.sensors", "SensorFile"),
    ("Fabric catalogue", "config/fabrics.yaml (simulator)", "tactex_ros.sim.fabrics",
     "Catalogue"),
)


def cell(value: Any) -> str:
    """Text of one table cell: one line, pipes escaped."""
    text = " ".join(str(value).split())
    return text.replace("|", "\\|")


def show(value: Any) -> str:
    """A default as the reader types it (``''`` for the empty string)."""
    if isinstance(value, str):
        return "`''`" if value == "" else f"`{value}`"
    if isinstance(value, (list, tuple)):
        return "`[" + ", ".join(map(str, value)) + "]`"
    return f"`{value}`"


def type_name(kind: Any) -> str:
    """A short name of a Python / typing type: constraints dropped (``Annotated``), ``Literal``
    as the type of its values, ``Optional[int]`` as ``int | None``, ``tuple[float, float,
    float]`` as ``tuple[float, float, float]``."""
    origin, args = typing.get_origin(kind), typing.get_args(kind)
    if origin is typing.Annotated:
        return type_name(args[0])
    if origin is Literal:
        return " | ".join(sorted({type(a).__name__ for a in args}))
    if origin in (typing.Union, types.UnionType):
        names = []
        for a in args:
            n = "None" if a is type(None) else type_name(a)
            if n not in names:
                names.append(n)
        return " | ".join(names)
    if origin is not None:
        name = getattr(origin, "__name__", str(origin).replace("typing.", ""))
        return f"{name}[{', '.join('...' if a is Ellipsis else type_name(a) for a in args)}]"
    if isinstance(kind, type):
        return kind.__name__
    return str(kind).replace("typing.", "")


def doc_line(obj: Any) -> str:
    """The first paragraph of a docstring, on one line."""
    return " ".join((inspect.getdoc(obj) or "").split("\n\n")[0].split())


def bounds(lo: Any, hi: Any, choices: tuple = ()) -> str:
    if choices:
        return ", ".join(show(c) for c in choices)
    if lo is None and hi is None:
        return ""
    return f"{'' if lo is None else lo} .. {'' if hi is None else hi}"


def table(header: tuple[str, ...], rows: list[tuple[str, ...]]) -> list[str]:
    out = ["| " + " | ".join(header) + " |", "|" + " --- |" * len(header)]
    out += ["| " + " | ".join(cell(c) for c in r) + " |" for r in rows]
    return out


# --- node parameters ---------------------------------------------------------------------

def node_parameters() -> list[str]:
    """One table per node of the graph description, in its order."""
    from ..core.schema import fields, flatten
    from ..ros.graph import SETTINGS
    out = ["## Node parameters", "",
           "Declared as ROS 2 parameters from the nodes' settings schemas "
           "(`tactex_ros/ros/settings.py`, `core/schema.py`); set them in a parameters file, "
           "with `--ros-args -p name:=value`, or through the options below. A value of the "
           "wrong type or outside its range ends the node with exit status 2, the parameter "
           "named.", ""]
    for node, cls in SETTINGS.items():
        try:
            effective = flatten(cls.check({}).model_dump())
        except Exception:   # noqa: BLE001 - a schema with required fields has no defaults
            effective = {}
        rows = [(f"`{s.name}`", type_name(s.kind), show(effective.get(s.name, s.default)),
                 bounds(s.lo, s.hi, s.choices),
                 s.description + (" (read-only)" if s.read_only else "")
                 + (f" (learner: {', '.join(s.learners)})" if s.learners else ""))
                for s in fields(cls)]
        out += [f"### `{node}` ({cls.__name__})", ""]
        if any("." in s.name for s in fields(cls)):
            out += ["Nested parameters take the value of the preset named by `config` unless "
                    "given (defaults shown: the default preset's, or the learner class's for "
                    "a setting the default learner does not have; other presets: "
                    "[Presets](#presets)).", ""]
        if any(s.tag for s in fields(cls)):
            out += ["`learner.model` picks the learner and with it the `learner.*` parameters "
                    "the node declares: those marked *(learner: ...)* exist only for that "
                    "learner family (`descriptor`: model descriptor; `cnn`: the CNN models; "
                    "`cnn_auto`: the ladder over CNN sizes, which also has the `cnn` ones; `auto`: the "
                    "ladder descriptor -> representation -> CNN, which also has the "
                    "`descriptor` ones); one given to another "
                    "learner is refused by name (exit status 2).", ""]
        out += table(("parameter", "type", "default", "range / choices", "description"),
                     rows) + [""]
    return out


def presets() -> list[str]:
    """What each preset of ``TrialSettings.config`` changes against the default preset."""
    from ..core import plugins
    from ..core.config import TrialSettings
    from ..core.schema import fields, flatten
    config = next((s for s in fields(TrialSettings) if s.name == "config"), None)
    if config is None or not config.choices:
        return []
    base = flatten(TrialSettings.check({}).model_dump())
    out = ["## Presets", "",
           f"`config` (`tactex trial --config`, `config:=`, explorer `config`) picks a named "
           f"set of learner and trial settings; the default is `{config.default}`. Settings "
           "another preset changes:", ""]
    rows = []
    for name in config.choices:
        if name == config.default:
            continue
        s = TrialSettings.check({"config": name})
        own = {f"learner.{k}": v for k, v in type(s.learner)().model_dump().items()}
        values = flatten(s.model_dump())
        rows += [(f"`{name}`", f"`{k}`", show(v),
                  show(base[k]) if k in base else f"none (class default {show(own[k])})")
                 for k, v in values.items()
                 if k != "config" and v != base.get(k, own.get(k))]
    return (out + table(("preset", "setting", "value", f"`{config.default}`"), rows) + [""]
            + [f"The learners besides `descriptor` and `auto` are the lab's plug-ins (entry "
               f"point group `{plugins.LEARNERS}`): [reference_lab.md]({LAB_OUT}).", ""])


# --- launch arguments --------------------------------------------------------------------

def launch_file() -> Path:
    """launch/explore.launch.py of the source tree or the install (beside ``config/``)."""
    from ..core.paths import config_dir
    return config_dir().parent / "launch" / "explore.launch.py"


def launch_arguments() -> list[str]:
    path = launch_file()
    spec = importlib.util.spec_from_file_location("tactex_explore_launch_reference", path)
    if spec is None or spec.loader is None:
        raise FileNotFoundError(f"launch file {path} not found")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    rows = [(f"`{n}`", show(d), h) for n, d, h in module.arguments()]
    return ["## Launch arguments", "",
            "`ros2 launch tactex explore.launch.py name:=value ...` "
            "(`launch/explore.launch.py`, `arguments()`); every value is checked before any "
            "process starts.", ""] + table(("argument", "default", "description"), rows) + [""]


# --- command line ------------------------------------------------------------------------

def _subparsers(p: argparse.ArgumentParser) -> list[tuple[str, str, argparse.ArgumentParser]]:
    """(name, help, parser) of the sub-commands of ``p``, by name (plug-in commands are found in
    an order that depends on the install)."""
    out = []
    for a in p._actions:   # noqa: SLF001 - argparse has no public walk
        if isinstance(a, argparse._SubParsersAction):   # noqa: SLF001
            helps = {c.dest: c.help or "" for c in a._choices_actions}   # noqa: SLF001
            out += [(name, helps.get(name, ""), sp) for name, sp in a.choices.items()]
    return sorted(out, key=lambda t: t[0])


def value_type(t: Any) -> str:
    """The value an option takes: a type's name, a range checker's ``int 0..232`` (the closure
    of ``cli.options.bounded``), or the checker function's name."""
    if t is None:
        return "str"
    if isinstance(t, type):
        return t.__name__
    free = inspect.getclosurevars(t).nonlocals if inspect.isfunction(t) else {}
    if {"kind", "lo", "hi"} <= set(free):
        kind = free["kind"]
        return f"{kind.__name__} {kind(free['lo'])}..{kind(free['hi'])}"
    return getattr(t, "__name__", type(t).__name__)


def _option_row(a: argparse.Action) -> tuple[str, ...]:
    name = ", ".join(f"`{o}`" for o in a.option_strings) or f"`{a.dest}` (positional)"
    if isinstance(a, (argparse._StoreTrueAction, argparse._StoreFalseAction)):   # noqa: SLF001
        kind = "flag"
    elif a.choices is not None:
        kind = ", ".join(f"`{c}`" for c in a.choices)
    else:
        kind = value_type(a.type)
    if a.nargs in ("+", "*"):
        kind += " ..."
    if isinstance(a, argparse._AppendAction):   # noqa: SLF001
        kind += " (repeatable)"
    if a.required:
        default = "required"
    elif a.default is None or isinstance(a, (argparse._StoreTrueAction,   # noqa: SLF001
                                            argparse._StoreFalseAction)):
        default = ""
    else:
        default = show(a.default)
    return name, kind, default, (a.help or "").replace("%(default)s", str(a.default))


def declared_plugins(group: str) -> list[tuple[str, str]]:
    """(name, ``module:object``) of the plug-ins of an entry point group that the repository's
    ``setup.cfg`` declares (the lab's), by name: read from the file, not the install."""
    import configparser
    cfg = configparser.ConfigParser()
    cfg.read(Path(__file__).resolve().parents[2] / "setup.cfg")
    text = cfg.get("options.entry_points", group, fallback="")
    pairs = (line.split("=", 1) for line in text.splitlines() if "=" in line)
    return sorted((n.strip(), v.strip()) for n, v in pairs)


def lab_parser_or_missing() -> tuple[argparse.ArgumentParser | None, str | None]:
    """(the lab's parser, None), built once (:func:`lab_parser`), or (None, why the lab's page
    cannot be generated in this install: a product install without the lab's requirements,
    ``make setup PRODUCT=1``)."""
    try:
        return lab_parser(), None
    except ModuleNotFoundError as exc:
        return None, f"the lab's commands need {exc.name!r}, not installed (requirements-lab.txt)"


def lab_parser() -> argparse.ArgumentParser:
    """The ``tactex`` parser with the product's commands and the lab's (``setup.cfg``)."""
    from .main import build_parser
    parser = build_parser(plugins=False)
    sub = next(a for a in parser._actions   # noqa: SLF001
               if isinstance(a, argparse._SubParsersAction))   # noqa: SLF001
    from ..core.plugins import COMMANDS
    for _, value in declared_plugins(COMMANDS):
        module, _, name = value.partition(":")
        getattr(importlib.import_module(module), name)(sub, None)
    return parser


def command_sections(parser: argparse.ArgumentParser) -> dict[str, list[str]]:
    """{``tactex a b``: its section (heading, help, options table)} of every sub-command of
    ``parser`` with options, depth first, by name."""
    out: dict[str, list[str]] = {}

    def walk(p: argparse.ArgumentParser, path: str, help_text: str) -> None:
        subs = _subparsers(p)
        rows = [_option_row(a) for a in p._actions   # noqa: SLF001
                if not isinstance(a, (argparse._HelpAction,   # noqa: SLF001
                                      argparse._SubParsersAction))]   # noqa: SLF001
        if rows or not subs:
            out[path] = ([f"### `{path}`", ""] + ([help_text, ""] if help_text else [])
                         + table(("option", "type", "default", "description"), rows) + [""])
        for name, sub_help, sp in subs:
            walk(sp, f"{path} {name}", sub_help)

    walk(parser, parser.prog, "")
    return out


EXIT_STATUS = ("Exit status: 0 success, 1 a run-time failure (a trial that could not finish, a "
               "failed check), 2 bad input (the option, file or field named).")


def command_line(parser: argparse.ArgumentParser | None = None) -> list[str]:
    """Every sub-command of the product's ``tactex`` with its options, depth first, by name."""
    from .main import build_parser
    parser = parser or build_parser(plugins=False)
    out = ["## Command line", "",
           f"`tactex <command> ...` (`tactex_ros/cli/`). {EXIT_STATUS} The lab's commands "
           f"(`tactex experiment`, `bench`, `weights`, `sim compare`): "
           f"[reference_lab.md]({LAB_OUT}).", ""]
    for section in command_sections(parser).values():
        out += section
    return out


# --- settings files ----------------------------------------------------------------------

def _model_of(ann: Any) -> tuple[type | None, str]:
    """The model inside an annotation and how it is held: ('', '[]' list, '{}' mapping)."""
    if isinstance(ann, type) and issubclass(ann, BaseModel):
        return ann, ""
    origin, args = typing.get_origin(ann), typing.get_args(ann)
    if origin in (list, tuple) and args and isinstance(args[0], type) \
            and issubclass(args[0], BaseModel):
        return args[0], "[]"
    if origin is dict and len(args) == 2 and isinstance(args[1], type) \
            and issubclass(args[1], BaseModel):
        return args[1], "{}"
    return None, ""


def model_rows(cls: type, prefix: str = "") -> list[tuple[str, ...]]:
    """(field, type, default, range / choices, description) of every field of a pydantic model,
    nested models walked (``platforms[].id``, ``fabrics{}.pitch``)."""
    import annotated_types
    rows: list[tuple[str, ...]] = []
    for name, f in cls.model_fields.items():
        sub, how = _model_of(f.annotation)
        if sub is not None:
            rows.append((f"`{prefix}{name}{how}`", sub.__name__,
                         "required" if f.is_required() else "", "",
                         f.description or doc_line(sub)))
            rows += model_rows(sub, f"{prefix}{name}{how}.")
            continue
        ann = f.annotation
        choices = typing.get_args(ann) if typing.get_origin(ann) is Literal else ()
        lo = next((m.ge for m in f.metadata if isinstance(m, annotated_types.Ge)), None)
        hi = next((m.le for m in f.metadata if isinstance(m, annotated_types.Le)), None)
        default = "required" if f.is_required() else show(
            f.get_default(call_default_factory=True))
        rows.append((f"`{prefix}{name}`", type_name(ann), default,
                     bounds(lo, hi, choices), f.description or ""))
    return rows


def settings_files() -> list[str]:
    out = ["## Settings files", "",
           "YAML files validated at start-up by these models; an unknown or bad field is "
           "refused with its location (e.g. `platforms.2.position`). `[]`: a list of, `{}`: a "
           "mapping of.", ""]
    for title, where, module, model in FILES:
        cls = getattr(importlib.import_module(module), model)
        out += [f"### {title} ({cls.__name__})", "", where, ""]
        out += table(("field", "type", "default", "range / choices", "description"),
                     model_rows(cls)) + [""]
    return out


# --- the page ------------------------------------------------------------------------------

def render_lab(parser: argparse.ArgumentParser | None = None) -> str:
    """The whole of docs/reference_lab.md: the lab's learners and commands (``parser``: the
    lab's parser when the caller has built it, else :func:`lab_parser`)."""
    from ..core.plugins import COMMANDS, LEARNERS
    from .main import build_parser
    product = set(command_sections(build_parser(plugins=False)))
    lines = ["# Reference: the lab's commands and learners", "",
             f"Generated from the code by `{REGENERATE}` (do not edit by hand); "
             "`test/unit/cli/test_reference.py` fails when this page is stale. The thesis lab "
             "(`tactex_lab`) adds these to the product ([reference.md](reference.md)) through "
             "the entry points `setup.cfg` declares.", "",
             f"## Learners (`learner.model`, entry point group `{LEARNERS}`)", ""]
    lines += table(("model", "object"), [(f"`{n}`", f"`{v}`")
                                         for n, v in declared_plugins(LEARNERS)]) + [""]
    lines += [f"## Commands (entry point group `{COMMANDS}`)", "",
              f"`tactex <command> ...` (`tactex_lab/cli/`). {EXIT_STATUS}", ""]
    for path, section in command_sections(parser or lab_parser()).items():
        if path not in product:
            lines += section
    while lines and lines[-1] == "":
        lines.pop()
    return "\n".join(lines) + "\n"


def render() -> str:
    """The whole of docs/reference.md."""
    lines = ["# Reference: parameters, launch arguments, command line, settings files", "",
             f"Generated from the code by `{REGENERATE}` (do not edit by hand); "
             "`test/unit/cli/test_reference.py` fails when this page is stale.", "",
             "- [Node parameters](#node-parameters)", "- [Presets](#presets)",
             "- [Launch arguments](#launch-arguments)", "- [Command line](#command-line)",
             "- [Settings files](#settings-files)", ""]
    lines += node_parameters() + presets() + launch_arguments() + command_line() \
        + settings_files()
    while lines and lines[-1] == "":
        lines.pop()
    return "\n".join(lines) + "\n"


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog=REGENERATE, description=__doc__.split("\n\n")[0])
    p.add_argument("--out", default=str(DEFAULT_OUT),
                   help=f"product page to write or check ({LAB_OUT} is written beside it)")
    p.add_argument("--check", action="store_true",
                   help="write nothing; exit 1 with a diff when the page differs")
    args = p.parse_args(argv)
    out = Path(args.out)
    pages = [(render(), out)]
    lab, missing = lab_parser_or_missing()
    if lab is not None:
        pages.append((render_lab(lab), out.parent / LAB_OUT))
    else:
        print(f"{out.parent / LAB_OUT} left as it is: {missing}", file=sys.stderr)
    if args.check:
        stale = 0
        for text, path in pages:
            old = path.read_text() if path.is_file() else ""
            if old != text:
                sys.stdout.writelines(difflib.unified_diff(
                    old.splitlines(True), text.splitlines(True), str(path), "generated"))
                print(f"{path} is stale: run `{REGENERATE}` from the repository root",
                      file=sys.stderr)
                stale = 1
        return stale
    for text, path in pages:
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(text)
        print(f"wrote {path}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
