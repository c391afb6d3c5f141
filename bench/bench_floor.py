"""Milliseconds per camera frame with the floor drawn as MuJoCo's 200 × 200 grid against the
few quads of ``so101sim.recording.floor`` (the ``draft`` preset's), interleaved A/B/A/B so that a
shared machine's load falls on both alike, and the largest pixel difference between the two.

    PYTHONPATH=src python bench/bench_floor.py [--size 160x120] [--frames 100] [--rounds 3]

Prints one JSON line per round and the median ratio. Nothing is asserted.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics

import numpy as np


def frames_and_ms(size: tuple[int, int], frames: int, few_quads: bool) -> tuple[np.ndarray, float]:
    from bench_small_meshes import time_cameras  # this folder: run as bench/bench_floor.py

    from so101sim.recording import frames as frames_module

    old = frames_module.finite_planes
    if not few_quads:
        frames_module.finite_planes = lambda model: ()  # MuJoCo's infinite plane, as before
    try:
        return time_cameras(size, frames)
    finally:
        frames_module.finite_planes = old


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--size", default="160x120", help="WIDTHxHEIGHT")
    p.add_argument("--frames", type=int, default=100)
    p.add_argument("--rounds", type=int, default=3)
    args = p.parse_args()
    os.environ.setdefault("MUJOCO_GL", "egl")
    w, h = (int(v) for v in args.size.split("x"))
    ratios = []
    for i in range(args.rounds):
        grid, grid_ms = frames_and_ms((h, w), args.frames, few_quads=False)
        quads, quads_ms = frames_and_ms((h, w), args.frames, few_quads=True)
        ratios.append(grid_ms / quads_ms)
        diff = int(np.abs(grid.astype(int) - quads.astype(int)).max())
        row = {"round": i, "grid_ms": round(grid_ms, 2), "few_quads_ms": round(quads_ms, 2),
               "ratio": round(grid_ms / quads_ms, 2), "max_pixel_difference": diff,
               "load": round(os.getloadavg()[0], 1)}  # fmt: skip
        print(json.dumps(row), flush=True)
    print(json.dumps({"median_ratio": round(statistics.median(ratios), 2), "size": args.size}))


if __name__ == "__main__":
    main()
