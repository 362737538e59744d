"""One resolution of a graph run's settings, new or resumed (``resolve_run``): the launch
file (``launch/explore.launch.py``), ``tactex graph describe|run`` (``cli/graph_commands.py``)
and the explorer node (its parameters) call it, and nothing after it validates them again.

What a run was given is its *options* (the names of ``graph.OPTIONS`` and ``RUN_OPTIONS``;
None: not given) and further explorer settings (``--set``, ``explorer_set:=``,
``learner.NAME:=``). A new run: the options over the explorer's settings file
(config/explorer.yaml or ``settings``). A run that continues a folder (``resume``: a trial
record, ``session_dir``: a session) with a ``run.json`` (``RUN_FILE``, written when the run
started, ``save_run_file``) takes every option not given from there; a trial record's
``config.json`` gives every explorer setting (``trial.resume.settings_from_record``) and its
scene (``record_scene``). A value given now that contradicts the record is refused
(InputError, exit status 2), both values named. The result is frozen and validated once.
"""

from __future__ import annotations

import json
import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any
from collections.abc import Mapping

from ..core.errors import InputError
from ..core.schema import flatten, merge, nest, overrides
from .graph import OPTIONS, option_overrides, params_from_file, scene_path
from .settings import ExplorerSettings

#: what a run's folder keeps of the options it was given (``save_run_file``)
RUN_FILE = "run.json"
#: the graph options a run remembers as given (paths absolute) and a resume takes from there
RUN_OPTIONS = ("sim", "scene", "settings", "node_params", "set", "yes", "source", "sensor",
               "device", "domain_id")
#: the setting options whose value, given or not, a run remembers (``graph.OPTIONS`` names)
SETTING_OPTIONS = ("config", "strategy", "model", "rounds", "seed", "session")
_PATHS = ("scene", "settings", "node_params", "session")


def _given(options: Mapping[str, Any], name: str) -> Any:
    """Option ``name`` as given (None: not given; a file path made absolute)."""
    v = options.get(name)
    if v is None or v is False or v == []:
        return None
    return str(Path(v).resolve()) if name in _PATHS and Path(str(v)).is_file() else v


@dataclass(frozen=True)
class RunSettings:
    """A run's settings, resolved: the explorer's (validated, frozen), the options (given or
    taken from the folder's ``run.json``), the scene file, the folder it continues (None: a
    new run) and the settings options' values (``SETTING_OPTIONS``) for ``run.json``."""

    explorer: ExplorerSettings
    options: Mapping[str, Any]
    scene: str
    folder: Path | None = None
    remembered: Mapping[str, Any] = field(default_factory=dict)


def _options_from_record(options: dict[str, Any]) -> Path | None:
    """``options`` with every option the run in the ``resume`` / ``session_dir`` folder was
    given (its ``run.json``), in place; a contradiction refused. The folder, or None."""
    folder = options.get("resume") or options.get("session_dir")
    if not folder or not (Path(folder) / RUN_FILE).is_file():
        return None
    p = Path(folder) / RUN_FILE
    try:
        was = json.loads(p.read_text())
    except (OSError, ValueError) as exc:
        raise InputError(f"{str(p)!r}: not readable ({exc})") from None
    for k in RUN_OPTIONS + SETTING_OPTIONS:
        if k == "scene" and options.get("resume"):
            continue            # a trial's scene: its record's copy (``record_scene``)
        given, rec = _given(options, k), was.get(k)
        if given is None:
            options[k] = rec if rec is not None or k not in ("sim", "yes") else False
        elif given != rec:
            name = OPTIONS[k][1] if k in OPTIONS else k
            raise InputError(f"--{k} {given!r} given but the record {str(folder)!r} has "
                             f"{name} = {rec!r}; a resumed run keeps what it was given "
                             "(leave the option out)")
    if options.get("resume") and not (Path(folder) / "config.json").is_file():
        # the run stopped before its trial recorded anything (e.g. no camera): the trial
        # starts in that folder with the options the run was given
        if options.get("record_dir") is not None or options.get("trial_id") is not None:
            raise InputError("--resume names the record; --record-dir and --trial-id do not "
                             "apply")
        d = Path(folder).resolve()
        options.update(resume=None, record_dir=str(d.parent), trial_id=d.name)
    return Path(folder)


