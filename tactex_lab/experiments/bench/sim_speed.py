"""``tactex bench sim``: simulator frames per second (prints the figures)."""

from __future__ import annotations

import statistics
import time

import cv2
import numpy as np


def run(frames: int = 400, repeats: int = 5) -> dict:
    """Frames per second for 320x240 contact frames on one thread (tiles cached first)."""
    cv2.setNumThreads(1)
    from tactex_ros.sources import open_source
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
