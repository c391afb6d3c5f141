"""How the simulated follower keeps time: real-time tracking, CPU cost, lockstep throughput.

    PYTHONPATH=src python bench/bench_robot.py [--seconds 3]

Prints measured figures side by side in one run (nothing is asserted).
"""

from __future__ import annotations

import argparse
import time

from so101sim.robot import SO101SimFollower, SO101SimFollowerConfig
from so101sim.units import ZERO_POSE

GOAL = {f"{n}.pos": v for n, v in ZERO_POSE.items()}


def realtime(seconds: float) -> None:
    robot = SO101SimFollower(SO101SimFollowerConfig())
    with robot:
        wall0, sim0, cpu0 = time.perf_counter(), robot.time, time.process_time()
        lags = []
        while (now := time.perf_counter()) - wall0 < seconds:
            robot.send_action(GOAL)
            lags.append((now - wall0) - (robot.time - sim0))
            time.sleep(0.02)
        wall = time.perf_counter() - wall0
        sim = robot.time - sim0
        cpu = time.process_time() - cpu0
    print(f"real time : {sim:.3f} sim s in {wall:.3f} wall s (ratio {sim / wall:.4f})")
    print(
        f"            sim behind wall at each 50 Hz call: max {max(lags) * 1e3:.2f} ms, "
        f"mean {sum(lags) / len(lags) * 1e3:.2f} ms"
    )
    print(f"            process CPU {cpu / wall * 100:.1f}% of one core (physics thread + loop)")


def lockstep(ticks: int) -> None:
    robot = SO101SimFollower(SO101SimFollowerConfig(mode="lockstep"))
    with robot:
        t0, sim0 = time.perf_counter(), robot.time
        for _ in range(ticks):
            robot.get_observation()
            robot.send_action(GOAL)
        wall = time.perf_counter() - t0
        sim = robot.time - sim0
    print(
        f"lockstep  : {ticks} ticks of 20 ms ({sim:.2f} sim s) in {wall:.3f} wall s: "
        f"{sim / wall:.1f}x real time, {wall / ticks * 1e6:.0f} µs per tick"
    )


def main() -> None:
    p = argparse.ArgumentParser()
    p.add_argument("--seconds", type=float, default=3.0)
    p.add_argument("--ticks", type=int, default=500)
    a = p.parse_args()
    realtime(a.seconds)
    lockstep(a.ticks)


if __name__ == "__main__":
    main()
