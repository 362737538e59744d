"""``tactex`` command line: trials, representations, the simulator, the ROS graph; the lab's
commands (experiments, benchmarks, checkpoint tools, ``sim compare``) are plug-ins of group
``tactex.commands`` (``core/plugins.py``).

Exit status: 0 success, 1 a run-time failure or a failed check (e.g. weights mismatch), 2 bad
input (named).
"""

from __future__ import annotations

import argparse
import sys
import time
from typing import TYPE_CHECKING

from ..core.errors import InputError, TrialError
from .options import add_schema_options, bounded, builds, schema_values, write_json

if TYPE_CHECKING:                    # start-up imports no numpy (``tactex --help``)
    import numpy as np

    from ..core.config import DescriptorSettings


# a trial touches every platform at least once first; a bench holds a handful (the lab scene
# has 4 comparisons): more than this is a typing error, not an experiment
MAX_COMPARISONS = 24


# what `tactex trial` takes of a trial's settings (TrialSettings, core/config.py)
TRIAL_OPTIONS = ("trial.strategy", "learner.model", "learner.weights", "learner.device",
                 "learner.representation", "trial.rounds", "trial.stop_confidence")


# what `tactex trial` takes of a trial's own (its ``cli`` section of config.json): a resume
# takes them from the record
CLI_TRIAL_OPTIONS = ("source", "comparisons", "classes", "reference", "seed")
DEFAULT_COMPARISONS = 4
DEFAULT_RECORD_DIR = "runs/trials"      # as the explorer's record_dir (config/explorer.yaml)


#: how ``run.json`` names ``tactex trial`` (``trial.settings.ENTRANCE_KEY``)
TRIAL_ENTRANCE = "trial"
#: what `tactex trial`'s run.json keeps (``_remembered``): its own options and the settings
#: options' values, given or not; a resume takes those not given from there
TRIAL_REMEMBER = CLI_TRIAL_OPTIONS + ("config", "strategy", "model", "rounds")


def _option(name: str) -> str:
    """The option of a dotted setting of ``TRIAL_OPTIONS`` (``trial.rounds`` -> ``rounds``)."""
    return name.rsplit(".", 1)[-1]


def _trial_entrance():
    """``tactex trial`` as ``trial.settings.resolve_settings`` sees it: its options
    (``CLI_TRIAL_OPTIONS``, ``config``, ``TRIAL_OPTIONS`` by their last part, ``set``,
    ``resume``, ``record_dir``, ``trial_id``) give the flat settings (``source`` ... ``seed``,
    ``config``, ``learner.*``, ``trial.*``), nothing beneath them (the preset's and the
    defaults come after, in ``cmd_trial``)."""
    from ..core.config import TrialSettings
    from ..core.schema import flatten, merge, overrides
    from ..trial.settings import Entrance

    def given(opts: dict) -> dict:
        out = flatten(merge(schema_values(argparse.Namespace(**opts), ("config",) + TRIAL_OPTIONS),
                            overrides(TrialSettings, opts.get("set"), "--set")))
        out.update({k: opts[k] for k in CLI_TRIAL_OPTIONS if opts.get(k) is not None})
        if opts.get("resume"):
            out["resume"] = opts["resume"]
        return out

    return Entrance(TRIAL_ENTRANCE, "tactex trial", given, lambda opts, record: {},
                    remember=TRIAL_REMEMBER,
                    labels={_option(n): n for n in TRIAL_OPTIONS})


