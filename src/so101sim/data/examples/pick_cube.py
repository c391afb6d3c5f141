"""Pick up a cube: the so101sim/PickCube-v0 Gymnasium environment driven by its scripted
expert, step by step, as a policy would drive it; optionally recorded to a video.

(in the folder the examples were copied to: so101sim examples FOLDER; cd FOLDER)
python pick_cube.py                 # seed 0, prints the episode
python pick_cube.py --seed 3 --record pick.mp4
"""

import argparse

import gymnasium as gym

import so101sim.envs  # noqa: F401  (importing it registers the environments)
from so101sim.envs import expert_for, run_expert


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--record", help="write the episode to this MP4 (front camera)")
    args = parser.parse_args()

    env = gym.make("so101sim/PickCube-v0")
    expert = expert_for(env)
    obs, info = env.reset(seed=args.seed)
    expert.reset()
    cube = obs["environment_state"][:3]
    print(f"cube at x={cube[0]:.3f} y={cube[1]:.3f} m; arm at {obs['agent_pos'].round(1)}")
    done, steps, phase = False, 0, None
    while not done:
        obs, reward, terminated, truncated, info = env.step(expert.act(obs))
        steps += 1
        done = terminated or truncated
        if expert.phase != phase:
            phase = expert.phase
            print(f"  step {steps:3d}  t = {info['time']:.2f} s  {phase:8s} reward {reward:.2f}")
    print(
        f"success: {info['is_success']} after {steps} steps ({info['time']:.2f} s simulated), "
        f"cube {1000 * info['cube_rise_m']:.0f} mm up"
    )
    env.close()

    if args.record:
        result = run_expert("pick_cube", args.seed, record=args.record, force=True)
        print(f"wrote {result.video} ({result.steps} steps, success: {result.success})")


if __name__ == "__main__":
    main()
