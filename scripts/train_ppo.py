"""PPO on an so101sim task with stable-baselines3, on so101sim's batched environment
(``so101sim.envs.make_vec``): the recipe of docs/rl.md.

It lives outside ``src/so101sim`` on purpose: stable-baselines3 needs torch, and the core never
imports torch (the ``rl`` extra installs stable-baselines3; run it where torch is, e.g. the
LeRobot venv). The trained policy is recorded to a video here too: ``so101sim demo`` runs the
scripted experts and cannot load a torch policy without importing torch.

    python scripts/train_ppo.py --task reach --minutes 14 --out runs/reach
    python scripts/train_ppo.py --task reach --smoke          # a few hundred steps (tests)
    python scripts/train_ppo.py --task pick_cube --minutes 60 --target 0.9 --out runs/pick

Writes to --out: ``progress.csv`` (the learning curve: steps, wall time, the share of the
last episodes that succeeded), ``curve.png``, ``model.zip`` and ``vecnormalize.pkl``,
``eval.json`` (success over --eval-episodes episodes from seeds 10 000 on, with the 95 %
Wilson interval) and ``policy.mp4`` (one evaluation episode from the front camera).
"""

from __future__ import annotations

import argparse
import csv
import json
import math
import time
from collections import deque
from pathlib import Path
from typing import Any

import numpy as np

OBS_KEYS = ("agent_pos", "agent_vel", "environment_state")
ENV_KWARGS: dict[str, dict[str, Any]] = {
    # a reward per step in 0..1 and no end on success: the policy learns to stay on the goal
    # the tip moved in metres (the kinematics module's IK turns it into joint targets): the
    # policy need not learn the arm's geometry, so PPO gets there in a few minutes of CPU
    "reach": {"control": "ee_delta", "control_hz": 10.0, "ee_step": 0.03, "episode_seconds": 2.5},
    "reach_joint": {
        "control": "joint_delta",
        "control_hz": 10.0,
        "max_delta": 20.0,
        "episode_seconds": 2.5,
    },
    # the tip and the gripper (4 numbers), the tool's pitch and roll held as they start: from
    # PICK_START, pointing straight down (from the folded rest pose the held pitch is -50
    # degrees, and jaws closing along an axis tilted 40 degrees up picked the cube in 9 of
    # 20 hand-driven episodes against 19 of 20 top-down: scripts/pick_by_hand.py, docs/rl.md);
    # 5 s episodes
    "pick_cube": {
        "control": "ee_delta",
        "control_hz": 10.0,
        "episode_seconds": 5.0,
        "initial_pose": {
            # the tip 8 cm above the table at x = 0.20 m, pitch -89.9, roll 0.01 degrees
            "shoulder_pan": 0.0,
            "shoulder_lift": -12.1,
            "elbow_flex": 11.4,
            "wrist_flex": 90.6,
            "wrist_roll": 2.8,
            "gripper": 0.0,
        },
    },
}
TASK_OF = {"reach_joint": "reach"}
"""Recipes on another recipe's task (the same task, other settings)."""
POSITION_ONLY = {"reach"}
"""Recipes whose policy moves the tip only (dx, dy, dz: ``ee_delta``'s first three), the
tool's pitch, roll and the gripper held (0, 0, closed): what a reach needs, as ManiSkill's
``pd_ee_delta_pos``."""


POSITION_GRIPPER = {"pick_cube"}
"""Recipes whose policy moves the tip and sets the gripper (4 numbers)."""
TIP_FEATURES = {"pick_cube"}
"""Recipes whose policy also sees where the tip is and the cube from the point between the
jaws (6 numbers, from the joint positions by forward kinematics and the cube's pose in the
state): an MLP need not learn the arm's geometry from a few hundred thousand steps, as
ManiSkill's state observations give ``tcp_pose`` and ``tcp_to_obj_pos``."""


def action_size(recipe: str, full: int) -> int:
    return 3 if recipe in POSITION_ONLY else 4 if recipe in POSITION_GRIPPER else full