def _trial_request(args: argparse.Namespace) -> tuple[dict, str | None]:
    """``tactex trial``'s options and settings, flat (``source`` ... ``seed``, ``config``,
    ``learner.*``, ``trial.*``), resolved by the one resolver of every entrance
    (``trial.settings.resolve_settings``): those given, or for ``--resume`` the record's
    (its run.json, its config.json) with the given ones checked against them (a
    contradiction is refused, both values named). Returns them and the record folder to
    continue (None: a new trial)."""
    from ..trial.settings import resolve_settings
    if not args.resume and args.source is None:
        raise InputError("--source is required (replay:DIR or sim[:difficulty]), unless "
                         "--resume continues a recorded trial")
    names = CLI_TRIAL_OPTIONS + ("config", "set", "resume", "record_dir", "trial_id") + \
        tuple(_option(n) for n in TRIAL_OPTIONS)
    options = {k: getattr(args, k) for k in names}
    options["classes"] = args.classes.split(",") if args.classes else None
    got = resolve_settings(options, _trial_entrance())
    if not args.resume:
        return got.flat, None
    if got.record is None:
        raise InputError(f"resume {args.resume!r}: not a trial record with a config.json")
    if "source" not in got.flat:
        raise InputError(f"resume {args.resume!r}: not a record of `tactex trial` (the "
                         "graph's records continue with `tactex graph run --resume`)")
    return got.flat, str(got.record)


def _remembered(opts: dict, settings) -> dict:
    """What a ``tactex trial`` run keeps in its record's run.json (``TRIAL_REMEMBER``):
    ``opts`` (its own options, defaults applied) and the values of ``settings``
    (``TrialSettings``) that options set."""
    from ..trial.settings import ENTRANCE_KEY
    out = {ENTRANCE_KEY: TRIAL_ENTRANCE, "config": settings.config,
           "strategy": settings.trial.strategy, "model": settings.learner.model,
           "rounds": settings.trial.rounds}
    out.update({k: opts[k] for k in CLI_TRIAL_OPTIONS if opts.get(k) is not None})
    return out


