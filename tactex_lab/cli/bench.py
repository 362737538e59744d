"""``tactex bench latency|sim``: the benchmarks (``experiments/bench/``) on the command line."""

from __future__ import annotations

import argparse

from tactex_ros.core.errors import InputError
from tactex_ros.cli.options import bounded, builds, write_json


def device_text(text: str) -> str:
    """argparse type: a ``learner.device`` value (``core/config.DEVICE_PATTERN``)."""
    import re
    from tactex_ros.core.config import DEVICE_PATTERN
    if not re.fullmatch(DEVICE_PATTERN, text):
        raise argparse.ArgumentTypeError(f"{text!r}: choose cpu, cuda, cuda:N or auto")
    return text


def cmd_bench_latency(args: argparse.Namespace) -> int:
    from tactex_ros.core.config import PRESETS
    from tactex_lab.experiments.bench import latency
    unknown = [c for c in args.configs if latency.parse_config(c)[1] not in PRESETS]
    if unknown:
        raise InputError(f"--configs: unknown configuration(s) {unknown}; choose from "
                         f"{', '.join(PRESETS)}")
    devices = ("cpu",) if args.device == "cpu" else ("cpu", args.device)
    out = latency.run(touch_counts=args.touches, repeats=args.repeats,
                      seed_epochs=args.seed_epochs, configs=tuple(args.configs),
                      devices=devices)
    write_json(args.json, out)
    return 0


def cmd_bench_sim(args: argparse.Namespace) -> int:
    from tactex_lab.experiments.bench import sim_speed
    out = sim_speed.run(args.frames, args.repeats)
    write_json(args.json, out)
    return 0


def add_commands(sub: argparse._SubParsersAction, command: str | None = None) -> None:
    b = sub.add_parser("bench", help="benchmarks (print figures)")
    if not builds(command, "bench"):
        return
    bsub = b.add_subparsers(dest="bcmd", required=True)
    bl = bsub.add_parser("latency", help="per-round decision time, seed-faithful vs default")
    bl.add_argument("--touches", type=bounded(int, 1, 1000), nargs="+", default=[5, 15, 25],
                    help="stored touches at which a decision is timed, 1..1000 each")
    bl.add_argument("--repeats", type=bounded(int, 1, 1000), default=5)
    bl.add_argument("--seed-epochs", type=bounded(int, 1, 10), default=1,
                    help="epochs actually timed for the seed-faithful config on the CPU "
                         "(scaled to 10; a GPU times all 10)")
    bl.add_argument("--device", type=device_text, default="cpu",
                    help="also time every CNN configuration on this torch device, side by side "
                         "with the CPU: cuda, cuda:N or auto (an absent GPU is refused)")
    bl.add_argument("--configs", nargs="+", default=["seed_faithful", "cnn", "default"],
                    help="configurations to time (ratios are to the last one): a preset, or "
                         "label=preset:PATH=value,... e.g. "
                         "prepared=default:learner.representation=r.npz")
    bl.add_argument("--json")
    bl.set_defaults(func=cmd_bench_latency)

    bs = bsub.add_parser("sim", help="simulator frames per second")
    bs.add_argument("--frames", type=bounded(int, 1, 1000000), default=400)
    bs.add_argument("--repeats", type=bounded(int, 1, 1000), default=5)
    bs.add_argument("--json")
    bs.set_defaults(func=cmd_bench_sim)
