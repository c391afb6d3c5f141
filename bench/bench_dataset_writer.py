"""What LeRobot's writer costs per frame in ``so101sim dataset``, as LeRobot ships it and with
``lerobot_robot_so101sim.writer.fast_writer``, side by side in one run.

    python bench/bench_dataset_writer.py [--episodes 40] [--size 160x120] [--rounds 2]

Simulates two episodes of ``pick_cube`` once (front and wrist cameras at ``--size``,
WIDTHxHEIGHT), then writes them ``--episodes`` times over into a new dataset through
``LeRobotDataset`` as ``so101sim dataset`` does (streaming encoder, one encoder thread; AV1,
LeRobot's default codec, as ``so101sim dataset --vcodec libsvtav1`` writes),
alternately without and with ``fast_writer`` and ``size_video_files``, ``--rounds`` times each.
Prints, per round, the CPU milliseconds per frame of this process (all its threads: the
encoder's too) and the wall milliseconds per frame, then the median ratio. The datasets'
statistics are compared too (the largest relative difference and where it is: the images'
standard deviations, where LeRobot's float32 sums of squares round and ``fast_writer``'s are
exact). Needs LeRobot (the robot plugin's Python). Nothing is asserted.
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import statistics
import tempfile
import time
from contextlib import nullcontext
from pathlib import Path


def cpu_seconds() -> float:
    r = resource.getrusage(resource.RUSAGE_SELF)
    return r.ru_utime + r.ru_stime


def write(episodes: list, times: int, size: tuple[int, int], fast: bool, root: Path) -> dict:
    from lerobot.datasets import LeRobotDataset
    from lerobot_robot_so101sim.dataset import ENCODER_THREADS, DatasetSettings, dataset_features
    from lerobot_robot_so101sim.writer import fast_writer, size_video_files

    settings = DatasetSettings(
        task="pick_cube", episodes=times, root=str(root), cameras=("front", "wrist"),
        image_size=size,
    )  # fmt: skip
    frames = 0
    with fast_writer() if fast else nullcontext():
        ds = LeRobotDataset.create(
            "local/bench", 30, root=root, robot_type="so101_follower",
            features=dataset_features(settings), use_videos=True, image_writer_threads=0,
            streaming_encoding=True, encoder_threads=ENCODER_THREADS,
            encoder_queue_maxsize=1000,
        )  # fmt: skip
        cpu0, wall0 = cpu_seconds(), time.perf_counter()
        for k in range(times):
            ep = episodes[k % len(episodes)]
            for t in range(len(ep.actions)):
                ds.add_frame(
                    {
                        "observation.state": ep.states[t],
                        "action": ep.actions[t],
                        "task": "Pick up the red cube.",
                        **{f"observation.images.{c}": im[t] for c, im in ep.images.items()},
                    }
                )
            ds.save_episode()
            if fast and k == 0:
                size_video_files(ds, times)
            frames += len(ep.actions)
        ds.finalize()
        cpu, wall = cpu_seconds() - cpu0, time.perf_counter() - wall0
    stats = json.loads((root / "meta" / "stats.json").read_text())
    videos = len(list((root / "videos").rglob("*.mp4")))
    return {"cpu_ms": 1000 * cpu / frames, "wall_ms": 1000 * wall / frames, "stats": stats,
            "videos": videos, "frames": frames}  # fmt: skip


def largest_difference(a: dict, b: dict, where: str = "") -> tuple[float, str]:
    """The largest relative difference between two stats.json trees, and where it is."""
    import numpy as np

    worst = (0.0, "")
    for key, value in a.items():
        path = f"{where}/{key}"
        if isinstance(value, dict):
            worst = max(worst, largest_difference(value, b[key], path))
        else:
            x, y = np.asarray(value, float), np.asarray(b[key], float)
            diff = float(np.max(np.abs(x - y) / np.maximum(np.abs(x), 1e-12)))
            worst = max(worst, (diff, path))
    return worst


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--episodes", type=int, default=40)
    parser.add_argument("--size", default="160x120", help="WIDTHxHEIGHT")
    parser.add_argument("--rounds", type=int, default=2)
    args = parser.parse_args()
    os.environ.setdefault("SVT_LOG", "1")
    import datasets
    from lerobot_robot_so101sim.dataset import DatasetSettings, quiet_encoder_logs
    from lerobot_robot_so101sim.episodes import simulate_episode

    datasets.disable_progress_bars()
    quiet_encoder_logs()
    w, h = (int(v) for v in args.size.split("x"))
    settings = DatasetSettings(
        task="pick_cube", episodes=2, root="unused", cameras=("front", "wrist"),
        image_size=(h, w),
    )  # fmt: skip
    episodes = [simulate_episode(settings, seed) for seed in (0, 1)]
    runs: dict[bool, list[dict]] = {False: [], True: []}
    with tempfile.TemporaryDirectory() as tmp:
        for r in range(args.rounds):
            for fast in (False, True):
                root = Path(tmp) / f"{'fast' if fast else 'lerobot'}{r}"
                run = write(episodes, args.episodes, (h, w), fast, root)
                runs[fast].append(run)
                row = {
                    "round": r,
                    "writer": "fast_writer" if fast else "LeRobot's",
                    "cpu_ms_per_frame": round(run["cpu_ms"], 2),
                    "wall_ms_per_frame": round(run["wall_ms"], 2),
                    "video_files": run["videos"],
                    "frames": run["frames"],
                }
                print(json.dumps(row))
    cpu = [statistics.median(x["cpu_ms"] for x in runs[f]) for f in (False, True)]
    wall = [statistics.median(x["wall_ms"] for x in runs[f]) for f in (False, True)]
    worst = largest_difference(runs[False][0]["stats"], runs[True][0]["stats"])
    print(json.dumps({
        "episodes": args.episodes, "size": args.size, "load_after": round(os.getloadavg()[0], 1),
        "cpu_ratio_lerobot_to_fast": round(cpu[0] / cpu[1], 2),
        "wall_ratio_lerobot_to_fast": round(wall[0] / wall[1], 2),
        "stats_largest_relative_difference": worst[0], "where": worst[1],
    }))  # fmt: skip


if __name__ == "__main__":
    main()