def cmd_trial(args: argparse.Namespace) -> int:
    """One trial through ``trial.run.TrialRun``: its record (``--record-dir``/``--trial-id``),
    report and result as the graph's; ``--resume RECORD`` continues an interrupted one (the
    recorded touches are replayed, the source is brought to where it stopped)."""
    from ..core.config import TrialSettings
    from ..core.schema import nest
    from ..core.engine import TrialSpec, default_platform_ids, refusing_no_contact
    from ..sources import open_source, trial_scene
    from ..trial.report import run_info
    from ..trial.run import TrialRun
    flat, resume = _trial_request(args)
    opts = {k: flat.get(k) for k in CLI_TRIAL_OPTIONS}
    opts["comparisons"] = opts["comparisons"] or DEFAULT_COMPARISONS
    opts["seed"] = opts["seed"] or 0
    nested = nest({k: v for k, v in flat.items() if k == "config"
                   or k.startswith(("learner.", "trial."))})
    settings = TrialSettings.check(nested, "tactex trial")
    src = open_source(opts["source"])
    cfg, tcfg = settings.learner, settings.trial
    chosen = opts["classes"]
    if chosen is not None:
        dup = sorted({c for c in chosen if chosen.count(c) > 1})
        if dup or "" in chosen:
            raise InputError(f"--classes {','.join(chosen)!r}: "
                              + (f"{', '.join(dup)} given more than once (each comparison "
                                 "platform holds another class)" if dup else "an empty name"))
    if chosen is not None and len(chosen) > MAX_COMPARISONS:
        raise InputError(f"--classes: {len(chosen)} comparison classes; at most "
                         f"{MAX_COMPARISONS}")
    if chosen is None and opts["comparisons"] < 2:
        raise InputError(f"--comparisons must be >= 2, got {opts['comparisons']}")
    seed = opts["seed"]
    platform_classes, truth = trial_scene(src, opts["comparisons"], seed, chosen,
                                          opts["reference"])
    n = len(platform_classes) - 1
    ids = default_platform_ids(n)
    spec = TrialSpec(n, cfg, tcfg, seed=seed, platform_ids=tuple(ids))
    # each touch judged against its own no-contact frame: a replay's presses come from
    # separate sensor sessions (on the robot, one camera's frame serves every touch)
    touch = refusing_no_contact(src.trial(platform_classes, seed), cfg)

    def press(platform: int, meta: dict):
        from ..core.touch import as_touch
        meta["requested"] = time.time()
        got = as_touch(touch(platform))
        meta["stamp"] = time.time()
        return got

    record_dir = args.record_dir or DEFAULT_RECORD_DIR       # a resume: the record's own
    inputs = {"cli": dict(opts, config=settings.config,
                          platforms=dict(zip(ids, platform_classes, strict=True)), truth=ids[truth]),
              "learner": cfg.model_dump(), "trial": tcfg.model_dump(), "run": run_info()}
    run = TrialRun(spec, record_dir, args.trial_id or "", press=press, inputs=inputs,
                   resume=resume, guard_reference=False,
                   log=lambda level, text: print(f"tactex: {text}", file=sys.stderr))
    from ..trial.settings import save_run_file
    save_run_file(run.dir, _remembered(opts, settings))     # a resume keeps the first one
    if resume:
        from ..trial.resume import catch_up
        catch_up(resume, touch)          # the source's next touch: the one the trial needs

    import numpy as np

    def progress(rec, line) -> None:
        if not args.quiet:
            nxt = ids[rec.platform] if rec.platform is not None else "-"
            ev = ("" if rec.evalues is None else
                  f"  E={[float(f'{e:.3g}') for e in rec.evalues]} (stop at "
                  f"{1 / tcfg.stop_alpha:g}, alpha {tcfg.stop_alpha:g})")
            print(f"round {rec.round:3d}  p={np.round(rec.probs, 2).tolist()}{ev}  next={nxt}  "
                  f"decision {rec.decision_s:.2f}s", file=sys.stderr)

    def outcome(out: dict) -> dict:
        pred = ids.index(out["prediction"])
        return {"truth": ids[truth], "correct": pred == truth, "truth_platforms": [ids[truth]],
                "classes": dict(zip(ids, platform_classes, strict=True)),
                "prediction_class": platform_classes[pred],
                "truth_class": platform_classes[truth], "config": settings.config,
                "source": opts["source"]}

    try:
        out = run.run(on_decision=progress, extra=outcome, t0=time.monotonic())
    except KeyboardInterrupt:        # Ctrl-C: the record stays resumable, its report says how
        run.close()
        from ..trial.report import write_trial_report
        try:
            write_trial_report(run.dir)
        except Exception as exc:  # noqa: BLE001 - the record is the ground truth
            print(f"tactex: report.html not written: {exc}", file=sys.stderr)
        import shlex
        print(f"tactex: trial interrupted; {run.record.n_touches} touches on disk in "
              f"{run.dir}; continue with: tactex trial --resume "
              f"{shlex.quote(str(run.dir))}", file=sys.stderr)
        return 130
    except Exception as exc:        # the trial ends in an explicit result
        run.fail(exc)
        raise
    write_json(args.json, out)
    pred = ids.index(out["prediction"])
    verdict = "correct" if out["correct"] else "wrong"
    bound = out.get("bound") or {}
    if out["sure"] is False and bound.get("rule") == "evalue":
        print(f"not sure: no e-value reached {bound['threshold']:g} (largest "
              f"{max(bound['evalues']):.3g}, alpha {bound['alpha']:g}); best guess {ids[pred]} "
              f"({platform_classes[pred]})")
    elif out["sure"] is False:
        print(f"not sure: the belief ended at {out['confidence']:.2f} < "
              f"{tcfg.stop_confidence:g}; best guess {ids[pred]} ({platform_classes[pred]})")
    elif bound.get("rule") == "evalue":
        print(f"sure: e-value {max(bound['evalues']):.3g} >= {bound['threshold']:g} (P(ever "
              f"stopping wrong) <= {bound['alpha']:g} under the evidence model)")
    print(f"reference ({platform_classes[0]}) matches {ids[pred]} "
          f"({platform_classes[pred]}); truth {ids[truth]}: {verdict}; "
          f"{out['touches']} touches; stopped: {out['stop_reason']}; record {run.dir}")
    return 0


