"""Preflight's cost next to raw ``mj_step`` and a plain run of the same motion, side by side.

    PYTHONPATH=src python bench/bench_preflight.py [--repeats 5] [MOTION.toml]

Two motions (or the one given): the lab motion (6 s) and a 60 s straight tip move (30,000
physics steps, its line checked). For each, interleaved, best of ``--repeats``:

* raw ``mujoco.mj_step(m, d, nstep=50)`` driving the motion's own targets (changed every 50
  steps: nearly pure C, the same poses, hence the same contact and solver work) -- the floor;
* a plain headless run (``run_plan``: what ``so101sim run --headless`` steps);
* the preflight (``so101sim.preflight.preflight``: plan, run, measure, judge), the model loaded
  once before (start-up aside);
* the same preflight watching every physics step from Python (the step recorder: how the
  check ran before issue 30; ``--no-per-step`` leaves it out).

The last lines print the preflight over raw ``mj_step`` (goal on the 60 s motion: at most 2x).
"""

from __future__ import annotations

import argparse
import time
from collections.abc import Callable

import mujoco
import numpy as np

from so101sim.model import arm_index, load_model
from so101sim.motion import Move
from so101sim.motion.file import lab_motion_path, load_motion
from so101sim.motion.plan import plan_segments, run_plan
from so101sim.preflight import measure, preflight
from so101sim.sim.simulation import Simulation
from so101sim.units import STARTING_POSE

EVERY = 50  # raw mj_step: targets changed every this many steps


def motions(path: str | None, m: mujoco.MjModel) -> list[tuple[str, tuple, dict]]:
    if path is not None:
        motion = load_motion(path, model=m)
        return [(path, motion.steps, motion.start)]
    lab = load_motion(lab_motion_path(), model=m)
    line = (Move.to_tip((0.22, 0.05, 0.08), 60.0, pitch=-60),)
    return [
        ("the lab motion", lab.steps, lab.start),
        ("a 60 s straight tip move", line, STARTING_POSE),
    ]


def runners(m: mujoco.MjModel, steps: tuple, start: dict) -> dict[str, Callable[[], object]]:
    plan = plan_segments(m, steps, Simulation(m, initial_pose=start).commanded_array())
    units = Simulation(m, initial_pose=start).units
    targets = units.to_radians(plan.path()[1])[EVERY - 1 :: EVERY]
    act = arm_index(m).actuator

    def raw() -> None:
        d = Simulation(m, initial_pose=start).data
        for row in targets:
            d.ctrl[act] = row
            mujoco.mj_step(m, d, nstep=EVERY)

    def plain() -> None:
        sim = Simulation(m, initial_pose=start)
        run_plan(sim, plan_segments(m, steps, sim.commanded_array()), trace=False)

    def checked() -> None:
        preflight(steps, start=start, model=m)

    def per_step() -> None:
        derivable = measure.derivable
        measure.derivable = lambda model: False  # the step recorder, called after every step
        try:
            preflight(steps, start=start, model=m)
        finally:
            measure.derivable = derivable

    return {"raw mj_step": raw, "plain run": plain, "preflight": checked, "per step": per_step}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("motion", nargs="?", help="a motion file (default: the two motions)")
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--no-per-step", action="store_true", help="skip the per-step check")
    args = parser.parse_args()
    m = load_model()
    for name, steps, start in motions(args.motion, m):
        fns = runners(m, steps, start)
        if args.no_per_step:
            del fns["per step"]
        for fn in fns.values():
            fn()  # warm up (the contact twin, the kinematics)
        best = dict.fromkeys(fns, np.inf)
        for _ in range(args.repeats):  # interleaved: the machine's load hits all alike
            for key, fn in fns.items():
                t0 = time.perf_counter()
                fn()
                best[key] = min(best[key], time.perf_counter() - t0)
        sim_time = sum(s.duration for s in steps)
        print(f"{name} ({sim_time:g} s simulated), best of {args.repeats}:")
        for key, t in best.items():
            print(f"  {key:<11}: {t * 1000:9.1f} ms   {t / best['raw mj_step']:6.2f}x raw")
    print("goal: the preflight of the 60 s motion at most 2x raw mj_step")


if __name__ == "__main__":
    main()
