"""The Gymnasium tasks: environment steps per second side by side with raw ``mj_step``, the
scripted experts' success rates over 100 seeds, and the grasp figures over 50 placements.

    PYTHONPATH=src python bench/bench_envs.py [--repeats 9] [--seeds 100] [--placements 50]

Speed, measured in one run, interleaved, best of ``--repeats`` (all on the ``pick_cube`` scene,
25 Hz control: 20 physics steps of 2 ms per environment step, replaying the actions the
scripted expert sent in one 8 s episode, so every variant does the same physics):

* raw ``mujoco.mj_step(m, d, nstep=20)`` per action, the targets written to ``d.ctrl``: the
  baseline, no Python per physics step;
* ``PickCube-v0`` without images (``agent_pos``, ``agent_vel``, ``environment_state``);
* ``PickCube-v0`` with one 224 × 224 camera (``front``, the draft meshes);
* ``gymnasium.vector.AsyncVectorEnv`` of 2 environments without images (environment steps of
  both together per second).

Batched (``--only batched``, ``--worlds 64``): ``so101sim.envs.make_vec`` of 64 worlds, each
replaying the same actions, against one raw ``mj_step`` thread measured in the same run; the
ratio that matters is to (cores × raw), the most the cores could give; the stepper alone (the
physics of all worlds, no observation or reward) shows what the Python of an env step costs.

Success: ``evaluate_expert`` over seeds 0..N-1 of each task (each seed draws new start poses).
Grasps: ``grasp_trials`` at ``--placements`` placements of 10-50 g cubes drawn from seed 0
(pick, lift, hold 3 s), and cubes left on the table for 60 s. Ablation: the tuned contact
settings against MuJoCo's defaults and against the tuned set with one setting put back, at
``--ablation-placements`` placements.
"""

from __future__ import annotations

import argparse
import os
import time
from dataclasses import replace

import gymnasium as gym
import mujoco
import numpy as np

import so101sim.envs  # noqa: F401  (registers the environments)
from so101sim.envs import TASKS, evaluate_expert, expert_for, make_vec
from so101sim.envs.grasp import (
    GRASP_LIMITS,
    REST_LIMITS,
    default_contact,
    grasp_trials,
    rest_trial,
)
from so101sim.scenes import ContactSettings
from so101sim.sim.batched import default_threads

ENV_ID = "so101sim/PickCube-v0"


def expert_actions(seed: int = 0) -> list[np.ndarray]:
    """The actions the scripted expert sends over one whole PickCube episode (200 steps)."""
    env = gym.make(ENV_ID, terminate_on_success=False)
    expert = expert_for(env)
    obs, _ = env.reset(seed=seed)
    expert.reset()
    actions, done = [], False
    while not done:
        a = expert.act(obs)
        actions.append(a)
        obs, _, terminated, truncated, _ = env.step(a)
        done = terminated or truncated
    env.close()
    return actions


def time_raw(actions: list[np.ndarray]) -> float:
    env = gym.make(ENV_ID)
    env.reset(seed=0)
    inner = env.unwrapped
    m, d = inner.model, mujoco.MjData(inner.model)
    state = np.empty(mujoco.mj_stateSize(m, mujoco.mjtState.mjSTATE_INTEGRATION))
    mujoco.mj_getState(m, inner.sim.data, state, mujoco.mjtState.mjSTATE_INTEGRATION)
    mujoco.mj_setState(m, d, state, mujoco.mjtState.mjSTATE_INTEGRATION)
    ctrl = [inner.sim.units.to_radians(np.asarray(a, dtype=float)) for a in actions]
    act, n = inner.sim.index.actuator, inner.substeps
    t0 = time.perf_counter()
    for q in ctrl:
        d.ctrl[act] = q
        mujoco.mj_step(m, d, nstep=n)
    return time.perf_counter() - t0


def time_env(actions: list[np.ndarray], **kwargs: object) -> float:
    env = gym.make(ENV_ID, terminate_on_success=False, **kwargs)
    env.reset(seed=0)
    env.step(actions[0])  # the first frame starts the renderer: not timed
    t0 = time.perf_counter()
    for a in actions:
        env.step(a)
    elapsed = time.perf_counter() - t0
    env.close()
    return elapsed