def full_action(recipe: str, a: np.ndarray, low: np.ndarray, high: np.ndarray) -> np.ndarray:
    """The environment's actions (n, 6) for the policy's (n, k) in -1..1."""
    a = np.clip(a, -1.0, 1.0)
    if recipe in POSITION_ONLY or recipe in POSITION_GRIPPER:
        out = np.zeros((len(a), len(low)))
        out[:, :3] = low[:3] + (a[:, :3] + 1.0) * 0.5 * (high[:3] - low[:3])
        if recipe in POSITION_GRIPPER:
            out[:, 5] = low[5] + (a[:, 3] + 1.0) * 0.5 * (high[5] - low[5])
        return out
    return low + (a + 1.0) * 0.5 * (high - low)


def flatten(obs: dict[str, np.ndarray], recipe: str | None = None) -> np.ndarray:
    """The state keys side by side: (num_envs, features) float32; for the recipes of
    :data:`TIP_FEATURES` the tip's position and the cube less the point between the jaws
    after them."""
    parts = [np.asarray(obs[k], dtype=np.float32) for k in OBS_KEYS]
    if recipe in TIP_FEATURES:
        parts.append(tip_features(obs["agent_pos"], obs["environment_state"]))
    return np.concatenate(parts, axis=-1)


def tip_features(joints: np.ndarray, state: np.ndarray) -> np.ndarray:
    """(n, 6) float32: the tip's position (metres, base frame) for each row of joint positions
    (arm units), and the object's position (``state``'s first three) less the point between
    the jaws."""
    from so101sim.envs.scene_state import GRIP_OFFSET_M  # the point between the jaws
    from so101sim.kinematics import for_model

    kin = for_model()
    out = np.empty((len(joints), 6), dtype=np.float32)
    for i, row in enumerate(np.asarray(joints, dtype=float)):
        tip = kin.tip_array(row)
        out[i, :3] = tip.position
        out[i, 3:] = np.asarray(state[i][:3]) - (tip.position + GRIP_OFFSET_M * tip.rotation[:, 2])
    return out


def wilson(successes: int, n: int, z: float = 1.96) -> tuple[float, float]:
    """The Wilson score interval of a success rate (95 % by default)."""
    if n == 0:
        return 0.0, 1.0
    p = successes / n
    centre = (p + z * z / (2 * n)) / (1 + z * z / n)
    half = z * math.sqrt(p * (1 - p) / n + z * z / (4 * n * n)) / (1 + z * z / n)
    return max(0.0, centre - half), min(1.0, centre + half)


