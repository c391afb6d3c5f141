"""Cost per physics step of the lab motion (rest -> zeros 2 s, hold 2 s, back 2 s), headless.

Prints, measured side by side in one run (interleaved, best of several repeats):

* raw ``mujoco.mj_step(m, d, nstep=N)`` driving the same motion, its targets changed every
  50 steps (one Python call per 50 steps, so nearly pure C; the same poses, hence the same
  contact and solver work, as the real motion) -- the baseline;
* raw ``mj_step(nstep=N)`` holding one pose (the cheapest possible physics, for reference);
* the lab handout's helpers reproduced (dicts per step, 3.14159, interpolation per joint in
  Python), timed by simulated time so they take the same 3000 steps;
* a naive per-step NumPy loop (``d.ctrl[:] = target; mj_step`` in Python);
* so101sim's headless lab motion (``run_motion``), which computes each move's targets at once
  and replays them in C;
* ``Simulation.move_to`` / ``Simulation.hold``, the same three segments;
* the handout's helpers as so101sim ships them (``so101sim.lab``: ``move_to_pose`` /
  ``hold_position`` on a bare ``(m, d)``, with their warnings computed after each segment from
  the states the stepping kernel recorded): the code students actually run.

The last line prints the lab helpers' cost over raw ``mj_step`` on the same motion (goal: at
most 1.1x).

Run: python bench/bench_lab.py [--repeats 7]
"""

from __future__ import annotations

import argparse
import time

import mujoco
import numpy as np

from so101sim import LAB_MOTION, Simulation, run_motion
from so101sim.lab import hold_position, move_to_pose
from so101sim.model import default_units
from so101sim.motion import Move, plan_move
from so101sim.units import JOINT_NAMES, STARTING_POSE, ZERO_POSE

PI_HANDOUT = 3.14159


# -- the handout's helpers, reproduced for timing (dicts and per-step Python, as written there)
def h_to_dict(qpos):
    d = {n: qpos[i] * 180.0 / PI_HANDOUT for i, n in enumerate(JOINT_NAMES[:5])}
    d["gripper"] = qpos[5] * 100 / PI_HANDOUT
    return d


def h_to_list(pose):
    out = [pose[n] * PI_HANDOUT / 180.0 for n in JOINT_NAMES[:5]]
    out.append(pose["gripper"] * PI_HANDOUT / 100.0)
    return out


def h_send(d, pose):
    d.ctrl = h_to_list(pose)


def h_move(m, d, desired, duration):
    start = h_to_dict(d.qpos.copy())
    n = round(duration / m.opt.timestep)
    for i in range(n):
        alpha = min(i * m.opt.timestep / duration, 1)
        cmd = {j: (1 - alpha) * start[j] + alpha * desired[j] for j in desired}
        h_send(d, cmd)
        mujoco.mj_step(m, d)


def h_hold(m, d, duration):
    pose = h_to_dict(d.qpos.copy())
    for _ in range(round(duration / m.opt.timestep)):
        h_send(d, pose)
        mujoco.mj_step(m, d)


# -- the variants
def lab_targets(sim: Simulation) -> np.ndarray:
    """The lab motion's per-step targets in radians (3000 x 6)."""
    units = sim.units
    blocks = []
    for step in LAB_MOTION:
        if isinstance(step, Move):
            _, t = plan_move(sim.model, sim.data, step.target, step.duration)
            blocks.append(units.to_radians(t))
            sim.command(step.target)
        else:
            blocks.append(np.repeat(blocks[-1][-1:], round(step.duration / sim.timestep), 0))
    sim.reset()
    return np.concatenate(blocks)


ARM = "official"  # --arm: the handout's model (the file as is) by default


def fresh() -> Simulation:
    return Simulation(arm=ARM)


