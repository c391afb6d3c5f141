"""Preflight's cost next to a plain run of the same motion, measured side by side.

    PYTHONPATH=src python bench/bench_preflight.py [MOTION.toml]

Prints the best of several repeats of each, and their ratio.
"""

from __future__ import annotations

import sys
import time

from so101sim.model import load_model
from so101sim.motion import run_motion
from so101sim.motion.file import lab_motion_path, load_motion
from so101sim.preflight import preflight
from so101sim.sim.simulation import Simulation


def best_of(fn, repeats: int = 5) -> float:
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return min(times)


def main() -> None:
    path = sys.argv[1] if len(sys.argv) > 1 else lab_motion_path()
    motion = load_motion(path)
    m = load_model()

    def plain() -> None:
        sim = Simulation(m, initial_pose=motion.start)
        run_motion(m, sim.data, motion.steps)

    def checked() -> None:
        preflight(motion.steps, start=motion.start, model=m)

    plain()
    checked()  # warm up
    t_run, t_check = best_of(plain), best_of(checked)
    sim_time = sum(s.duration for s in motion.steps)
    print(f"motion: {path} ({sim_time:g} s simulated)")
    print(f"plain run : {t_run * 1000:8.1f} ms")
    print(f"preflight : {t_check * 1000:8.1f} ms")
    print(f"ratio     : {t_check / t_run:8.1f}x")


if __name__ == "__main__":
    main()