def make_venv(
    task: str, num_envs: int, seed: int, nthread: int | None, ray: str | None = None
) -> Any:
    """stable-baselines3's VecEnv over so101sim's batched environment (same-step autoreset:
    the episode's last observation goes in ``info["terminal_observation"]``, as sb3 expects),
    the actions scaled from -1..1 to the environment's delta range."""
    from gymnasium import spaces
    from stable_baselines3.common.vec_env import VecEnv

    from so101sim.envs import make_vec

    class So101SB3VecEnv(VecEnv):
        def __init__(self) -> None:
            kwargs = {**ENV_KWARGS[task], "terminate_on_success": False}
            where = {"backend": "ray", "address": ray} if ray else {"nthread": nthread}
            self.venv = make_vec(TASK_OF.get(task, task), num_envs, **where, **kwargs)
            single = self.venv.single_observation_space
            size = sum(single[k].shape[0] for k in OBS_KEYS) + 6 * (task in TIP_FEATURES)
            obs_space = spaces.Box(-np.inf, np.inf, (size,), dtype=np.float32)
            act = self.venv.single_action_space
            self.low, self.high = act.low, act.high
            dims = action_size(task, act.shape[0])
            act_space = spaces.Box(-1.0, 1.0, (dims,), dtype=np.float32)
            super().__init__(num_envs, obs_space, act_space)
            self._seed = seed
            self._actions: np.ndarray | None = None
            self.successes: deque[float] = deque(maxlen=100)
            self.returns: deque[float] = deque(maxlen=100)
            self._return = np.zeros(num_envs)
            self._ever = np.zeros(num_envs, dtype=bool)

        def reset(self) -> np.ndarray:
            obs, _ = self.venv.reset(seed=self._seed)
            self._seed += num_envs
            self._ever[:] = False
            self._return[:] = 0.0
            return flatten(obs, task)

        def step_async(self, actions: np.ndarray) -> None:
            self._actions = full_action(task, actions, self.low, self.high)

        def step_wait(self) -> tuple:
            obs, rew, term, trunc, info = self.venv.step(self._actions)
            flat = flatten(obs, task)
            done = term | trunc
            self._return += rew
            self._ever |= np.asarray(info.get("is_success", np.zeros(num_envs)), dtype=bool)
            infos: list[dict[str, Any]] = [{} for _ in range(num_envs)]
            for i in np.flatnonzero(done):
                final = info["final_obs"][i]  # the world's own observation (gymnasium 1.x)
                last = {k: final[k][None] for k in OBS_KEYS}
                infos[i]["terminal_observation"] = flatten(last, task)[0]
                infos[i]["TimeLimit.truncated"] = bool(trunc[i] and not term[i])
                success = bool(self._ever[i] or info["final_info"]["is_success"][i])
                infos[i]["is_success"] = success
                self.successes.append(float(success))
                self._ever[i] = False
                self.returns.append(float(self._return[i]))
                self._return[i] = 0.0
            return flat, rew.astype(np.float32), done, infos

        def close(self) -> None:
            self.venv.close()

        def get_attr(self, name: str, indices: Any = None) -> list:
            return [getattr(self, name)] * num_envs

        def set_attr(self, name: str, value: Any, indices: Any = None) -> None:
            setattr(self, name, value)

        def env_method(self, name: str, *args: Any, indices: Any = None, **kw: Any) -> list:
            return [None] * num_envs

        def env_is_wrapped(self, wrapper_class: Any, indices: Any = None) -> list[bool]:
            return [False] * num_envs

    return So101SB3VecEnv()


def evaluate(task: str, model: Any, norm: Any, episodes: int, video: Path | None) -> dict:
    """Success over ``episodes`` episodes (seeds 10 000 on, deterministic actions): an episode
    succeeds if the task succeeded at any step (as lerobot-eval counts)."""
    from so101sim.envs import make
    from so101sim.recording import VideoRecorder, VideoSettings

    kwargs = {**ENV_KWARGS[task], "terminate_on_success": False}
    env = make(TASK_OF.get(task, task), **kwargs).unwrapped
    act = env.action_space
    wins, at_end = 0, 0
    for ep in range(episodes):
        recorder = None
        if video is not None and ep == 0:
            settings = VideoSettings(width=640, height=480, camera="front", caption=False)
            recorder = VideoRecorder(video, env.model, settings, force=True)
            env.sim.observers.append(recorder)
        obs, info = env.reset(seed=10_000 + ep)
        ever, done = False, False
        while not done:
            x = norm.normalize_obs(flatten({k: obs[k][None] for k in OBS_KEYS}, task))
            a, _ = model.predict(x, deterministic=True)
            a = full_action(task, a, act.low, act.high)[0]
            obs, _, term, trunc, info = env.step(a)
            ever |= bool(info["is_success"])
            done = term or trunc
        wins += ever
        at_end += bool(info["is_success"])
        if recorder is not None:
            env.sim.observers.remove(recorder)
            recorder.close()
    env.close()
    lo, hi = wilson(wins, episodes)
    return {
        "task": task,
        "episodes": episodes,
        "success_rate": wins / episodes,
        "wilson95": [lo, hi],
        "success_at_end_rate": at_end / episodes,
        "video": str(video) if video else None,
    }


