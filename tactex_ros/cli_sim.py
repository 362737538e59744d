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
    from .sources import open_source
    src = open_source("sim")
    print(f"{'#':>3} {'name':<18} {'family':<9} {'pitch':>6} {'width':>6} {'height':>7} "
          f"{'twist':>6} {'irreg':>6} {'fuzz':>5} {'rep':>4}")
    for i, (name, f) in enumerate(src.catalogue.items(), 1):
        print(f"{i:>3} {name:<18} {f.family:<9} {f.pitch_mm:>6.2f} {f.yarn_width:>6.2f} "
              f"{f.yarn_height_mm:>7.2f} {f.twist:>6.2f} {f.irregularity:>6.2f} "
              f"{f.fuzz:>5.2f} {f.repeat:>4d}")
    return 0


def cmd_render(args: argparse.Namespace) -> int:
    from .sources import open_source
    src = open_source("sim")
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
    from .sources import open_source
    src = open_source("sim")
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
    add_compare(ssub)
    b = bench_sub.add_parser("sim", help="simulator frames per second")
    b.add_argument("--frames", type=int, default=400)
    b.add_argument("--repeats", type=int, default=5)
    b.add_argument("--json")
    b.set_defaults(func=cmd_bench_sim)


def compare_with_real(real_dir: str, out_png: str, seed: int = 0, n: int = 12) -> dict:
    """Statistics of simulated vs real GelSight frames, and a side-by-side picture.

    Per set: mean RGB of no-contact frames, mean |contact - no-contact| (grey levels), and the
    share of spectral power above 0.1 cycles/px in the contact-minus-no-contact image (how much
    fine detail the contact adds). Real frames: first frame and strongest-contact frame of each
    press of the first ``n`` classes of ``real_dir``.
    """
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from .core.contact import strongest_contact
    from .sources import open_source
    from .sources.replay import ReplaySource, read_video

    def hf_share(diff: np.ndarray) -> float:
        g = diff.astype(np.float64).mean(axis=2)
        p = np.abs(np.fft.fftshift(np.fft.fft2(g - g.mean()))) ** 2
        fy = np.fft.fftshift(np.fft.fftfreq(g.shape[0]))[:, None]
        fx = np.fft.fftshift(np.fft.fftfreq(g.shape[1]))[None, :]
        return float(p[np.hypot(fx, fy) > 0.1].sum() / p.sum())

    rep = ReplaySource(real_dir)
    real_pairs = []
    for cls in rep.classes[:n]:
        try:
            arr = read_video(rep.presses(cls)[0])[..., ::-1]  # BGR -> RGB
        except TactexError:
            continue
        idx, _ = strongest_contact(arr)
        real_pairs.append((cls, arr[0], arr[idx]))
    sim = open_source("sim")
    rng = np.random.default_rng(seed)
    sim_pairs = [(name, sim.renderer.no_contact(rng), sim.press(name, rng))
                 for name in sim.classes[:: max(1, len(sim.classes) // n)][:n]]

    def stats(pairs):
        return {
            "no_contact_mean_rgb": np.mean([p[1].reshape(-1, 3).mean(0) for p in pairs],
                                           0).round(1).tolist(),
            "no_contact_std_rgb": np.mean([p[1].reshape(-1, 3).std(0) for p in pairs],
                                          0).round(1).tolist(),
            "contact_minus_no_contact_mean_abs": float(np.mean(
                [np.abs(p[2].astype(float) - p[1]).mean() for p in pairs])),
            "high_frequency_share_of_difference": float(np.mean(
                [hf_share(p[2].astype(float) - p[1]) for p in pairs])),
        }

    result = {"real": stats(real_pairs), "sim": stats(sim_pairs),
              "real_classes": [p[0] for p in real_pairs], "sim_fabrics": [p[0] for p in sim_pairs]}
    k = min(4, len(real_pairs), len(sim_pairs))
    fig, axes = plt.subplots(2, 2 * k, figsize=(4 * k, 3.2))
    for i in range(k):
        for row, (pairs, label) in enumerate(((real_pairs, "real"), (sim_pairs, "sim"))):
            name, nc, c = pairs[i]
            axes[row, 2 * i].imshow(c)
            axes[row, 2 * i].set_title(f"{label}: {name}", fontsize=7)
            d = np.clip(np.abs(c.astype(float) - nc) * 8, 0, 255).astype(np.uint8)
            axes[row, 2 * i + 1].imshow(d)
            axes[row, 2 * i + 1].set_title("|contact - no contact| x8", fontsize=7)
    for a in axes.ravel():
        a.axis("off")
    fig.tight_layout()
    Path(out_png).parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out_png, dpi=110)
    plt.close(fig)
    return result


def cmd_compare(args: argparse.Namespace) -> int:
    res = compare_with_real(args.real, args.out, args.seed)
    for k in ("real", "sim"):
        print(k, json.dumps(res[k]))
    if args.json:
        Path(args.json).write_text(json.dumps(res, indent=2))
    print(f"wrote {args.out}")
    return 0


def add_compare(ssub) -> None:
    c = ssub.add_parser("compare", help="simulated vs real frames: statistics and a picture")
    c.add_argument("--real", required=True, help="folder of real presses (<class>/<file>)")
    c.add_argument("--out", required=True, help="side-by-side PNG")
    c.add_argument("--seed", type=int, default=0)
    c.add_argument("--json")
    c.set_defaults(func=cmd_compare)
