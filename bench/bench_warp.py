"""The GPU backend of make_vec (MuJoCo Warp) against the CPU backend: speed for 1, 1024 and 4096
worlds, and how far its physics strays from MuJoCo's on the CPU over a rollout.

Run on a machine with an NVIDIA GPU (``pip install 'so101sim[warp]'``):

    PYTHONPATH=src python bench/bench_warp.py                  # 1, 1024, 4096 worlds
    PYTHONPATH=src python bench/bench_warp.py --out warp.json  # the figures as JSON too

``--device cpu --worlds 2 --steps 10`` checks the agreement on a machine without one (Warp's CPU
kernels: slow, and minutes of compilation the first time). The figures of the CPU backend (64
worlds on every core, and one raw ``mj_step`` thread) are measured in the same run, so the
ratios hold on the machine it ran on. Both run the reach task on the ``official`` arm (MuJoCo
Warp has no PID actuators, which the default servo model uses) with random ``joint_delta``
actions from one seed.
"""

from __future__ import annotations

import argparse
import json
import platform
import time

import mujoco
import numpy as np

from so101sim.envs import make, make_vec

KW = {"arm": "official", "control": "joint_delta", "terminate_on_success": False}


def actions(n_worlds: int, steps: int, space) -> np.ndarray:
    rng = np.random.default_rng(0)
    return rng.uniform(space.low, space.high, (steps, n_worlds, *space.shape)).astype(np.float32)


def rate(venv, acts: np.ndarray) -> float:
    venv.reset(seed=0)
    venv.step(acts[0])  # warm up (graph capture, kernel loads)
    t = time.perf_counter()
    for a in acts[1:]:
        venv.step(a)
    return (len(acts) - 1) * venv.num_envs / (time.perf_counter() - t)


def raw_rate(steps: int) -> float:
    env = make("reach", **KW).unwrapped
    env.reset(seed=0)
    m, d = env.model, env.sim.data
    t = time.perf_counter()
    for _ in range(steps):
        mujoco.mj_step(m, d, nstep=env.substeps)
    return steps / (time.perf_counter() - t)


def agreement(device: str, worlds: int, steps: int) -> dict:
    """The largest difference of the joint positions (degrees) and of the tip-to-goal distance
    (mm) between the two backends, same seeds, same actions, over ``steps`` control periods."""
    gpu = make_vec("reach", worlds, backend="warp", device=device, **KW)
    cpu = make_vec("reach", worlds, **KW)
    acts = actions(worlds, steps, cpu.single_action_space)
    og, ig = gpu.reset(seed=0)
    oc, ic = cpu.reset(seed=0)
    worst_pos, worst_dist = 0.0, 0.0
    for a in acts:
        og, _, _, _, ig = gpu.step(a)
        oc, _, _, _, ic = cpu.step(a)
        worst_pos = max(worst_pos, float(np.abs(og["agent_pos"] - oc["agent_pos"]).max()))
        gap = np.abs(ig["goal_distance_m"] - ic["goal_distance_m"]).max()
        worst_dist = max(worst_dist, 1000 * float(gap))
    gpu.close()
    cpu.close()
    return {"worlds": worlds, "steps": steps, "max_joint_deg": worst_pos, "max_goal_mm": worst_dist}


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--device", default="cuda")
    p.add_argument("--worlds", type=int, nargs="*", default=[1, 1024, 4096])
    p.add_argument("--steps", type=int, default=100, help="control periods per measurement")
    p.add_argument("--out", default=None)
    args = p.parse_args()
    import warp

    warp.config.quiet = True
    result: dict = {"machine": platform.node(), "device": args.device, "speed": []}
    if args.device.startswith("cuda"):
        warp.init()
        result["card"] = warp.get_device(args.device).name
    raw = raw_rate(200)
    cpu = make_vec("reach", 64, **KW)
    cpu_rate = rate(cpu, actions(64, 50, cpu.single_action_space))
    cpu.close()
    result["raw_mj_step_env_steps_per_s"] = raw
    result["cpu_64_worlds_env_steps_per_s"] = cpu_rate
    for n in args.worlds:
        venv = make_vec("reach", n, backend="warp", device=args.device, **KW)
        r = rate(venv, actions(n, args.steps, venv.single_action_space))
        venv.close()
        result["speed"].append({"worlds": n, "env_steps_per_s": r, "vs_raw_mj_step": r / raw})
        print(f"{n:5d} worlds: {r:12.0f} env steps/s ({r / raw:7.1f} x one raw mj_step thread)")
    result["agreement"] = agreement(args.device, min(8, max(args.worlds)), min(args.steps, 50))
    print(json.dumps(result, indent=2))
    if args.out:
        with open(args.out, "w") as f:
            json.dump(result, f, indent=2)


if __name__ == "__main__":
    main()
