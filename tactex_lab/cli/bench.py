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


def cmd_bench_env(args: argparse.Namespace) -> int:
    from tactex_ros.core.config import SHIPPED_STOP, preset, trial_preset
    from tactex_lab.env.agents import EngineAgent, evaluate
    from tactex_lab.env.touch_env import TouchEnv, parse_seeds
    from tactex_lab.experiments.curves import parse_setting
    from tactex_lab.experiments.real import DEFAULT_SETTINGS
    seeds = parse_seeds(args.seeds)
    settings = [parse_setting(s) for s in args.agent or DEFAULT_SETTINGS]
    labels = [s[0] for s in settings]
    if len(set(labels)) != len(labels):
        raise InputError(f"--agent labels must be unique, got {labels}")
    stop = SHIPPED_STOP if args.stop is None else args.stop
    agents = {}
    for label, pre, strategy, over in settings:
        learner = preset(pre, **over)
        st = strategy or trial_preset(pre).strategy
        agents[label] = (lambda learner=learner, st=st:
                         EngineAgent(args.comparisons, learner, st, stop, args.budget))
    out = evaluate(lambda: TouchEnv(args.source, args.comparisons, args.budget), agents, seeds)
    print(f"{args.source}: {len(seeds)} scenes (seeds {args.seeds}), {args.comparisons} "
          f"comparisons, budget {args.budget}, stop at belief {stop:g}")
    for label, r in out.items():
        print(f"  {label:>14}: accuracy {r['accuracy']:.3f}  touches after the baseline "
              f"{r['touches']:.2f}  reward {r['reward']:.3f}")
    write_json(args.json, {"source": args.source, "seeds": seeds,
                           "comparisons": args.comparisons, "budget": args.budget,
                           "stop": stop, "agents": out})
    return 0


def cmd_bench_press(args: argparse.Namespace) -> int:
    from tactex_ros.robot import press_bench
    out = press_bench.run(args.scene, args.worlds, args.seed, heavy=args.heavy,
                          approach_height=args.approach_height,
                          surface_tolerance=args.surface_tolerance, robot=args.robot)
    print(press_bench.report(out))
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

    bp = bsub.add_parser("press", help="the press controller in seeded faulty mock worlds "
                                        "(ROS-free): capture share, refusals, force, time")
    bp.add_argument("--scene", required=True, help="scene file (e.g. config/scene.yaml)")
    bp.add_argument("--worlds", type=bounded(int, 1, 100000), default=1000)
    bp.add_argument("--seed", type=bounded(int, 0, 2 ** 31 - 1), default=0)
    bp.add_argument("--robot", help="robot profile whose law presses (default: by the "
                                    "scene's frame_id: fr3_crisp, panda_crisp)")
    bp.add_argument("--heavy", action="store_true",
                    help="heavy-arm worlds: 6 kg apparent mass, 2-4 N static force down")
    bp.add_argument("--approach-height", type=bounded(float, 0.001, 0.3),
                    help="the scene's approach_height changed [m]")
    bp.add_argument("--surface-tolerance", type=bounded(float, 0.0, 0.05),
                    help="the scene's surface_tolerance changed [m] (a measured scene)")
    bp.add_argument("--json")
    bp.set_defaults(func=cmd_bench_press)

    be = bsub.add_parser("env", help="tactex's agents in the touch environment (seeded scenes "
                                     "of experiment real)")
    be.add_argument("--source", required=True, help="replay:DIR of recorded presses (or sim)")
    be.add_argument("--seeds", default="0-9", help="scenes by seed: 0-9, 0,3,7 or 0-4,10")
    be.add_argument("--comparisons", type=bounded(int, 2, 24), default=4)
    be.add_argument("--budget", type=bounded(int, 0, 1000), default=15,
                    help="touches after the baseline")
    be.add_argument("--stop", type=bounded(float, 0.0, 1.0),
                    help="stop threshold of the belief (default: the shipped one)")
    be.add_argument("--agent", action="append", metavar="LABEL=PRESET[:PATH=VALUE,...]",
                    help="an agent as experiment real's --setting (repeat); default: "
                         "default, random, variance")
    be.add_argument("--json")
    be.set_defaults(func=cmd_bench_env)
