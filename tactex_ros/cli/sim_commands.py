"""``tactex sim ...``: the fabric simulator on the command line (the lab adds ``sim compare``)."""

from __future__ import annotations

import argparse
from pathlib import Path

from ..core.errors import InputError
from .options import builds, command_group


def cmd_fabrics(args: argparse.Namespace) -> int:
    from ..sources import open_source
    src = open_source("sim")
    print(f"{'#':>3} {'name':<18} {'family':<9} {'pitch':>6} {'width':>6} {'height':>7} "
          f"{'twist':>6} {'irreg':>6} {'fuzz':>5} {'rep':>4} {'soft':>5}")
    for i, (name, f) in enumerate(src.catalogue.items(), 1):
        print(f"{i:>3} {name:<18} {f.family:<9} {f.pitch_mm:>6.2f} {f.yarn_width:>6.2f} "
              f"{f.yarn_height_mm:>7.2f} {f.twist:>6.2f} {f.irregularity:>6.2f} "
              f"{f.fuzz:>5.2f} {f.repeat:>4d} {f.softness:>5.2f}")
    return 0


def cmd_render(args: argparse.Namespace) -> int:
    from ..sources import open_source
    src = open_source("sim")
    if args.depth is not None and not 0.0 < args.depth <= 3.0:
        raise InputError(f"--depth {args.depth} mm outside (0, 3]")
    import cv2
    import numpy as np
    rng = np.random.default_rng(args.seed)
    img = (src.renderer.no_contact(rng) if args.no_contact
           else src.press(args.fabric, rng, depth_mm=args.depth))
    from ..core.outputs import write_bytes
    out = Path(args.out)
    ok, buf = cv2.imencode(out.suffix.lower(), cv2.cvtColor(img, cv2.COLOR_RGB2BGR))
    if not ok:
        raise InputError(f"--out {out}: cannot encode an image as {out.suffix}")
    write_bytes(out, buf.tobytes())
    print(f"wrote {out} ({img.shape[1]}x{img.shape[0]} RGB)")
    return 0


def add_commands(sub: argparse._SubParsersAction, command: str | None = None) -> None:
    ssub = command_group(sub, "sim", "fabric simulator")
    if not builds(command, "sim"):
        return
    f = ssub.add_parser("fabrics", help="list the fabric catalogue")
    f.set_defaults(func=cmd_fabrics)
    r = ssub.add_parser("render", help="write one simulated frame")
    r.add_argument("--fabric", default="denim")
    r.add_argument("--seed", type=int, default=0)
    r.add_argument("--depth", type=float, help="press depth [mm]")
    r.add_argument("--no-contact", action="store_true")
    r.add_argument("--out", required=True)
    r.set_defaults(func=cmd_render)
