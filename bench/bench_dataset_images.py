"""How fast ``so101sim dataset`` writes an image dataset: simulated seconds per wall second.

    PYTHONPATH=src:plugins/lerobot_robot_so101sim python bench/bench_dataset_images.py \
        [--episodes 8] [--workers 1,2] [--size 160x120] [--storage h264,libsvtav1,png] \
        [--out FILE]

For each worker count and image storage (videos in a codec: ``h264``, the default, or
``libsvtav1``, AV1 as lerobot-record writes; or ``png`` frames in the data files), writes
``--episodes`` episodes of ``pick_cube`` with the ``front`` and ``wrist`` cameras at ``--size``
(WIDTHxHEIGHT) through ``generate_dataset`` into a temporary folder and prints the ratio to
real time, the wall time and the load average (1 min)
before and after: on a shared machine the ratio depends on the load, so read them together.
It also prints the CPU seconds spent (this process and its workers) per simulated second,
which the load changes much less, and the ratio to real time two free cores would give at that
cost (2 / that figure, an upper bound: it assumes both cores busy all the time).
Also times the rendering alone (ms per frame, one camera, this process) with the small draft
meshes used at this size. Needs LeRobot (the robot plugin's Python). Nothing is asserted.
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import tempfile
import time
from pathlib import Path


def render_ms(size: tuple[int, int], frames: int = 60) -> float:
    """Milliseconds per frame of the front camera at ``size`` (h, w), draft quality."""
    from so101sim.envs.run import make

    env = make("pick_cube", cameras=["front"], image_size=size, quality="draft")
    try:
        env.reset(seed=0)
        u = env.unwrapped
        renderer = u._renderer("front", size)  # the one the observations use
        renderer.render(u.sim.data)
        t0 = time.perf_counter()
        for _ in range(frames):
            renderer.render(u.sim.data)
        return (time.perf_counter() - t0) / frames * 1000
    finally:
        env.close()


def cpu_seconds() -> float:
    """User + system CPU time of this process and its finished children (the workers)."""
    total = 0.0
    for who in (resource.RUSAGE_SELF, resource.RUSAGE_CHILDREN):
        r = resource.getrusage(who)
        total += r.ru_utime + r.ru_stime
    return total


CODECS = {"png": "h264", "video": "libsvtav1"}
"""--storage names that are not codecs: ``png`` (no video), ``video`` (what this bench's
``video`` measured before H.264 became the default: AV1)."""


def one_run(episodes: int, workers: int, size: tuple[int, int], storage: str) -> dict:
    from lerobot_robot_so101sim.dataset import DatasetSettings, generate_dataset

    with tempfile.TemporaryDirectory() as tmp:
        load0 = os.getloadavg()[0]
        cpu0 = cpu_seconds()
        settings = DatasetSettings(
            task="pick_cube", episodes=episodes, root=str(Path(tmp) / "ds"),
            cameras=("front", "wrist"), image_size=size, workers=workers,
            video=storage != "png", vcodec=CODECS.get(storage, storage),
        )  # fmt: skip
        report = generate_dataset(settings)
        cpu = cpu_seconds() - cpu0
        return {
            "cpu_s": round(cpu, 1),
            "cpu_s_per_sim_s": round(cpu / report.sim_seconds, 3),
            "x_real_time_if_2_free_cores": round(2 * report.sim_seconds / cpu, 2),
            "workers": workers,
            "storage": storage,
            "episodes": report.episodes,
            "frames": report.frames,
            "sim_s": round(report.sim_seconds, 1),
            "wall_s": round(report.wall_seconds, 1),
            "x_real_time": round(report.speed, 2),
            "load_before": round(load0, 1),
            "load_after": round(os.getloadavg()[0], 1),
        }


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--episodes", type=int, default=8)
    p.add_argument("--workers", default="1,2")
    p.add_argument("--size", default="160x120", help="WIDTHxHEIGHT")
    p.add_argument("--storage", default="h264,libsvtav1", help="h264, libsvtav1 or png (a list)")
    p.add_argument("--out", help="also write the results as JSON here")
    args = p.parse_args()
    w, h = (int(v) for v in args.size.split("x"))
    os.environ.setdefault("MUJOCO_GL", "egl")
    rows = [{"render_ms_per_frame": round(render_ms((h, w)), 2), "size": args.size,
             "load": round(os.getloadavg()[0], 1)}]  # fmt: skip
    print(json.dumps(rows[0]), flush=True)
    for storage in args.storage.split(","):
        for workers in (int(n) for n in args.workers.split(",")):
            row = one_run(args.episodes, workers, (h, w), storage)
            rows.append(row)
            print(json.dumps(row), flush=True)
    if args.out:
        Path(args.out).write_text(json.dumps(rows, indent=1))


if __name__ == "__main__":
    main()