def library_descriptors(spec: str, cfg: DescriptorSettings, sim_presses: int = 6,
                        seed: int = 0) -> dict[str, np.ndarray]:
    """{class: (n, D) descriptors} of a library, described as the learner settings ``cfg``
    describe a touch (``core.descriptor.raw_descriptor``: frames, height map, embedding): every
    press of ``replay:DIR`` that the contact guard accepts (``cfg.guards``; checked against the
    press's own no-contact frame, ``core.guards.press_verdict``: a trial never describes a
    press without contact), or ``sim_presses`` simulated presses of every catalogue fabric for
    ``sim``."""
    import numpy as np
    from ..core.descriptor import raw_descriptor
    from ..core.guards import press_verdict
    from ..core.touch import Touch
    from ..sources import open_source
    src = open_source(spec)
    out = {}
    most = press_frames(src, spec)
    if cfg.descriptor_frames > most:
        raise InputError(f"--frames {cfg.descriptor_frames}: a press of {spec} gives at most "
                         f"{most} contact frame(s) (a recorded video: the strongest and "
                         "core.contact.EXTRA_FRAMES more; an image or a simulated press: 1): "
                         f"use --frames 1..{most}")
    if spec.startswith("replay:"):
        for cls in src.classes:
            xs = []
            for path in src.presses(cls):
                try:
                    touch = src.touch(path)
                    ok, reason = (press_verdict(touch, cfg.contact_flat_min, cfg.contact_min)
                                  if cfg.guards else (True, ""))
                    if not ok:
                        print(f"tactex prepare: skipped {path}: {reason}", file=sys.stderr)
                        continue
                    xs.append(raw_descriptor(touch, cfg))
                except InputError as exc:
                    print(f"tactex prepare: skipped {path}: {exc}", file=sys.stderr)
            if xs:
                out[f"{spec}/{cls}"] = np.stack(xs)
        return out
    rng = np.random.default_rng([seed, 43])
    for cls in src.classes:
        nc = src.renderer.no_contact(rng)
        out[f"{spec}/{cls}"] = np.stack([raw_descriptor(Touch(src.press(cls, rng), nc), cfg)
                                         for _ in range(sim_presses)])
    return out


def press_frames(src, spec: str) -> int:
    """The most contact frames a press of the library ``spec`` (its source ``src``) gives:
    a recorded video the strongest and ``core.contact.EXTRA_FRAMES`` more, an image press or
    a simulated one 1."""
    from ..core.contact import EXTRA_FRAMES
    from ..sources.replay import VIDEO_EXT
    if not spec.startswith("replay:"):
        return 1
    videos = any(f.suffix.lower() in VIDEO_EXT for c in src.classes for f in src.presses(c))
    return 1 + EXTRA_FRAMES if videos else 1


def cmd_prepare(args: argparse.Namespace) -> int:
    """Describe every press of the library, fit the representation, calibrate the belief's
    temperature on the library with classes left out (``core/calibration.py``), write .npz."""
    from ..core import representation
    from ..core.config import SHIPPED_STOP, preset
    from ..core.preparation import PrepareSettings, prepare
    t0 = time.perf_counter()
    desc: dict[str, np.ndarray] = {}
    height_map = args.height_map == "on"
    cfg = preset("default", descriptor_frames=args.frames, descriptor_height_map=height_map,
                 descriptor_embedding="" if args.embedding == "none" else args.embedding,
                 descriptor_embedding_frames=args.embedding_frames)
    for spec in args.library:
        desc.update(library_descriptors(spec, cfg, args.sim_presses, args.seed))
    settings = PrepareSettings(**{name: getattr(args, name)
                                  for name in PrepareSettings.model_fields})
    rep = prepare(desc, settings, cfg, seed=args.seed)
    path = representation.save(rep, args.out)
    cal = (f"; belief temperature {rep.temperature:.4g} calibrated on {rep.calibration['trials']} "
           f"left-out trials (wrong stops at {SHIPPED_STOP:g}: "
           f"{rep.calibration['wrong_stop'][str(SHIPPED_STOP)]:.3f}, "
           f"ECE {rep.calibration['ece']:.3f})" if args.calibration != "off" else "")
    print(f"representation {rep.kind} ({rep.dims} dims of a {rep.descriptor_dim}-number "
          f"descriptor, height map {args.height_map}, embedding {args.embedding}) from {rep.classes} classes, "
          f"{rep.presses} presses ({', '.join(args.library)}){cal} -> {path} in "
          f"{time.perf_counter() - t0:.0f} s; use it with `tactex trial ... --representation "
          f"{path}`")
    return 0