def time_async(actions: list[np.ndarray], n_envs: int = 2) -> float:
    envs = gym.vector.AsyncVectorEnv(
        [lambda: gym.make(ENV_ID, terminate_on_success=False) for _ in range(n_envs)]
    )
    try:
        envs.reset(seed=list(range(n_envs)))
        t0 = time.perf_counter()
        for a in actions:
            envs.step(np.stack([a] * n_envs))
        return time.perf_counter() - t0
    finally:
        envs.close()


def speed(repeats: int) -> None:
    actions = expert_actions()
    n = len(actions)
    runs = {
        "raw mj_step(nstep=20)": (lambda: time_raw(actions), 1),
        "PickCube-v0, no images": (lambda: time_env(actions), 1),
        "PickCube-v0, 224x224 front camera": (
            lambda: time_env(actions, cameras=["front"], image_size=(224, 224)),
            1,
        ),
        "AsyncVectorEnv, 2 envs, no images": (lambda: time_async(actions), 2),
    }
    best = dict.fromkeys(runs, np.inf)
    for _ in range(repeats):
        for name, (run, _) in runs.items():
            best[name] = min(best[name], run())
    base = n / best["raw mj_step(nstep=20)"]
    load = ", ".join(f"{x:.1f}" for x in os.getloadavg())
    print(
        f"speed: {n} environment steps of 20 physics steps (best of {repeats}, interleaved; "
        f"{os.cpu_count()} CPUs, load average {load})"
    )
    print(f"  {'variant':38s} {'env steps/s':>12s} {'physics steps/s':>16s} {'vs raw':>8s}")
    for name, (_, k) in runs.items():
        rate = k * n / best[name]
        print(f"  {name:38s} {rate:12.0f} {rate * 20:16.0f} {rate / base:8.2f}")


def time_batched(actions: list[np.ndarray], worlds: int, physics_only: bool) -> float:
    """``make_vec`` of ``worlds`` worlds, every world replaying the actions (or, physics
    only, its WorldStepper alone stepping the same targets: what the Python of an env step
    costs is the difference)."""
    venv = make_vec("pick_cube", worlds, terminate_on_success=False, episode_seconds=3600.0)
    venv.reset(seed=0)
    rows = [np.repeat(a[None], worlds, axis=0) for a in actions]
    try:
        if physics_only:
            envs = venv.envs
            act, units = envs[0].sim.index.actuator, envs[0].sim.units
            ctrl = [units.to_radians(np.asarray(a, dtype=float)) for a in actions]
            t0 = time.perf_counter()
            for q in ctrl:
                for e in envs:
                    e.sim.data.ctrl[act] = q
                venv._stepper.advance(envs[0].substeps)
            return time.perf_counter() - t0
        t0 = time.perf_counter()
        for a in rows:
            venv.step(a)
        return time.perf_counter() - t0
    finally:
        venv.close()


def batched(repeats: int, worlds: int) -> None:
    actions = expert_actions()
    n = len(actions)
    cores = default_threads()
    runs = {
        "raw mj_step(nstep=20), one thread": (lambda: time_raw(actions), 1),
        f"WorldStepper, {worlds} worlds (physics only)": (
            lambda: time_batched(actions, worlds, True),
            worlds,
        ),
        f"make_vec, {worlds} worlds, no images": (
            lambda: time_batched(actions, worlds, False),
            worlds,
        ),
    }
    best = dict.fromkeys(runs, np.inf)
    for _ in range(repeats):
        for name, (run, _) in runs.items():
            best[name] = min(best[name], run())
    base = n / best["raw mj_step(nstep=20), one thread"]
    load = ", ".join(f"{x:.1f}" for x in os.getloadavg())
    print(
        f"batched: {n} environment steps of 20 physics steps per world (best of {repeats}, "
        f"interleaved; {cores} cores for this process, load average {load})"
    )
    print(
        f"  {'variant':44s} {'env steps/s':>12s} {'physics steps/s':>16s} {'vs raw':>7s} "
        f"{'vs cores x raw':>15s}"
    )
    for name, (_, k) in runs.items():
        rate = k * n / best[name]
        print(
            f"  {name:44s} {rate:12.0f} {rate * 20:16.0f} {rate / base:7.2f} "
            f"{rate / (cores * base):15.2f}"
        )


