"""The scripted expert's image episodes (what a ``so101sim dataset`` worker runs), one process:
a new environment for every episode against the environment ``expert_frames`` keeps between
clean episodes (the compiled scene and its renderers made once), side by side in one run.

    PYTHONPATH=src python bench/bench_expert_frames.py [--episodes 4] [--size 160x120]
"""

from __future__ import annotations

import argparse
import time

from so101sim.envs import expert_frames
from so101sim.envs import run as envs_run


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--episodes", type=int, default=4)
    ap.add_argument("--size", default="160x120", help="WIDTHxHEIGHT of the front and wrist images")
    args = ap.parse_args()
    w, h = (int(v) for v in args.size.split("x"))
    kw = {"cameras": ("front", "wrist"), "image_size": (h, w)}
    expert_frames("pick_cube", 0, **kw)  # the model cache warm
    for label in ("a new environment each episode", "the kept environment"):
        start, frames = time.perf_counter(), 0
        for seed in range(1, args.episodes + 1):
            if label.startswith("a new"):
                envs_run._close_kept()
            frames += len(expert_frames("pick_cube", seed, **kw).actions)
        wall = time.perf_counter() - start
        print(f"{label:32s} {frames} frames ({frames / 30:.1f} s simulated) in {wall:.2f} s: "
              f"{frames / 30 / wall:.2f}x real time")  # fmt: skip


if __name__ == "__main__":
    main()
