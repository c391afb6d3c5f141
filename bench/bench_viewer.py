"""The viewer on this machine's OpenGL: frames/s with the draft and the full meshes, and how far
the real-time robot's physics falls behind the wall clock with the viewer open.

    Xvfb :99 &
    DISPLAY=:99 PYTHONPATH=src python bench/bench_viewer.py [--seconds 4] [--busy 0]

``--busy N`` runs N CPU-burning processes beside it (a busy machine). Prints measured figures
side by side in one run (nothing is asserted); needs a display.

- frames/s: states a mirrored viewer drew per wall second, offered 240 times a second (its
  drawing rate), and how long ``sync()`` kept the caller: a mirrored viewer only copies the
  state; the viewer on the live data (``mirror=False``, the robot's viewer before) waits while
  MuJoCo draws.
- physics lag: wall-clock time minus simulated time since the start, sampled 100 times a second
  (sim time read first, so the figure is an upper bound), for the real-time robot with no
  viewer, the draft and the full mirrored viewer, and the previous design (the physics thread
  syncing the viewer on the live data, holding the lock), as a reference.
"""

from __future__ import annotations

import argparse
import contextlib
import math
import subprocess
import sys
import threading
import time
from collections.abc import Iterator

import numpy as np

from so101sim import gl
from so101sim.robot import SO101SimFollower, SO101SimFollowerConfig
from so101sim.simulation import Pacer, Simulation
from so101sim.viewer import open_viewer

OFFER_HZ = 240.0


@contextlib.contextmanager
def busy(n: int) -> Iterator[None]:
    procs = [subprocess.Popen([sys.executable, "-c", "while True: pass"]) for _ in range(n)]
    try:
        yield
    finally:
        for p in procs:
            p.kill()
            p.wait()


def frames(quality: str, mirror: bool, seconds: float) -> str:
    """Offer the viewer a new state OFFER_HZ times a second; count what it drew."""
    sim = Simulation()
    waits = []
    with open_viewer(sim.model, sim.data, mirror=mirror, quality=quality) as v:
        drawn0 = getattr(v, "frames", 0)
        cpu0, wall0 = time.process_time(), time.perf_counter()
        n = 0
        while time.perf_counter() - wall0 < seconds:
            sim.step(2)
            t = time.perf_counter()
            v.sync()
            waits.append(time.perf_counter() - t)
            n += 1
            time.sleep(max(0.0, wall0 + n / OFFER_HZ - time.perf_counter()))
        wall = time.perf_counter() - wall0
        cpu = time.process_time() - cpu0
        drawn = (getattr(v, "frames", 0) - drawn0) if mirror else n  # live: each sync drew
    w = np.array(waits) * 1e3
    what = f"{quality:5s} {'mirrored' if mirror else 'live    '}"
    return (
        f"  {what}: {drawn / wall:6.1f} frames/s drawn; sync() kept the caller median "
        f"{np.median(w):6.2f} ms, max {w.max():6.2f} ms; process CPU {cpu / wall * 100:4.0f}%"
    )


def sample_lag(now_sim, seconds: float) -> np.ndarray:
    """Wall time minus simulated time since the first sample, 100 times a second (ms)."""
    s0, w0 = now_sim(), time.perf_counter()
    lags = []
    while (time.perf_counter() - w0) < seconds:
        s = now_sim()
        lags.append((time.perf_counter() - w0) - (s - s0))
        time.sleep(0.01)
    return np.array(lags) * 1e3


def lag_line(what: str, lags: np.ndarray, extra: str = "") -> str:
    return (
        f"  {what:22s}: behind the wall clock max {lags.max():7.1f} ms, "
        f"p99 {np.percentile(lags, 99):7.1f} ms, at the end {lags[-1]:7.1f} ms{extra}"
    )


def robot_lag(quality: str | None, seconds: float) -> str:
    viewer = quality is not None
    cfg = SO101SimFollowerConfig(viewer=viewer, viewer_quality=quality or "auto")
    robot = SO101SimFollower(cfg)
    with robot:
        time.sleep(0.5)  # let the window open and settle
        t0 = robot.time
        robot.send_action({"shoulder_pan.pos": 10.0})
        lags = sample_lag(lambda: robot.time, seconds)
        while robot.time - t0 < 0.3:
            time.sleep(0.001)
        pan = robot.get_observation()["shoulder_pan.pos"]  # later than +0.3 s: close enough
        drawn = robot.viewer.frames / (seconds + 0.5) if viewer else math.nan
    extra = f"; viewer drew {drawn:5.1f} frames/s" if viewer else ""
    return lag_line(f"robot, viewer {quality or 'none'}", lags, extra + f"; pan {pan:.1f} deg")


def previous_design_lag(seconds: float) -> str:
    """The robot's physics thread before: steps a block, then syncs the viewer on the live data
    at 60 Hz while holding the lock (waiting for MuJoCo to draw the full meshes)."""
    sim = Simulation()
    stop = threading.Event()
    with open_viewer(sim.model, sim.data) as v:

        def physics() -> None:
            pacer, t, last = Pacer(sleep=stop.wait), sim.time, -math.inf
            pacer.wait(t)
            while not stop.is_set():
                pacer.wait(t + 0.004)
                with sim.lock:
                    sim.step(2)
                    t = sim.time
                    if time.perf_counter() - last >= 1 / 60:
                        last = time.perf_counter()
                        v.sync()

        thread = threading.Thread(target=physics)
        thread.start()
        time.sleep(0.5)

        def now_sim() -> float:
            with sim.lock:
                return sim.time

        lags = sample_lag(now_sim, seconds)
        stop.set()
        thread.join()
    return lag_line("previous design (full)", lags)


def main() -> None:
    p = argparse.ArgumentParser()
    p.add_argument("--seconds", type=float, default=4.0)
    p.add_argument("--busy", type=int, default=0, help="CPU-burning processes beside the bench")
    a = p.parse_args()
    print(f"OpenGL renderer: {gl.renderer_string()!r} (software: {gl.software_rendering()})")
    with busy(a.busy):
        print(f"viewer frames/s (states offered {OFFER_HZ:.0f} times a second, busy={a.busy}):")
        for quality, mirror in (("draft", True), ("full", True), ("full", False)):
            print(frames(quality, mirror, a.seconds), flush=True)
        print(f"real-time physics lag over {a.seconds:g} s (sampled at 100 Hz):")
        for quality in (None, "draft", "full"):
            print(robot_lag(quality, a.seconds), flush=True)
        print(previous_design_lag(a.seconds), flush=True)


if __name__ == "__main__":
    main()