def plot(rows: list[dict], path: Path, task: str) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(6, 3.5))
    ax.plot([r["minutes"] for r in rows], [r["success_last100"] for r in rows])
    ax.set_xlabel("wall-clock minutes (2-core CPU, shared)")
    ax.set_ylabel("success, last 100 episodes")
    ax.set_ylim(-0.02, 1.02)
    ax.set_title(f"PPO on {task} (stable-baselines3, so101sim make_vec)")
    ax.grid(alpha=0.3)
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--task", default="reach", choices=sorted(ENV_KWARGS))
    p.add_argument("--envs", type=int, default=16)
    p.add_argument("--nthread", type=int, default=None)
    p.add_argument(
        "--ray",
        metavar="ADDRESS",
        default=None,
        help="step the worlds on Ray actors: local (start a Ray here), auto or host:port",
    )
    p.add_argument("--minutes", type=float, default=14.0, help="training wall-clock budget")
    p.add_argument("--steps", type=int, default=3_000_000, help="at most this many env steps")
    p.add_argument("--target", type=float, default=0.97, help="stop once the last 100 reach it")
    p.add_argument("--eval-episodes", type=int, default=100)
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--out", type=Path, default=Path("runs/ppo"))
    p.add_argument("--smoke", action="store_true", help="a few hundred steps, no evaluation")
    args = p.parse_args(argv)

    import torch
    from stable_baselines3 import PPO
    from stable_baselines3.common.callbacks import BaseCallback
    from stable_baselines3.common.vec_env import VecNormalize

    torch.set_num_threads(1)
    args.out.mkdir(parents=True, exist_ok=True)
    raw = make_venv(
        args.task, args.envs if not args.smoke else 2, args.seed, args.nthread, args.ray
    )
    venv = VecNormalize(raw, norm_obs=True, norm_reward=True, gamma=0.98)
    n_steps = 16 if args.smoke else 128
    model = PPO(
        "MlpPolicy",
        venv,
        n_steps=n_steps,
        batch_size=32 if args.smoke else 512,
        n_epochs=2 if args.smoke else 10,
        learning_rate=3e-4,
        gamma=0.98,
        gae_lambda=0.95,
        clip_range=0.2,
        ent_coef=0.0,
        policy_kwargs={"net_arch": [128, 128], "log_std_init": -0.5},
        seed=args.seed,
        device="cpu",
        verbose=0,
    )
    rows: list[dict] = []
    start = time.perf_counter()

    class Progress(BaseCallback):
        def _on_step(self) -> bool:
            return True

        def _on_rollout_end(self) -> None:
            minutes = (time.perf_counter() - start) / 60
            rate = float(np.mean(raw.successes)) if raw.successes else 0.0
            rows.append(
                {
                    "steps": self.num_timesteps,
                    "minutes": round(minutes, 3),
                    "success_last100": round(rate, 3),
                    "episodes_seen": len(raw.successes),
                    "return_last100": round(float(np.mean(raw.returns)), 3) if raw.returns else 0.0,
                }
            )
            with (args.out / "progress.csv").open("w", newline="") as f:
                w = csv.DictWriter(f, fieldnames=list(rows[0]))
                w.writeheader()
                w.writerows(rows)
            full = len(raw.successes) == raw.successes.maxlen
            self._stop = minutes >= args.minutes or (full and rate >= args.target)

        def _on_rollout_start(self) -> None:
            if getattr(self, "_stop", False):
                self.model._so101_stop = True

    class Stopper(Progress):
        def _on_step(self) -> bool:
            return not getattr(self, "_stop", False)

    total = 2 * args.envs * n_steps if args.smoke else args.steps
    model.learn(total_timesteps=total, callback=Stopper())
    train_minutes = (time.perf_counter() - start) / 60
    model.save(args.out / "model.zip")
    venv.save(str(args.out / "vecnormalize.pkl"))
    venv.training = False
    if rows:
        plot(rows, args.out / "curve.png", args.task)
    summary: dict[str, Any] = {
        "train_minutes": round(train_minutes, 2),
        "train_steps": int(model.num_timesteps),
        "envs": raw.num_envs,
        "nthread": getattr(raw.venv, "nthread", None),
        "ray_workers": getattr(raw.venv, "workers", None),
    }
    if not args.smoke:
        summary.update(
            evaluate(args.task, model, venv, args.eval_episodes, args.out / "policy.mp4")
        )
    (args.out / "eval.json").write_text(json.dumps(summary, indent=2))
    print(json.dumps(summary))
    venv.close()
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
