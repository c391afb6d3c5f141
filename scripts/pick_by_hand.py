"""Can the PPO recipe's PickCube action space pick the cube at all? A hand-written policy in
exactly that space (``ee_delta``: tip dx, dy, dz and the gripper's target; the tool's pitch and
roll held as they start), over a few seeds, from the folded rest pose (pitch -50 degrees) or
from the recipe's top-down start (scripts/train_ppo.py's ``initial_pose``): docs/rl.md.

    python scripts/pick_by_hand.py --start rest --seeds 20
    python scripts/pick_by_hand.py --start recipe --seeds 20 --rewards

The policy reads the true cube and tip positions and moves the point between the jaws above
the cube (gripper open), down onto it, closes for 0.5 s and lifts. ``--rewards`` prints the
dense reward along the first two episodes (it should rise: reach, grasp, lift).
"""

from __future__ import annotations

import argparse
import importlib.util
from pathlib import Path

import numpy as np

from so101sim.envs import make

OPEN, CLOSED = 35.0, 0.0
ABOVE_M = 0.05


def recipe_kwargs() -> dict:
    path = Path(__file__).with_name("train_ppo.py")
    spec = importlib.util.spec_from_file_location("train_ppo", path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return dict(module.ENV_KWARGS["pick_cube"])


def episode(env, seed: int, step: float) -> tuple[bool, list[tuple[str, float]]]:
    env.reset(seed=seed)
    phase, closed_at, ever, rewards = "above", 0, False, []
    for k in range(env.max_episode_steps):
        cube = env.object_pose("cube")[:3]
        centre = env.grip_centre()
        grip = OPEN
        if phase == "above":
            goal = cube + np.array([0.0, 0.0, ABOVE_M])
            if np.linalg.norm(centre[:2] - cube[:2]) < 0.008:
                phase = "down"
        if phase == "down":
            goal = cube.copy()
            near = np.linalg.norm(centre[:2] - cube[:2]) < 0.008
            if abs(centre[2] - cube[2]) < 0.006 and near:
                phase, closed_at = "close", k
        if phase == "close":
            goal, grip = centre, CLOSED
            if k - closed_at >= 5:
                phase = "lift"
        if phase == "lift":
            goal, grip = centre + np.array([0.0, 0.0, 0.02]), CLOSED
        delta = np.clip(goal - centre, -step, step)  # closed loop on where the jaws are
        action = np.concatenate([delta, [0.0, 0.0, grip]])  # pitch and roll held
        _, reward, _, _, info = env.step(action)
        rewards.append((phase, round(float(reward), 3)))
        ever |= bool(info["is_success"])
    return ever, rewards


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--start", choices=["rest", "recipe"], default="recipe")
    p.add_argument("--seeds", type=int, default=20)
    p.add_argument("--rewards", action="store_true")
    args = p.parse_args()
    kwargs = {**recipe_kwargs(), "terminate_on_success": False}
    if args.start == "rest":
        kwargs.pop("initial_pose")
    env = make("pick_cube", **kwargs).unwrapped
    step = env.action_space.high[0]
    wins = 0
    for seed in range(args.seeds):
        ok, rewards = episode(env, seed, float(step))
        wins += ok
        print(seed, "success" if ok else "fail")
        if args.rewards and seed < 2:
            print("  reward every 3rd step:", rewards[::3])
    print(f"{args.start}: {wins}/{args.seeds}")
    env.close()
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
