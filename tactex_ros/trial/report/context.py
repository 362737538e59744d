"""The context of a record: how it was made (``run_info``, kept in ``config.json``), the
settings changed from the preset, simulation or robot from the command, the scene's platforms
and fabrics (``scene_truth``), the session a record lies in, and the context table
(``context_rows``) the trial and session pages show."""

from __future__ import annotations

import json
import os
import shlex
from pathlib import Path
from typing import Any

from ..record import read_config
from .page import esc, when


def run_info(command: str | None = None) -> dict[str, Any]:
    """What a record keeps about how it was made (``config.json`` ``run``): the start (epoch
    seconds), tactex's version and git commit (``+dirty`` with uncommitted changes; '' outside
    a checkout), the host and the command (``TACTEX_COMMAND``, set by the ``tactex`` CLI)."""
    import socket
    import subprocess
    from importlib import metadata
    try:
        version = metadata.version("tactex")
    except metadata.PackageNotFoundError:
        version = ""
    repo = Path(__file__).resolve().parents[3]
    commit = ""
    if (repo / ".git").exists():
        try:
            commit = subprocess.run(["git", "-C", str(repo), "rev-parse", "--short=12", "HEAD"],
                                    capture_output=True, text=True, timeout=5).stdout.strip()
            dirty = subprocess.run(["git", "-C", str(repo), "status", "--porcelain",
                                    "--untracked-files=no"], capture_output=True, text=True,
                                   timeout=5).stdout.strip()
            commit += "+dirty" if commit and dirty else ""
        except (OSError, subprocess.SubprocessError):
            commit = ""
    cmd = command if command is not None else os.environ.get("TACTEX_COMMAND", "")
    return {"started": __import__("time").time(), "version": version, "commit": commit,
            "host": socket.gethostname(), "command": cmd}


def changed_settings(now: dict[str, Any], default: dict[str, Any], prefix: str = ""
                     ) -> dict[str, Any]:
    """Flattened ``section.key -> value`` of ``now`` where it differs from ``default``."""
    out: dict[str, Any] = {}
    for k, v in now.items():
        d = default.get(k) if isinstance(default, dict) else None
        if isinstance(v, dict):
            out.update(changed_settings(v, d or {}, f"{prefix}{k}."))
        elif v != d:
            out[f"{prefix}{k}"] = v
    return out


def preset_changes(cfg: dict) -> dict[str, Any]:
    """Trial and learner settings of ``config.json`` that differ from their preset's."""
    from ...core.config import TRIAL_PRESETS, TrialConfig, learner_class, preset_learner
    preset = ((cfg.get("explorer") or cfg.get("cli") or {}).get("config")) or "default"
    learner = cfg.get("learner") or {}

    def defaults(cls: type) -> dict:
        return {n: f.get_default(call_default_factory=True) for n, f in cls.model_fields.items()}
    try:             # the preset's values (as TrialSettings makes them), not validated again
        given = preset_learner(preset, {"model": learner["model"]} if "model" in learner
                               else None)
        base = {"learner": {**defaults(learner_class(given["model"])), **given},
                "trial": {**defaults(TrialConfig), **TRIAL_PRESETS[preset]}}
    except Exception:  # noqa: BLE001 - an old or foreign record: every value is shown
        base = {}
    out = changed_settings(cfg.get("trial") or {}, base.get("trial") or {}, "trial.")
    out.update(changed_settings(learner, base.get("learner") or {}, "learner."))
    return out


def command_profiles(command: str) -> dict[str, str]:
    """Simulation or robot, robot and sensor profiles read from a ``tactex graph run``
    command ('' where the command does not say)."""
    try:
        words = shlex.split(command)
    except ValueError:
        words = command.split()
    if not words:
        return {}

    def opt(name: str) -> str | None:
        for i, w in enumerate(words):
            if w == name and i + 1 < len(words):
                return words[i + 1]
            if w.startswith(name + "="):
                return w.split("=", 1)[1]
        return None
    sim = "--sim" in words or "sim:=true" in words
    return {"mode": "simulation (mock arm and camera)" if sim else "robot",
            "robot": opt("--robot") or ("sim" if sim else "fr3_crisp (default)"),
            "sensor": opt("--sensor") or ("mock camera" if sim else "gelsight_mini (default)")}


def scene_fabrics(d: Path) -> tuple[list[str], dict[str, str]]:
    """Platform ids (scene order, reference first) and their fabric where the record says."""
    import yaml
    cfg = read_config(d)
    placed = (cfg.get("session") or {}).get("placement") or {}
    ids, fabrics = [], {}
    p = d / "scene.yaml"
    cli = (cfg.get("cli") or {}).get("platforms")
    if not p.is_file() and isinstance(cli, dict):      # `tactex trial`: the source's classes
        return [str(k) for k in cli], {str(k): str(v) for k, v in cli.items()}
    if p.is_file():
        doc = yaml.safe_load(p.read_text()) or {}
        plats = doc.get("platforms") or []
        ref = [q for q in plats if q.get("role") == "reference"]
        for q in ref + [q for q in plats if q.get("role") != "reference"]:
            ids.append(str(q.get("id")))
            f = placed.get(str(q.get("id"))) or q.get("sim_fabric") or q.get("replay_class")
            if f:
                fabrics[str(q.get("id"))] = str(f)
    return ids, fabrics