# the product's commands that plug-ins do not extend (``sim`` is a group a plug-in adds to,
# ``command_group``): ``tactex trial ...`` reads no installed metadata and loads no plug-in
CLOSED_COMMANDS = frozenset({"trial", "prepare", "graph", "report", "robot", "export"})


def build_parser(command: str | None = None, plugins: bool = True) -> argparse.ArgumentParser:
    """The ``tactex`` parser; with ``command``, the options of that command only (``builds``).
    Plug-ins of group ``tactex.commands`` are called as ``add_commands(subparsers, command)``
    (``plugins=False``: the product's commands only)."""
    p = argparse.ArgumentParser(prog="tactex", description=__doc__)
    sub = p.add_subparsers(dest="cmd", required=True)
    _trial_parser(sub, command)
    _prepare_parser(sub, command)

    from . import export, graph_commands, report, robot, sim_commands
    sim_commands.add_commands(sub, command)
    export.add_commands(sub, command)
    graph_commands.add_commands(sub, command)
    report.add_commands(sub, command)
    robot.add_commands(sub, command)
    if command in CLOSED_COMMANDS or not plugins:
        return p                          # no plug-in adds to them: none is looked up
    from ..core.plugins import COMMANDS, available
    for name, ep in available(COMMANDS).items():
        try:
            ep.load()(sub, command)
        except ImportError as exc:        # a plug-in whose package is not installed
            print(f"tactex: commands {name!r} unavailable: {exc}", file=sys.stderr)
    return p


def _trial_parser(sub: argparse._SubParsersAction, command: str | None) -> None:
    t = sub.add_parser("trial", help="run one active-exploration trial")
    if not builds(command, "trial"):
        return
    from ..core.config import TrialSettings
    t.add_argument("--source", help="replay:DIR or sim[:difficulty] (required unless "
                                    "--resume)")
    t.add_argument("--comparisons", type=bounded(int, 2, MAX_COMPARISONS), default=None,
                   help=f"comparison platforms, 2..{MAX_COMPARISONS} (default "
                        f"{DEFAULT_COMPARISONS})")
    t.add_argument("--classes", help="comparison classes, comma-separated, in platform order")
    t.add_argument("--reference", help="class of the reference platform")
    add_schema_options(t, TrialSettings, ("config",) + TRIAL_OPTIONS)
    t.add_argument("--set", action="append", metavar="PATH=VALUE",
                   help="any learner or trial setting by its dotted path, e.g. "
                        "learner.match_temperature=0.1 or trial.max_touches=8 (repeatable; "
                        "after the options above; docs/reference.md lists them)")
    t.add_argument("--seed", type=bounded(int, 0, 2**31 - 1), default=None,
                   help="seed of the scene, the touches and the learner (default 0)")
    t.add_argument("--record-dir", metavar="DIR",
                   help=f"folder that receives the trial record (default {DEFAULT_RECORD_DIR}; "
                        "a resume: the record's folder)")
    t.add_argument("--trial-id", metavar="NAME",
                   help="the record's sub-folder (default trial_<date>_<time>)")
    t.add_argument("--resume", metavar="RECORD",
                   help="continue the interrupted trial recorded in folder RECORD with the "
                        "options and settings it keeps (config.json); an option given with "
                        "another value is refused")
    t.add_argument("--json")
    t.add_argument("--quiet", action="store_true")
    t.set_defaults(func=cmd_trial)


