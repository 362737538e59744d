"""``tactex sim ...`` and ``tactex bench sim``: the fabric simulator on the command line."""

from __future__ import annotations

import argparse
import json
import statistics
import time
from pathlib import Path

import cv2
import numpy as np

from .core.errors import TactexError


def cmd_fabrics(args: argparse.Namespace) -> int:
    from .sim.source import SimSource
    src = SimSource()
    print(f"{'#':>3} {'name':<18} {'family':<9} {'pitch':>6} {'width':>6} {'height':>7} "
          f"{'twist':>6} {'irreg':>6} {'fuzz':>5} {'rep':>4}")
    for i, (name, f) in enumerate(src.catalogue.items(), 1):
        print(f"{i:>3} {name:<18} {f.family:<9} {f.pitch_mm:>6.2f} {f.yarn_width:>6.2f} "
              f"{f.yarn_height_mm:>7.2f} {f.twist:>6.2f} {f.irregularity:>6.2f} "
              f"{f.fuzz:>5.2f} {f.repeat:>4d}")
    return 0


def cmd_render(args: argparse.Namespace) -> int:
    from .sim.source import SimSource
    src = SimSource()
    if args.depth is not None and not 0.0 < args.depth <= 3.0:
        raise TactexError(f"--depth {args.depth} mm outside (0, 3]")
    rng = np.random.default_rng(args.seed)
    img = (src.renderer.no_contact(rng) if args.no_contact
           else src.press(args.fabric, rng, depth_mm=args.depth))
    out = Path(args.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    if not cv2.imwrite(str(out), cv2.cvtColor(img, cv2.COLOR_RGB2BGR)):
        raise TactexError(f"--out {out}: cannot write an image there")
    print(f"wrote {out} ({img.shape[1]}x{img.shape[0]} RGB)")
    return 0


def bench_sim(frames: int = 400, repeats: int = 5) -> dict:
    """Frames per second for 320x240 contact frames on one thread (tiles cached first)."""
    cv2.setNumThreads(1)
    from .sim.source import SimSource
    src = SimSource()
    names = src.classes
    rng = np.random.default_rng(0)
    for n in names:
        src.press(n, rng)  # build and cache every height tile (not a per-touch cost)
    fps = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        for i in range(frames):
            src.press(names[i % len(names)], rng)
        fps.append(frames / (time.perf_counter() - t0))
    out = {"fps_median": statistics.median(fps), "fps_runs": fps, "frames_per_run": frames,
           "opencv_threads": 1}
    print(f"simulator: {out['fps_median']:.0f} frames/s median over {repeats} runs of "
          f"{frames} contact frames (320x240, one OpenCV thread; min {min(fps):.0f}, "
          f"max {max(fps):.0f})")
    return out


def cmd_bench_sim(args: argparse.Namespace) -> int:
    out = bench_sim(args.frames, args.repeats)
    if args.json:
        Path(args.json).write_text(json.dumps(out, indent=2))
    return 0


def add_commands(sub, bench_sub) -> None:
    s = sub.add_parser("sim", help="fabric simulator")
    ssub = s.add_subparsers(dest="scmd", required=True)
    f = ssub.add_parser("fabrics", help="list the fabric catalogue")
    f.set_defaults(func=cmd_fabrics)
    r = ssub.add_parser("render", help="write one simulated frame")
    r.add_argument("--fabric", default="denim")
    r.add_argument("--seed", type=int, default=0)
    r.add_argument("--depth", type=float, help="press depth [mm]")
    r.add_argument("--no-contact", action="store_true")
    r.add_argument("--out", required=True)
    r.set_defaults(func=cmd_render)
    b = bench_sub.add_parser("sim", help="simulator frames per second")
    b.add_argument("--frames", type=int, default=400)
    b.add_argument("--repeats", type=int, default=5)
    b.add_argument("--json")
    b.set_defaults(func=cmd_bench_sim)