def resolve_run(options: Mapping[str, Any] | None = None,
                explorer: Mapping[str, Any] | None = None, *,
                defaults: Mapping[str, Any] | None = None, set_origin: str = "--set",
                origin: str = "explorer") -> RunSettings:
    """The settings of a run (module doc). ``options``: ``graph.OPTIONS`` and ``RUN_OPTIONS``
    names, typed, plus ``robot`` (the robot profile, for the default scene); ``set``: dotted
    ``PATH=VALUE`` items (``set_origin`` names them in errors). ``explorer``: more explorer
    settings given, nested, before the ``set`` items. ``defaults``: the explorer's settings
    beneath what is given, flat (the explorer node: its parameters; None: the settings file
    ``settings``, else config/explorer.yaml, and the scene). InputError names what is wrong."""
    from ..core.paths import config_dir
    from ..trial.resume import record_scene, settings_from_record
    opts = dict(options or {})
    folder = _options_from_record(opts)
    node_opts = {k: opts.get(k) for k in OPTIONS if OPTIONS[k][0] == "explorer"}
    given = flatten(merge(option_overrides(node_opts).get("explorer"), explorer,
                          overrides(ExplorerSettings, opts.get("set"), set_origin)))
    resume = given.get("resume") or (defaults or {}).get("resume") or ""
    record = bool(resume) and (Path(resume) / "config.json").is_file() and \
        not (given.get("session_file") or (defaults or {}).get("session_file"))
    if record:             # the record's folder is where the trial goes on
        d = Path(resume).resolve()
        for k, there in (("record_dir", str(d.parent)), ("trial_id", d.name)):
            v = opts.get(k)
            if v not in (None, "") and (str(Path(v).resolve()) if k == "record_dir"
                                        else v) != there:
                raise InputError(f"--{k.replace('_', '-')} {v!r} given but --resume names "
                                 f"the record {str(d)!r}, in {there!r} (leave it out)")
    scene = opts.get("scene")
    if defaults is None:
        scene = scene_path(bool(opts.get("sim")),
                           record_scene(resume) if record and not scene else scene,
                           opts.get("robot"))
        settings = opts.get("settings") or config_dir() / "explorer.yaml"
        if not Path(settings).is_file():
            raise InputError(f"explorer settings file {str(settings)!r} not found")
        base = dict(flatten(params_from_file(settings, "explorer")), scene_file=scene)
    else:
        base = dict(defaults)
        scene = str(given.get("scene_file") or base.get("scene_file") or "")
    if record:
        # a value counts as given when it was given, not when it is only a default beneath
        flat = settings_from_record(resume, {**base, **given},
                                    [{k: v for k, v in base.items() if k not in given}])
        if not flat.get("scene_file"):           # the node given only ``resume``
            flat["scene_file"] = scene = record_scene(resume)
    else:
        flat = {**base, **given}
    if opts.get("sim") and (flat.get("session_file") or flat.get("library_materials")) and \
            not flat.get("placement_service"):
        flat["placement_service"] = "/mock_image/set_parameters"   # the mock camera's
    settings = ExplorerSettings.check(nest(flat), origin)            # the one validation
    eff = flatten(settings.model_dump())
    remembered = {k: v for k in RUN_OPTIONS if (v := _given(opts, k)) is not None}
    remembered.update({k: eff[OPTIONS[k][1]] for k in SETTING_OPTIONS})
    if not remembered["session"]:
        del remembered["session"]
    return RunSettings(settings, opts, scene, folder, remembered)


def save_run_file(folder: str | Path, run: RunSettings) -> None:
    """``<folder>/run.json`` (the trial record or session folder) before any node starts,
    unless the folder has one: a resume keeps the run's first one."""
    from ..core.outputs import dumps
    p = Path(folder) / RUN_FILE
    if not p.is_file():
        p.parent.mkdir(parents=True, exist_ok=True)
        p.write_text(dumps(dict(run.remembered)))


def ros_domain_id() -> int | None:
    """``ROS_DOMAIN_ID`` of this process (None: not set), the domain a launch runs on."""
    v = os.environ.get("ROS_DOMAIN_ID", "").strip()
    try:
        return int(v) if v else None
    except ValueError:
        raise InputError(f"ROS_DOMAIN_ID {v!r}: not a number") from None
