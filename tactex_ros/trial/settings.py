"""One resolution of a run's settings, new or resumed, for every entrance into a trial
(``resolve_settings``; no ROS here): ``tactex trial`` (``cli/main.py``) and the graph's
(``ros/run_settings.resolve_run``: the launch file, ``tactex graph describe|run``, the
explorer node) call it, each with an ``Entrance`` that says how its options become settings.

What a run was given is its *options* ({name: value}; None: not given). A run that continues
a folder (``resume``: a trial record, ``session_dir``: a session folder) with a ``run.json``
(``RUN_FILE``, written when the run started, ``save_run_file``) takes every option it
remembers (``Entrance.remember``) and was not given from there. The options then give the
settings, flat (``Entrance.given``), over the settings beneath them (``Entrance.defaults``);
a trial record's ``config.json`` gives every setting that changes the trial
(``trial.resume.settings_from_record``). A value given now that contradicts the folder's is
refused (InputError, exit status 2), both values named. What is left to the entrance: its
options' parsing and the one validation of the flat settings.
"""

from __future__ import annotations

import json
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from ..core.errors import InputError

#: what a run's folder keeps of the options it was given (``save_run_file``)
RUN_FILE = "run.json"
#: the key of ``run.json`` naming the entrance that wrote it (a file without it: the graph's)
ENTRANCE_KEY = "entrance"


@dataclass(frozen=True)
class Entrance:
    """What one entrance tells ``resolve_settings``.

    ``name``: the entrance, as ``run.json`` keeps it (``graph``, ``trial``) and errors name it
    (``command``: the command that continues its runs). ``remember``: the options ``run.json``
    keeps and a resume takes from there when not given; ``paths``: those of them that are
    files (kept absolute); ``flags``: on/off ones (not given and not kept: False); ``own``:
    those a trial record keeps itself (not taken from ``run.json`` on a resume); ``labels``:
    {option: the setting it sets} for errors. ``given(options)``: the flat settings given
    now; ``defaults(options, record)``: the flat settings beneath them (``record``: the trial
    record the run continues, None: a new trial)."""

    name: str
    command: str
    given: Callable[[dict[str, Any]], dict[str, Any]]
    defaults: Callable[[dict[str, Any], Path | None], dict[str, Any]]
    remember: tuple[str, ...] = ()
    paths: tuple[str, ...] = ()
    flags: tuple[str, ...] = ()
    own: tuple[str, ...] = ()
    labels: Mapping[str, str] = field(default_factory=dict)


@dataclass(frozen=True)
class ResolvedSettings:
    """A run's settings, resolved (not yet validated: the entrance's one check): ``flat``
    (dotted names), the ``options`` (given, or taken from the folder's ``run.json``), the
    folder whose ``run.json`` gave them (None: none) and the trial record the run continues
    (None: a new trial)."""

    flat: dict[str, Any]
    options: dict[str, Any]
    folder: Path | None = None
    record: Path | None = None


def given_option(options: Mapping[str, Any], name: str, paths: tuple[str, ...] = ()) -> Any:
    """Option ``name`` as given (None: not given; a file path of ``paths`` made absolute)."""
    v = options.get(name)
    if v is None or v is False or v == []:
        return None
    return str(Path(v).resolve()) if name in paths and Path(str(v)).is_file() else v


def _options_from_run_file(options: dict[str, Any], entrance: Entrance) -> Path | None:
    """``options`` with every option the run in the ``resume`` / ``session_dir`` folder was
    given (its ``run.json``), in place; a contradiction refused. The folder, or None."""
    folder = options.get("resume") or options.get("session_dir")
    if not entrance.remember or not folder or not (Path(folder) / RUN_FILE).is_file():
        return None
    p = Path(folder) / RUN_FILE
    try:
        was = json.loads(p.read_text())
        by = str(was.get(ENTRANCE_KEY) or "graph")
    except (OSError, ValueError, AttributeError) as exc:
        raise InputError(f"{str(p)!r}: not readable ({exc})") from None
    if by != entrance.name:
        raise InputError(f"{str(folder)!r}: a run of `tactex {by}`, not of "
                         f"`{entrance.command}` (continue it with the command that started it)")
    for k in entrance.remember:
        if k in entrance.own and options.get("resume"):
            continue            # the trial record's own (e.g. its scene's copy)
        given, rec = given_option(options, k, entrance.paths), was.get(k)
        if given is None:
            options[k] = rec if rec is not None or k not in entrance.flags else False
        elif given != rec:
            name = entrance.labels.get(k, k)
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


def resolve_settings(options: Mapping[str, Any] | None, entrance: Entrance) -> ResolvedSettings:
    """The settings of a run (module doc) that ``entrance`` was given ``options``: the
    options (``run.json`` of the folder continued), then the settings given over those
    beneath, then a trial record's settings (its ``config.json``; ``--record-dir`` /
    ``--trial-id`` other than the record's refused). InputError names what is wrong."""
    from .resume import settings_from_record
    opts = dict(options or {})
    folder = _options_from_run_file(opts, entrance)
    given = entrance.given(opts)
    resume = given.get("resume") or ""
    record = Path(resume).resolve() if resume and (Path(resume) / "config.json").is_file() \
        and not given.get("session_file") else None
    if record is not None:         # the record's folder is where the trial goes on
        for k, there in (("record_dir", str(record.parent)), ("trial_id", record.name)):
            v = opts.get(k)
            if v not in (None, "") and (str(Path(v).resolve()) if k == "record_dir"
                                        else v) != there:
                raise InputError(f"--{k.replace('_', '-')} {v!r} given but --resume names "
                                 f"the record {str(record)!r}, in {there!r} (leave it out)")
    base = entrance.defaults(opts, record)
    if record is None:
        return ResolvedSettings({**base, **given}, opts, folder, None)
    # a value counts as given when it was given, not when it is only a default beneath
    flat = settings_from_record(resume, {**base, **given},
                                [{k: v for k, v in base.items() if k not in given}])
    return ResolvedSettings(flat, opts, folder, record)


def save_run_file(folder: str | Path, remembered: Mapping[str, Any]) -> None:
    """``<folder>/run.json`` (the trial record or session folder) before the trial starts,
    unless the folder has one: a resume keeps the run's first one. ``remembered``: what the
    run keeps of its options, with ``ENTRANCE_KEY``."""
    from ..core.outputs import dumps
    p = Path(folder) / RUN_FILE
    if not p.is_file():
        p.parent.mkdir(parents=True, exist_ok=True)
        p.write_text(dumps(dict(remembered)))
