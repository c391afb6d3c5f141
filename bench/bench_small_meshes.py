"""Milliseconds per camera frame at a policy's image size: the draft meshes against the small
draft meshes (``SMALL_FRAME_PX``), interleaved A/B/A/B so that a shared machine's load falls on
both alike.

    PYTHONPATH=src python bench/bench_small_meshes.py [--size 160x120] [--frames 100] [--rounds 3]

Prints one JSON line per round and the median ratio. Nothing is asserted.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import time

import numpy as np


def time_cameras(size: tuple[int, int], frames: int) -> tuple[np.ndarray, float]:
    """The first front and wrist frames of ``pick_cube`` at ``size`` (h, w), draft quality, and
    the milliseconds per camera frame over ``frames`` more (the observations' renderers)."""
    from so101sim.envs.run import make

    env = make("pick_cube", cameras=["front", "wrist"], image_size=size, quality="draft")
    try:
        env.reset(seed=0)
        u = env.unwrapped
        rs = [u._renderer(c, size) for c in ("front", "wrist")]
        shots = np.stack([r.render(u.sim.data).copy() for r in rs])
        t0 = time.perf_counter()
        for _ in range(frames):
            for r in rs:
                r.render(u.sim.data)
        return shots, (time.perf_counter() - t0) / (2 * frames) * 1000
    finally:
        env.close()


def ms_per_frame(size: tuple[int, int], frames: int, small: bool) -> float:
    from so101sim.recording import draft

    old = draft.SMALL_FRAME_PX
    draft.SMALL_FRAME_PX = 4096 if small else 0  # which mesh set render_model picks
    try:
        return time_cameras(size, frames)[1]
    finally:
        draft.SMALL_FRAME_PX = old


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
        big = ms_per_frame((h, w), args.frames, small=False)
        small = ms_per_frame((h, w), args.frames, small=True)
        ratios.append(big / small)
        row = {"round": i, "draft_ms": round(big, 2), "small_ms": round(small, 2),
               "ratio": round(big / small, 2), "load": round(os.getloadavg()[0], 1)}  # fmt: skip
        print(json.dumps(row), flush=True)
    print(json.dumps({"median_ratio": round(statistics.median(ratios), 2), "size": args.size}))


if __name__ == "__main__":
    main()