def raw_same_motion(targets: np.ndarray, block: int = 50):
    sim = fresh()
    m, d = sim.model, sim.data
    t = time.perf_counter()
    for k in range(0, len(targets), block):
        d.ctrl[:] = targets[k + block - 1]
        mujoco.mj_step(m, d, nstep=block)
    return time.perf_counter() - t


def raw_static(n: int):
    sim = fresh()
    sim.set_pose(dict.fromkeys(JOINT_NAMES, 0.0))
    t = time.perf_counter()
    mujoco.mj_step(sim.model, sim.data, nstep=n)
    return time.perf_counter() - t


def handout(_targets):
    sim = fresh()
    m, d = sim.model, sim.data
    h_send(d, STARTING_POSE)
    t = time.perf_counter()
    h_move(m, d, dict.fromkeys(JOINT_NAMES, 0.0), 2.0)
    h_hold(m, d, 2.0)
    h_move(m, d, STARTING_POSE, 2.0)
    return time.perf_counter() - t


def naive_loop(targets):
    sim = fresh()
    m, d = sim.model, sim.data
    t = time.perf_counter()
    for row in targets:
        d.ctrl[:] = row
        mujoco.mj_step(m, d)
    return time.perf_counter() - t


def so101sim_lab(_targets):
    sim = fresh()
    t = time.perf_counter()
    run_motion(sim.model, sim.data, LAB_MOTION)
    return time.perf_counter() - t


def simulation_segments(_targets):
    sim = fresh()
    t = time.perf_counter()
    sim.move_to(ZERO_POSE, 2.0)
    sim.hold(2.0)
    sim.move_to(STARTING_POSE, 2.0)
    return time.perf_counter() - t


def lab_helpers(_targets):
    sim = fresh()
    m, d = sim.model, sim.data
    t = time.perf_counter()
    move_to_pose(m, d, None, ZERO_POSE, 2.0)
    hold_position(m, d, None, 2.0)
    move_to_pose(m, d, None, STARTING_POSE, 2.0)
    return time.perf_counter() - t


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=7)
    ap.add_argument(
        "--arm",
        default="official",
        help="the servos' model: official (default: the file's own actuators, the model a "
        "student's mujoco.MjModel.from_xml_path(scene_path()) gets) or sts3215 (so101sim's "
        "default arm)",
    )
    args = ap.parse_args()
    global ARM
    ARM = args.arm
    default_units()
    targets = lab_targets(fresh())
    n = len(targets)
    variants = {
        "raw mj_step(nstep), same motion": lambda: raw_same_motion(targets),
        "raw mj_step(nstep), one pose held": lambda: raw_static(n),
        "handout's dict helpers": lambda: handout(targets),
        "naive per-step NumPy loop": lambda: naive_loop(targets),
        "so101sim lab motion (headless)": lambda: so101sim_lab(targets),
        "Simulation.move_to / hold": lambda: simulation_segments(targets),
        "so101sim.lab move_to_pose/hold_position": lambda: lab_helpers(targets),
    }
    lab_helpers(targets)  # first use: the contact screen's scratch model is made once per model
    best = dict.fromkeys(variants, float("inf"))
    for _ in range(args.repeats):  # interleaved, so machine noise hits all alike
        for name, fn in variants.items():
            best[name] = min(best[name], fn())
    base = best["raw mj_step(nstep), same motion"]
    print(
        f"lab motion: {n} physics steps (6 s at dt 0.002), best of {args.repeats}, arm {args.arm}"
    )
    print(f"{'variant':42s} {'µs/step':>9s} {'× raw':>7s}")
    for name, t in best.items():
        print(f"{name:42s} {t / n * 1e6:9.2f} {t / base:7.2f}")
    helpers = best["so101sim.lab move_to_pose/hold_position"]
    print(
        f"lab helpers / raw mj_step, same motion: {helpers / base:.2f}x (goal <= 1.1x); "
        f"/ Simulation.move_to: {helpers / best['Simulation.move_to / hold']:.2f}x"
    )


if __name__ == "__main__":
    main()
