"""Issue 14's figures side by side in one run: start-up and memory of a whole process, lockstep
cost per action, robust preflight against a raw rollout.

    PYTHONPATH=src python bench/bench_startup.py [--repeats 5] [--ticks 2000] [--variants 1000]

1. ``so101sim run --headless`` (the lab motion) as a whole process against
   ``python -c "import mujoco"``: wall time and peak RSS (``ru_maxrss`` from ``wait4``), the two
   commands alternated, median of ``--repeats``. The compiled-model cache is warmed first (as
   after a user's first run); one cold run (cache in an empty folder) is shown beside it.
2. A lockstep ``SO101SimFollower`` (``get_observation`` + ``send_action``, 0.02 s of simulated
   time each = 10 physics steps) against ``mujoco.mj_step(m, d, nstep=10)`` replaying the
   same controls on the same model from the same state, rounds alternated, best round.
3. ``check_variants`` of ``--variants`` lab variants against a raw rollout of the same
   variants (``bench_variants.py``), with 2 threads and 1.

Goals (issue 14): start-up <= 1.6x ``import mujoco``'s wall and <= 150 MB; lockstep <= 1.5x the
raw physics; robust preflight <= 1.15x the raw rollout. Nothing is asserted here.
"""

from __future__ import annotations

import argparse
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import mujoco

sys.path.insert(0, str(Path(__file__).resolve().parent))

RUN = [sys.executable, "-m", "so101sim", "run", "--headless"]
IMPORT_MUJOCO = [sys.executable, "-c", "import mujoco"]


# as on a user's machine: Python's bytecode cache on (pip compiles it at install)
USER_ENV = {k: v for k, v in os.environ.items() if k != "PYTHONDONTWRITEBYTECODE"}


def process(cmd: list[str], env: dict[str, str] | None = None) -> tuple[float, float]:
    """Wall seconds and peak RSS (MB) of one child process."""
    env = USER_ENV if env is None else env
    t0 = time.perf_counter()
    child = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, env=env)
    _pid, status, usage = os.wait4(child.pid, 0)
    wall = time.perf_counter() - t0
    err = child.stderr.read().decode() if child.stderr else ""
    child.stderr and child.stderr.close()
    if os.waitstatus_to_exitcode(status) != 0:
        raise SystemExit(f"{' '.join(cmd)} failed:\n{err}")
    return wall, usage.ru_maxrss / 1024  # kB on Linux


def startup(repeats: int) -> None:
    process(RUN)  # the compiled-model cache is warm from here on
    rows: dict[str, list[tuple[float, float]]] = {"import mujoco": [], "so101sim run": []}
    for _ in range(repeats):
        rows["import mujoco"].append(process(IMPORT_MUJOCO))
        rows["so101sim run"].append(process(RUN))
    with tempfile.TemporaryDirectory() as empty:
        cold = process(RUN, env={**USER_ENV, "SO101SIM_CACHE_DIR": empty})
    med = {
        k: (statistics.median(w for w, _ in v), statistics.median(r for _, r in v))
        for k, v in rows.items()
    }
    base_wall, base_rss = med["import mujoco"]
    print(f"1. whole process, median of {repeats} (commands alternated):")
    for name, (wall, rss) in med.items():
        print(f"   {name:<28} {wall:6.3f} s  {wall / base_wall:5.2f}x   peak {rss:6.1f} MB")
    name = "so101sim run, cache cold"
    print(f"   {name:<28} {cold[0]:6.3f} s  {cold[0] / base_wall:5.2f}x   peak {cold[1]:6.1f} MB")
    wall, rss = med["so101sim run"]
    print(
        f"   goal <= 1.6x and <= 150 MB: {wall / base_wall:.2f}x, {rss:.0f} MB"
        f" (import mujoco alone {base_rss:.0f} MB)"
    )


def lockstep(ticks: int, rounds: int = 7) -> None:
    """Per action: a lockstep robot's ``get_observation()`` + ``send_action()`` (10 physics
    steps) against ``mj_step(nstep=10)`` replaying the same controls from the same state (the
    same physics: its cost depends on the pose)."""
    import copy

    from so101sim.robot import SO101SimFollower, SO101SimFollowerConfig
    from so101sim.units import STARTING_POSE, ZERO_POSE

    goals = [{f"{n}.pos": float(v) for n, v in p.items()} for p in (ZERO_POSE, STARTING_POSE)]
    robot = SO101SimFollower(SO101SimFollowerConfig(mode="lockstep"))
    robot.connect()
    m, d = robot.simulation.model, robot.simulation.data
    try:
        start = copy.copy(d)
        ctrls = []
        for i in range(ticks):
            robot.get_observation()
            robot.send_action(goals[(i // 100) % 2])
            ctrls.append(d.ctrl.copy())
        per_robot, per_raw = [], []
        for _ in range(rounds):
            t0 = time.perf_counter()
            for i in range(ticks):
                robot.get_observation()
                robot.send_action(goals[(i // 100) % 2])
            per_robot.append((time.perf_counter() - t0) / ticks)
            raw = copy.copy(start)
            t0 = time.perf_counter()
            for c in ctrls:
                raw.ctrl[:] = c
                mujoco.mj_step(m, raw, nstep=10)
            per_raw.append((time.perf_counter() - t0) / ticks)
    finally:
        robot.disconnect()
    r, w = min(per_robot), min(per_raw)
    print(f"2. lockstep, {ticks} actions of 0.02 s, best of {rounds} alternated rounds:")
    print(f"   get_observation + send_action {r * 1e6:7.1f} µs per action")
    print(f"   mj_step(nstep=10), same ctrl  {w * 1e6:7.1f} µs   ratio {r / w:.2f} (goal <= 1.5)")


def preflight(count: int) -> None:
    from bench_variants import compare

    from so101sim.motion.file import lab_motion_path

    print(f"3. robust preflight of {count} lab variants against a raw rollout of them:")
    compare(count, lab_motion_path(), indent="   ")


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--repeats", type=int, default=5)
    p.add_argument("--ticks", type=int, default=2000)
    p.add_argument("--variants", type=int, default=1000)
    a = p.parse_args()
    print(f"MuJoCo {mujoco.__version__}, Python {sys.version.split()[0]}, {os.cpu_count()} cores")
    startup(a.repeats)
    lockstep(a.ticks)
    preflight(a.variants)


if __name__ == "__main__":
    main()