def _prepare_parser(sub: argparse._SubParsersAction, command: str | None) -> None:
    pr = sub.add_parser("prepare", help="build a representation (descriptor metric) from a "
                                        "library of presses of other materials")
    if not builds(command, "prepare"):
        return
    from ..core.config import DescriptorSettings
    pr.add_argument("--library", action="append", required=True,
                    help="replay:DIR of recorded presses, or sim (repeat to combine)")
    pr.add_argument("--frames", type=bounded(int, 1, 16), default=1,
                    help="contact frames per press, 1..16")
    pr.add_argument("--height-map", choices=("on", "off"),
                    default="on" if DescriptorSettings().descriptor_height_map else "off",
                    help="describe the library with the height map's statistics (as "
                         "learner.descriptor_height_map; a trial refuses a file prepared "
                         "with the other setting)")
    default_emb = DescriptorSettings().descriptor_embedding
    pr.add_argument("--embedding", default=default_emb or "none",
                    help="the learned embedding appended to each descriptor, as "
                         "learner.descriptor_embedding: sim (the shipped network), a weights "
                         "file, or none (a trial refuses a file prepared with another)")
    pr.add_argument("--embedding-frames", type=bounded(int, 1, 16),
                    default=DescriptorSettings().descriptor_embedding_frames,
                    help="contact frames per press averaged into the embedding, 1..16 (as "
                         "learner.descriptor_embedding_frames)")
    pr.add_argument("--sim-presses", type=bounded(int, 1, 10000), default=6,
                    help="presses per simulated fabric, 1..10000")
    from ..core.preparation import PrepareSettings
    from ..core.schema import fields
    for spec in fields(PrepareSettings):         # the one preparation schema: its defaults
        kind = float if spec.kind not in (int, float, str) else spec.kind
        pr.add_argument("--" + spec.name.replace("_", "-"), default=spec.default,
                        help=spec.description, choices=spec.choices or None,
                        type=bounded(kind, spec.lo, spec.hi) if spec.lo is not None else kind)
    pr.add_argument("--seed", type=bounded(int, 0, 2**31 - 1), default=0)
    pr.add_argument("--out", required=True, help="representation file to write (.npz)")
    pr.set_defaults(func=cmd_prepare)


# output options checked before any work: (command, option attribute) -> (kind, suffixes);
# "file" outputs must end in one of the suffixes, "dir" outputs are folders
IMAGE_SUFFIXES = (".png", ".jpg", ".jpeg", ".bmp", ".tif", ".tiff")
OUTPUTS: dict[tuple[str, str], tuple[str, tuple[str, ...]]] = {
    ("*", "json"): ("file", (".json",)),
    ("experiment", "out"): ("dir", ()),
    ("prepare", "out"): ("file", ()),
    ("sim", "out"): ("file", IMAGE_SUFFIXES),
    ("graph", "log_dir"): ("dir", ()),
    ("robot", "out"): ("file", (".yaml", ".yml")),      # measure-scene: before the arm moves
    ("export", "out"): ("dir", ()),
}


def check_outputs(args: argparse.Namespace) -> None:
    """Refuse, before any work, an output path of the command that cannot be written (named
    with its option: a folder that is a file or not writable, a wrong suffix)."""
    from ..core.outputs import check_dir, check_file
    for (cmd, attr), (kind, suffixes) in OUTPUTS.items():
        if cmd not in ("*", args.cmd):
            continue
        value = getattr(args, attr, None)
        if not value:
            continue
        option = "--" + attr.replace("_", "-")
        if kind == "dir":
            check_dir(value, option)
        else:
            check_file(value, option, suffixes)


def main(argv: list[str] | None = None) -> int:
    argv = sys.argv[1:] if argv is None else list(argv)
    import os
    import shlex
    # the command as typed, kept by every record this run writes (config.json "run")
    os.environ["TACTEX_COMMAND"] = shlex.join(["tactex", *argv])
    command = argv[0] if argv and not argv[0].startswith("-") else ""
    args = build_parser(command).parse_args(argv)
    try:
        check_outputs(args)
        return int(args.func(args) or 0)
    except InputError as exc:
        print(f"tactex: error: {exc}", file=sys.stderr)
        return 2
    except TrialError as exc:
        print(f"tactex: failed: {exc}", file=sys.stderr)
        return 1
    except OSError as exc:   # a run-time failure of a file or device (disk full, removed...)
        print(f"tactex: error: {exc}", file=sys.stderr)
        return 1


if __name__ == "__main__":
    sys.exit(main())
