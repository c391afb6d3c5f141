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
- physics lag: how late the robot's physics thread starts each 4 ms block after its
  wall-clock deadline (measured in the thread: its ``Pacer`` is swapped for one that records
  it), with no viewer, the draft and the full mirrored viewer with its threads at niceness
  ``VIEWER_NICE`` and at 0, and the previous design (the physics thread syncing the viewer on
  the live data while holding the lock) as a reference.
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

import so101sim.robot.threads
import so101sim.viewer.passive
from so101sim import gl
from so101sim.robot import SO101SimFollower, SO101SimFollowerConfig
from so101sim.sim.simulation import Pacer, Simulation
from so101sim.viewer import open_viewer

OFFER_HZ = 240.0
NICE = so101sim.viewer.passive.VIEWER_NICE


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


class LatenessPacer(Pacer):
    """A Pacer that records, at each wait, how late it returns after the deadline (s)."""

    def __init__(self, *args, **kw) -> None:
        super().__init__(*args, **kw)
        self.late: list[tuple[float, float]] = []  # (wall time, seconds late)

    def wait(self, sim_time: float) -> float:
        slept = super().wait(sim_time)
        if self._anchor is not None:
            wall0, sim0 = self._anchor
            now = self.clock()
            self.late.append((now, now - (wall0 + (sim_time - sim0) / self.speed)))
        return slept


@contextlib.contextmanager
def recording_pacers() -> Iterator[list[LatenessPacer]]:
    """Swap the robot's Pacer for a LatenessPacer (bench only); yield the ones made."""
    made: list[LatenessPacer] = []

    def make(*args, **kw) -> LatenessPacer:
        made.append(LatenessPacer(*args, **kw))
        return made[-1]

    saved = so101sim.robot.threads.Pacer
    so101sim.robot.threads.Pacer = make
    try:
        yield made
    finally:
        so101sim.robot.threads.Pacer = saved


def lag_line(what: str, late: list[tuple[float, float]], skip_s: float, extra: str = "") -> str:
    start = late[0][0] + skip_s  # the first second (the window opening) left out
    lags = np.array([lag for t, lag in late if t >= start]) * 1e3
    over = (lags > 10).sum()
    return (
        f"  {what:22s}: block started late max {lags.max():7.1f} ms, p99 "
        f"{np.percentile(lags, 99):6.1f} ms, median {np.median(lags):5.2f} ms, "
        f"{over} of {len(lags)} blocks > 10 ms late{extra}"
    )


def robot_lag(quality: str | None, seconds: float, nice: int = NICE) -> str:
    viewer = quality is not None
    so101sim.viewer.passive.VIEWER_NICE = nice  # read when the viewer opens; put back by main()
    cfg = SO101SimFollowerConfig(viewer=viewer, viewer_quality=quality or "auto")
    with recording_pacers() as pacers:
        robot = SO101SimFollower(cfg)
        with robot:
            wall0 = time.perf_counter()
            time.sleep(1.0)  # let the window open and settle
            robot.send_action({"shoulder_pan.pos": 10.0})  # the arm moves meanwhile
            time.sleep(max(0.0, seconds + 1.0 - (time.perf_counter() - wall0)))
            drawn = robot.viewer.frames / (time.perf_counter() - wall0) if viewer else math.nan
    extra = f"; viewer drew {drawn:5.1f} frames/s" if viewer else ""
    what = f"robot, viewer {quality}, nice {nice}" if viewer else "robot, no viewer"
    return lag_line(what, pacers[0].late, 1.0, extra)


def previous_design_lag(seconds: float) -> str:
    """The robot's physics thread before: steps a block, then syncs the viewer on the live data
    at 60 Hz while holding the lock (waiting for MuJoCo to draw the full meshes)."""
    sim = Simulation()
    stop = threading.Event()
    pacer = LatenessPacer(sleep=stop.wait)
    with open_viewer(sim.model, sim.data) as v:

        def physics() -> None:
            t, last = sim.time, -math.inf
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
        time.sleep(seconds + 1.0)
        stop.set()
        thread.join()
    return lag_line("previous design (full)", pacer.late, 1.0)


def main() -> None:
    p = argparse.ArgumentParser()
    p.add_argument("--seconds", type=float, default=4.0)
    p.add_argument("--busy", type=int, default=0, help="CPU-burning processes beside the bench")
    p.add_argument("--repeat", type=int, default=1, help="rounds of the viewer lag lines")
    a = p.parse_args()
    print(f"OpenGL renderer: {gl.renderer_string()!r} (software: {gl.software_rendering()})")
    with busy(a.busy):
        print(f"viewer frames/s (states offered {OFFER_HZ:.0f} times a second, busy={a.busy}):")
        for quality, mirror in (("draft", True), ("full", True), ("full", False)):
            print(frames(quality, mirror, a.seconds), flush=True)
        print(f"real-time physics lag over {a.seconds:g} s after the first second:")
        print(robot_lag(None, a.seconds), flush=True)
        for _ in range(a.repeat):  # alternated, so that other load hits each alike
            for quality in ("draft", "full"):
                for nice in (NICE, 0):
                    print(robot_lag(quality, a.seconds, nice), flush=True)
        so101sim.viewer.passive.VIEWER_NICE = NICE
        print(previous_design_lag(a.seconds), flush=True)


if __name__ == "__main__":
    main()