def scene_truth(folder: str | Path) -> list[str] | None:
    """The comparisons of record ``folder`` whose fabric is the reference's, when every
    platform of its scene names its fabric (``sim_fabric``, ``replay_class`` or a session's
    placement): a simulated or replayed trial's truth. None when a platform names none (a
    lab scene: the truth is not known) or no comparison matches."""
    ids, fabrics = scene_fabrics(Path(folder))
    if len(ids) < 2 or any(i not in fabrics for i in ids):
        return None
    same = [i for i in ids[1:] if fabrics[i] == fabrics[ids[0]]]
    return same or None


def session_of(d: Path) -> Path | None:
    """The session folder a trial record lies in (None: a single trial)."""
    from ..session import SESSION_FILE
    return d.parent if (d.parent / SESSION_FILE).is_file() else None


def failed_attempts(touches: list[dict]) -> int:
    """Press attempts that failed, over the record's touch lines: an accepted touch's attempts
    beyond its first, every attempt of a failed press (the motion node retries a press up to
    ``retries`` times before it answers)."""
    return sum(max(0, int(t.get("attempts") or 1) - 1) if t.get("accepted")
               else int(t.get("attempts") or 0) for t in touches)


MISSING = "<span class='muted'>not recorded</span>"


def stop_cell(trial: dict) -> tuple[str, str]:
    """(label, HTML) of a record's stop: the threshold on the belief, or the e-value rule
    with its bound on ever stopping wrong; ``trial``: config.json's ``trial`` section."""
    if trial.get("stop_rule") == "evalue":
        null = trial.get("stop_null", "library")
        return ("stop rule", f"e-value: P(ever stopping wrong) &le; alpha = "
                             f"{esc(trial.get('stop_alpha'))}, null: {esc(null)}"
                             + (" (the model's and the scene's own comparisons, the closer)"
                                if null == "scene" else " (the evidence model's)"))
    return "stop threshold", f"belief &ge; {esc(trial.get('stop_confidence'))}"


def run_context(cfg: dict, res: dict | None = None, command_id: str = "command"
                ) -> dict[str, str]:
    """How a record was made, label -> HTML cell, in the context table's order: tactex's
    version and commit, the command (``command_id``: its element id, '' for none), preset,
    model, strategy, the stop, the rounds cap, the settings changed from the preset, seed,
    simulation or robot, robot and sensor profiles, host. ``cfg``: its config.json; ``res``:
    its result (the model and strategy it names win)."""
    res = res or {}
    run = cfg.get("run") or {}
    ex, tr, le = cfg.get("explorer") or {}, cfg.get("trial") or {}, cfg.get("learner") or {}
    prof = command_profiles(run.get("command", ""))
    cli = cfg.get("cli") or {}
    if cli:          # `tactex trial`: touches from a source, no robot
        ex = cli
        prof = {"mode": f"no robot: touches from source {cli.get('source')}",
                "robot": "none", "sensor": "the source's recorded or simulated frames"}
    changes = dict(run.get("non_default") or {})
    changes.update(preset_changes(cfg))
    nd = ", ".join(f"<code>{esc(k)}={esc(json.dumps(v))}</code>"
                   for k, v in sorted(changes.items())) or "none"
    ident = f" id='{command_id}'" if command_id else ""
    stop_label, stop = stop_cell(tr)
    return {"tactex": (esc(run.get("version")) or MISSING) + " &middot; commit "
            + (f"<code>{esc(run['commit'])}</code>" if run.get("commit") else MISSING),
            "command": f"<code{ident}>{esc(run['command'])}</code>"
            if run.get("command") else MISSING,
            "preset": esc(ex.get("config") or "default"),
            "model": esc(res.get("model") or le.get("model")),
            "strategy": esc(res.get("strategy") or tr.get("strategy")),
            stop_label: stop,
            "rounds cap": esc(tr.get("rounds")),
            "settings changed from the preset": nd,
            "seed": esc(ex.get("seed")),
            "simulation or robot": esc(prof.get("mode")) or MISSING,
            "robot profile": esc(prof.get("robot")) or MISSING,
            "sensor": esc(prof.get("sensor")) or MISSING,
            "host": esc(run.get("host")) or MISSING}


def context_rows(d: Path, cfg: dict, res: dict, rec: dict) -> list[list[str]]:
    """The trial report's context table: the session trial, the date, how it was made
    (``run_context``) and the scene with each platform's fabric."""
    run = cfg.get("run") or {}
    ex = cfg.get("cli") or cfg.get("explorer") or {}
    first = min([t.get("requested") or 1e18 for t in rec["touches"]] or [1e18])
    started = run.get("started") or (first if first < 1e18 else None)
    ids, fabrics = scene_fabrics(d)
    scene = ", ".join(f"{esc(p)}: {esc(fabrics.get(p, '?'))}" for p in ids)
    cells = run_context(cfg, res)
    host = cells.pop("host")
    rows = [["date", esc(when(started)) or MISSING], *([k, v] for k, v in cells.items()),
            ["scene", f"{esc(Path(ex.get('scene_file') or '').name or ex.get('source'))} "
                      f"&middot; {scene}"],
            ["host", host]]
    sess = cfg.get("session") or {}
    if sess:
        rows.insert(0, ["session trial", f"{esc(sess.get('name'))}, trial "
                                          f"{esc(sess.get('trial'))}"])
    return rows