def success(seeds: int, tasks: list[str]) -> None:
    print(f"scripted experts over seeds 0..{seeds - 1}:")
    for task in tasks:
        t0 = time.perf_counter()
        score = evaluate_expert(task, range(seeds))
        wall = time.perf_counter() - t0
        retried = sum(e.attempts > 1 for e in score.episodes)
        print(
            f"  {task:13s} success {100 * score.success_rate:5.1f} % "
            f"({len(score.episodes) - len(score.failed_seeds)}/{len(score.episodes)}), "
            f"failed seeds {score.failed_seeds or 'none'}, {retried} retried a grasp, "
            f"mean {score.mean_steps:.0f} steps, {wall:.1f} s wall"
        )


def grasps(placements: int) -> None:
    t0 = time.perf_counter()
    trials = grasp_trials(placements, seed=0)
    wall = time.perf_counter() - t0
    ok = sum(t.ok for t in trials)
    print(f"grasps: {placements} placements of 10-50 g cubes (seed 0), hold 3 s, {wall:.0f} s wall")
    rows = [
        ("lift (mm, at least)", "lifted_mm", min),
        ("slip in the grip (mm)", "slip_mm", max),
        ("penetration (mm)", "penetration_mm", max),
        ("pushed before the grip (mm)", "disturbed_mm", max),
    ]
    for label, key, worst in rows:
        values, limit = [getattr(t, key) for t in trials], GRASP_LIMITS[key]
        print(
            f"  {label:28s} median {np.median(values):6.2f}  worst {worst(values):6.2f}  "
            f"limit {limit:g}"
        )
    print(f"  within all limits: {ok}/{placements}")
    for mass in (0.01, 0.05):
        r = rest_trial(0.2, 0.05, 30.0, mass, duration=60.0)
        print(
            f"  {mass * 1000:.0f} g cube on the table for 60 s: drift {r.drift_mm:.4f} mm, "
            f"up/down {r.sink_mm:.4f} mm, turn {r.turn_deg:.4f}° "
            f"(limits {REST_LIMITS['drift_mm']:g} / {REST_LIMITS['sink_mm']:g} mm)"
        )


def ablation(placements: int) -> None:
    """The tuned contacts against MuJoCo's defaults and against the tuned set with one setting
    put back to its default, at the same placements."""
    tuned = ContactSettings()
    variants = {
        "tuned (the default of so101sim)": tuned,
        "MuJoCo's defaults": default_contact(),
        "tuned, but impratio 1": replace(tuned, impratio=1.0),
        "tuned, but pyramidal cone": replace(tuned, cone="pyramidal"),
        "tuned, but solimp 0.9/0.95": replace(tuned, solimp=(0.9, 0.95, 0.001, 0.5, 2.0)),
        "tuned, but solref 0.02 s": replace(tuned, solref=(0.02, 1.0)),
    }
    print(f"contact settings at {placements} placements (seed 1), worst of each figure:")
    print(f"  {'settings':34s} {'lift mm':>8s} {'slip mm':>8s} {'pen. mm':>8s} {'ok':>6s}")
    for label, contact in variants.items():
        trials = grasp_trials(placements, seed=1, contact=contact)
        print(
            f"  {label:34s} {min(t.lifted_mm for t in trials):8.1f} "
            f"{max(t.slip_mm for t in trials):8.2f} {max(t.penetration_mm for t in trials):8.2f} "
            f"{sum(t.ok for t in trials):3d}/{placements}"
        )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=9)
    parser.add_argument("--seeds", type=int, default=100)
    parser.add_argument("--placements", type=int, default=50)
    parser.add_argument("--ablation-placements", type=int, default=10)
    parser.add_argument("--worlds", type=int, default=64, help="worlds of the batched run")
    parser.add_argument("--only", choices=("speed", "batched", "success", "grasps", "ablation"))
    parser.add_argument(
        "--tasks", default=",".join(TASKS), help="the success section's tasks, comma-separated"
    )
    args = parser.parse_args()
    tasks = [t for t in args.tasks.split(",") if t]
    unknown = sorted(set(tasks) - set(TASKS))
    if unknown:
        parser.error(f"unknown task(s) {', '.join(unknown)}; expected some of {', '.join(TASKS)}")
    if args.only in (None, "speed"):
        speed(args.repeats)
    if args.only in (None, "batched"):
        batched(min(args.repeats, 5), args.worlds)
    if args.only in (None, "success"):
        success(args.seeds, tasks)
    if args.only in (None, "grasps"):
        grasps(args.placements)
    if args.only in (None, "ablation"):
        ablation(args.ablation_placements)


if __name__ == "__main__":
    main()
