"""The graph's resolution of a run's settings, new or resumed (``resolve_run``): the launch
file (``launch/explore.launch.py``), ``tactex graph describe|run`` (``cli/graph_commands.py``)
and the explorer node (its parameters) call it, and nothing after it validates them again.
It is the graph's layer over the one resolver of every entrance into a trial
(``trial.settings.resolve_settings``, which ``tactex trial`` calls too).

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

import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any
from collections.abc import Mapping

from ..core.errors import InputError
from ..core.schema import flatten, merge, nest, overrides
from ..trial.settings import ENTRANCE_KEY, Entrance, given_option
from .graph import OPTIONS, option_overrides, params_from_file, scene_path
from .settings import ExplorerSettings

#: the graph options a run remembers as given (paths absolute) and a resume takes from there
RUN_OPTIONS = ("sim", "scene", "settings", "node_params", "set", "yes", "source", "sensor",
               "device", "domain_id")
#: the setting options whose value, given or not, a run remembers (``graph.OPTIONS`` names)
SETTING_OPTIONS = ("config", "strategy", "model", "rounds", "seed", "session")
_PATHS = ("scene", "settings", "node_params", "session")
#: how ``run.json`` names the graph (``trial.settings.ENTRANCE_KEY``)
GRAPH = "graph"


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
    from ..trial.resume import record_scene
    from ..trial.settings import resolve_settings
    scene: list[str] = []                   # the graph's scene file (``defaults_of``)

    def given_of(opts: dict[str, Any]) -> dict[str, Any]:
        node_opts = {k: opts.get(k) for k in OPTIONS if OPTIONS[k][0] == "explorer"}
        return flatten(merge(option_overrides(node_opts).get("explorer"), explorer,
                             overrides(ExplorerSettings, opts.get("set"), set_origin)))

    def defaults_of(opts: dict[str, Any], record: Path | None) -> dict[str, Any]:
        if defaults is not None:            # the node: its parameters
            base = dict(defaults)
            s = str(given_of(opts).get("scene_file") or base.get("scene_file") or "")
            if record is not None and not s:        # the node given only ``resume``
                s = base["scene_file"] = record_scene(record)
            scene.append(s)
            return base
        given_scene = opts.get("scene")
        s = scene_path(bool(opts.get("sim")), record_scene(record)
                       if record is not None and not given_scene else given_scene,
                       opts.get("robot"))
        settings = opts.get("settings") or config_dir() / "explorer.yaml"
        if not Path(settings).is_file():
            raise InputError(f"explorer settings file {str(settings)!r} not found")
        scene.append(s)
        return dict(flatten(params_from_file(settings, "explorer")), scene_file=s)

    got = resolve_settings(options, Entrance(
        GRAPH, "tactex graph run", given_of, defaults_of, remember=RUN_OPTIONS + SETTING_OPTIONS,
        paths=_PATHS, flags=("sim", "yes"), own=("scene",),
        labels={k: OPTIONS[k][1] for k in OPTIONS}))
    opts, flat = got.options, got.flat
    if opts.get("sim") and (flat.get("session_file") or flat.get("library_materials")) and \
            not flat.get("placement_service"):
        flat["placement_service"] = "/mock_image/set_parameters"   # the mock camera's
    settings = ExplorerSettings.check(nest(flat), origin)            # the one validation
    eff = flatten(settings.model_dump())
    remembered: dict[str, Any] = {ENTRANCE_KEY: GRAPH}
    remembered.update({k: v for k in RUN_OPTIONS
                       if (v := given_option(opts, k, _PATHS)) is not None})
    remembered.update({k: eff[OPTIONS[k][1]] for k in SETTING_OPTIONS})
    if not remembered["session"]:
        del remembered["session"]
    return RunSettings(settings, opts, scene[0], got.folder, remembered)


def save_run_file(folder: str | Path, run: RunSettings) -> None:
    """``<folder>/run.json`` (the trial record or session folder) before any node starts,
    unless the folder has one: a resume keeps the run's first one
    (``trial.settings.save_run_file``)."""
    from ..trial.settings import save_run_file as save
    save(folder, run.remembered)


def ros_domain_id() -> int | None:
    """``ROS_DOMAIN_ID`` of this process (None: not set), the domain a launch runs on."""
    v = os.environ.get("ROS_DOMAIN_ID", "").strip()
    try:
        return int(v) if v else None
    except ValueError:
        raise InputError(f"ROS_DOMAIN_ID {v!r}: not a number") from None
