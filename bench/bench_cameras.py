"""How fast the follower's simulated cameras render, and what that does to a 30 fps record loop.

    PYTHONPATH=src python bench/bench_cameras.py [--seconds 3] [--loop-seconds 10]

1. Camera frames/s through ``get_observation()`` (lockstep, so only rendering and the joint
   read are timed): draft and full meshes, 224×224 and 640×480, one camera (front) and two
   (front + wrist).
2. A LeRobot-style record loop at 30 fps (``get_observation``, ``send_action``, sleep to the
   next 1/30 s, as ``lerobot-record``'s ``record_loop`` does) with two cameras, in real-time
   mode (the default) and in lockstep mode: the loop rate reached and how far the dataset's
   timestamps (frame / 30) drift from simulated time.

Prints measured figures side by side in one run (nothing is asserted); on a busy machine every
figure drops, the ratios between them much less.
"""

from __future__ import annotations

import argparse
import time

from so101sim import gl
from so101sim.robot import SO101SimFollower, SO101SimFollowerConfig
from so101sim.units import STARTING_POSE, ZERO_POSE

FPS = 30
KEYS = [f"{n}.pos" for n in STARTING_POSE]


def cameras(n: int, width: int, height: int, quality: str) -> dict[str, dict]:
    names = ("front", "wrist")[:n]
    return {c: {"width": width, "height": height, "quality": quality} for c in names}


def frames_per_second(n: int, width: int, height: int, quality: str, seconds: float) -> float:
    cfg = SO101SimFollowerConfig(mode="lockstep", cameras=cameras(n, width, height, quality))
    with SO101SimFollower(cfg) as robot:
        robot.get_observation()  # the first frame builds the scene
        calls, t0 = 0, time.perf_counter()
        while calls < 3 or time.perf_counter() - t0 < seconds:
            robot.get_observation()
            calls += 1
        return calls * n / (time.perf_counter() - t0)


def goal(i: int) -> dict[str, float]:
    """A slow back-and-forth between the rest pose and the zero pose (a 6 s cycle)."""
    s = abs((i / FPS) % 6.0 - 3.0) / 3.0  # 1 -> 0 -> 1
    return {f"{k}.pos": s * STARTING_POSE[k] + (1 - s) * ZERO_POSE[k] for k in STARTING_POSE}


def record_loop(mode: str, width: int, height: int, seconds: float) -> str:
    """``lerobot-record``'s loop timing with two cameras; returns one line of figures."""
    # lockstep as the LeRobot plugin does it: to sim0 + frames / FPS after each action
    cfg = SO101SimFollowerConfig(
        mode=mode, cameras=cameras(2, width, height, "auto"), lockstep_action_seconds=0.0
    )
    with SO101SimFollower(cfg) as robot:
        robot.get_observation()
        sim0, wall0 = robot.time, time.perf_counter()
        frames = late = 0
        while time.perf_counter() - wall0 < seconds:
            start = time.perf_counter()
            robot.get_observation()
            robot.send_action(goal(frames))
            frames += 1
            if mode == "lockstep":
                robot.step(max(0.0, sim0 + frames / FPS - robot.time))
            spent = time.perf_counter() - start
            if spent > 1 / FPS:
                late += 1
            time.sleep(max(0.0, 1 / FPS - spent))
        wall = time.perf_counter() - wall0
        sim = robot.time - sim0
    dataset = frames / FPS  # the timestamps LeRobot gives the frames
    return (
        f"{mode:8s} {width}x{height}: {frames / wall:5.1f} frames/s (target {FPS}), "
        f"{late / frames:4.0%} late; dataset time {dataset:5.2f} s for {sim:5.2f} s simulated "
        f"(ratio {dataset / sim:.2f}) in {wall:5.2f} s of wall clock"
    )


def main() -> None:
    p = argparse.ArgumentParser()
    p.add_argument("--seconds", type=float, default=3.0, help="per rendering figure")
    p.add_argument("--loop-seconds", type=float, default=10.0, help="per record-loop figure")
    a = p.parse_args()

    gl.prepare_for_rendering()
    renderer = "CPU (software OpenGL)" if gl.software_rendering() else "GPU"
    print(f"OpenGL: {gl.selection}; renders on the {renderer}; 'auto' quality is ", end="")
    print("draft" if gl.software_rendering() else "full")
    print("camera frames/s through get_observation() (lockstep):")
    for quality in ("draft", "full"):
        for width, height in ((224, 224), (640, 480)):
            row = [
                f"{n} camera{'s' if n > 1 else ' '}: "
                f"{frames_per_second(n, width, height, quality, a.seconds):6.1f}"
                for n in (1, 2)
            ]
            print(f"  {quality:5s} {width}x{height}:  " + "   ".join(row))
    print(f"a {FPS} fps record loop with two cameras (front + wrist, 'auto' quality):")
    for mode in ("realtime", "lockstep"):
        for width, height in ((224, 224), (640, 480)):
            print("  " + record_loop(mode, width, height, a.loop_seconds))


if __name__ == "__main__":
    main()
