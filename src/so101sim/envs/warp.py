"""The GPU backend of :func:`so101sim.envs.make_vec` (``backend="warp"``): N worlds in MuJoCo
Warp (the optional ``warp`` extra: ``pip install 'so101sim[warp]'``), the model put on the
device once (``mujoco_warp.put_model``), all worlds in one ``mujoco_warp.Data``
(``put_data(nworld=N)``), each control period's physics steps captured once as a CUDA graph and
replayed, the observations, rewards and successes computed from the device's arrays for all
worlds at once (NumPy over the batch: no Python per world per step).

What it runs (and refuses with what to use instead):

* the **reach** task: its reward needs only the tip's position (the device's ``site_xpos``);
  the grasping tasks judge contacts, which stay on the CPU backend for now;
* the ``official`` arm profile (``arm="official"``, the vendored ideal position servos):
  MuJoCo Warp 4.0 has no ``mjDYN_PID`` actuators, which the default ``sts3215`` profile's
  servo model uses;
* ``joint`` and ``joint_delta`` control, no cameras, no randomisation;
* each control period takes ``substeps`` physics steps (20 at 25 Hz; at a rate that is not a
  whole number of steps, the nominal count rounded, not the CPU backend's 16-or-17).

Resets (and auto-resets, same step as on the CPU backend) draw each world's start on the CPU
with that world's own generator, as a single environment would, and copy it to the device.

A CUDA device is needed (``device="cuda"``, the default); ``device="cpu"`` runs Warp's CPU
kernels, slowly (minutes of kernel compilation the first time), to check results on a machine
without a GPU. This backend was written and checked on a CPU only (no GPU was available when
it was written): see docs/rl.md.
"""

from __future__ import annotations

from copy import deepcopy
from typing import Any, ClassVar

import numpy as np
from gymnasium.vector import AutoresetMode, VectorEnv
from gymnasium.vector.utils import batch_space

from ..errors import MissingDependencyError, SettingError
from ..model.load import arm_index
from ..model.loadfriction import active_load_friction
from ..scenes import object_qpos
from ..validation import check_choice, check_count
from .reach import REACH_SCALE, REACH_SUCCESS_M, ReachEnv
from .run import TASKS, env_id, make

WARP_TASKS = ("reach",)
WARP_CONTROLS = ("joint", "joint_delta")
MAX_WARP_WORLDS = 1 << 20


def import_warp(device: str) -> tuple[Any, Any]:
    """``(warp, mujoco_warp)``, initialised, with ``device`` usable.

    Raises:
        MissingDependencyError: MuJoCo Warp is not installed, or ``device`` is ``"cuda"`` and
            no CUDA device is there.
    """
    try:
        # optional extra (warp): only the GPU backend needs MuJoCo Warp
        import warp

        warp.config.quiet = True  # before mujoco_warp initialises it: the library never prints
        warp.config.log_level = warp.LOG_WARNING
        import mujoco_warp
    except ImportError as exc:
        raise MissingDependencyError(
            f"backend='warp' needs MuJoCo Warp, which is not installed ({exc.name}); expected "
            "pip install 'so101sim[warp]' (mujoco-warp) on a machine with a CUDA GPU, or "
            "backend='cpu'"
        ) from None
    warp.init()
    if device.startswith("cuda") and not warp.is_cuda_available():
        raise MissingDependencyError(
            "backend='warp' needs a CUDA device and Warp found none on this machine; expected "
            "a machine with an NVIDIA GPU and its driver, or backend='cpu' (every core)"
        )
    return warp, mujoco_warp


class WarpVectorEnv(VectorEnv):
    """Reach in N worlds of MuJoCo Warp (see the module's text); made by
    ``make_vec(task, N, backend="warp", ...)``."""

    metadata: ClassVar[dict[str, Any]] = {
        "autoreset_mode": AutoresetMode.SAME_STEP,
        "render_modes": [],
    }

    def __init__(
        self,
        task: str,
        num_envs: int,
        *,
        device: str = "cuda",
        nconmax: int | None = None,
        njmax: int | None = None,
        **env_kwargs: Any,
    ) -> None:
        self.num_envs = check_count(num_envs, "num_envs", minimum=1, maximum=MAX_WARP_WORLDS)
        if env_id(task) not in {TASKS[t] for t in WARP_TASKS}:
            raise SettingError(
                f"task {task!r} with backend='warp'; expected one of {', '.join(WARP_TASKS)} (the "
                "grasping tasks judge contacts, which are on the CPU backend)"
            )
        control = check_choice(env_kwargs.get("control", "joint"), "control", WARP_CONTROLS)
        for key in ("cameras", "render_mode", "visual_jitter"):
            if env_kwargs.get(key):
                raise SettingError(
                    f"{key} = {env_kwargs[key]!r} with backend='warp'; expected none (images "
                    "and rendering are on the CPU backend)"
                )
        if env_kwargs.get("randomize") not in (None, "none"):
            raise SettingError(
                f"randomize = {env_kwargs['randomize']!r} with backend='warp'; expected none "
                "(per-world randomisation is on the CPU backend)"
            )
        self.wp, self.mjw = import_warp(device)
        self.device = device
        self.env: ReachEnv = make(task, **env_kwargs).unwrapped  # the CPU template
        env = self.env
        self.control = control
        model = env.model
        if active_load_friction(model) is not None:
            raise SettingError(
                "MuJoCo Warp cannot run an arm profile with load_friction (so101sim sets that "
                "friction between steps on the CPU); expected a profile without it"
            )
        try:
            with self.wp.ScopedDevice(device):
                self.m_dev = self.mjw.put_model(model)
                self.d_dev = self.mjw.put_data(
                    model, env.sim.data, nworld=self.num_envs, nconmax=nconmax, njmax=njmax
                )
        except NotImplementedError as exc:
            raise SettingError(
                f"MuJoCo Warp cannot run this model ({exc}); expected arm='official' (the "
                "default sts3215 profile's servo model uses MuJoCo's PID actuators, which "
                "MuJoCo Warp does not have)"
            ) from None
        idx = arm_index(model)
        self._qpos, self._dof, self._act = idx.qpos, idx.dof, idx.actuator
        self._cube = object_qpos(model, "cube")
        self._units = env.sim.units
        self._scale = self._units.scale
        self.substeps = env.substeps
        self.max_episode_steps = env.max_episode_steps
        self.single_observation_space = env.observation_space
        self.single_action_space = env.action_space
        self.observation_space = batch_space(env.observation_space, self.num_envs)
        self.action_space = batch_space(env.action_space, self.num_envs)
        self.spec = env.spec
        n = self.num_envs
        self._rngs: list[np.random.Generator | None] = [None] * n
        self._goals = np.zeros((n, 3))
        self._commanded = np.zeros((n, 6))
        self._steps = np.zeros(n, dtype=np.int64)
        self._graph: Any = None

    # -- the CPU side of a reset: one world's start, drawn with its own generator
    def _draw(self, i: int, seed: int | None) -> tuple[np.ndarray, ...]:
        env = self.env
        if seed is None and self._rngs[i] is not None:
            env._np_random = self._rngs[i]  # go on with the world's generator
        env.reset(seed=seed)
        self._rngs[i] = env.np_random
        d = env.sim.data
        return (
            d.qpos.copy(),
            d.qvel.copy(),
            d.ctrl.copy(),
            env.goal.copy(),
            env.sim.commanded_array(),
        )

    def _upload(self, worlds: np.ndarray, seeds: list[int | None]) -> None:
        d = self.d_dev
        qpos, qvel, ctrl = d.qpos.numpy(), d.qvel.numpy(), d.ctrl.numpy()
        warm, time = d.qacc_warmstart.numpy(), d.time.numpy()
        for i, s in zip(worlds, seeds, strict=True):
            qpos[i], qvel[i], ctrl[i], self._goals[i], self._commanded[i] = self._draw(int(i), s)
            warm[i], time[i] = 0.0, 0.0
        self._steps[worlds] = 0
        for array, value in ((d.qpos, qpos), (d.qvel, qvel), (d.ctrl, ctrl)):
            array.assign(value)
        d.qacc_warmstart.assign(warm)
        d.time.assign(time)

    def reset(
        self, *, seed: int | list[int | None] | None = None, options: dict[str, Any] | None = None
    ) -> tuple[dict[str, np.ndarray], dict[str, Any]]:
        """Every world back to a start drawn as a single environment draws it (world i from
        ``seed + i``; a list: one seed per world)."""
        n = self.num_envs
        if seed is None:
            seeds: list[int | None] = [None] * n
        elif isinstance(seed, int | np.integer):
            seeds = [int(seed) + i for i in range(n)]
        else:
            seeds = list(seed)
            if len(seeds) != n:
                raise SettingError(f"{len(seeds)} seeds for {n} worlds; expected one per world")
        self._upload(np.arange(n), seeds)
        self.mjw.forward(self.m_dev, self.d_dev)
        obs, success, distance = self._read()
        mask = np.ones(self.num_envs, dtype=bool)
        info = {"is_success": success, "goal_distance_m": distance}
        return deepcopy(obs), {**info, "_is_success": mask, "_goal_distance_m": mask}

    # -- stepping on the device
    def _physics(self) -> None:
        wp, mjw = self.wp, self.mjw
        with wp.ScopedDevice(self.device):
            if not self.device.startswith("cuda"):
                for _ in range(self.substeps):
                    mjw.step(self.m_dev, self.d_dev)
                return
            if self._graph is None:  # captured once, replayed every control period
                with wp.ScopedCapture() as capture:
                    for _ in range(self.substeps):
                        mjw.step(self.m_dev, self.d_dev)
                self._graph = capture.graph
            wp.capture_launch(self._graph)

    def _read(self) -> tuple[dict[str, np.ndarray], np.ndarray, np.ndarray]:
        d = self.d_dev
        qpos, qvel = d.qpos.numpy().astype(float), d.qvel.numpy().astype(float)
        space = self.single_observation_space
        pos = self._units.from_radians(qpos[:, self._qpos])
        obs = {"agent_pos": np.clip(pos, space["agent_pos"].low, space["agent_pos"].high)}
        if "agent_vel" in space.spaces:
            obs["agent_vel"] = qvel[:, self._dof] / self._scale
        tip = d.site_xpos.numpy()[:, self.env._tip].astype(float)
        if "environment_state" in space.spaces:
            state = [qpos[:, self._cube], self._goals, tip]
            obs["environment_state"] = np.concatenate(state, axis=1)
        obs = {k: v.astype(np.float32) for k, v in obs.items()}
        distance = np.linalg.norm(tip - self._goals, axis=1)
        return obs, distance <= REACH_SUCCESS_M, distance

    def step(
        self, actions: Any
    ) -> tuple[dict[str, np.ndarray], np.ndarray, np.ndarray, np.ndarray, dict]:
        """One control period in every world on the device (see the module's text)."""
        a = np.asarray(actions, dtype=float)
        space = self.single_action_space
        if a.shape != (self.num_envs, *space.shape) or not np.isfinite(a).all():
            raise SettingError(
                f"actions of shape {a.shape}; expected ({self.num_envs}, {space.shape[0]}) "
                "finite numbers, one row per world"
            )
        a = np.clip(a, space.low, space.high)
        lower, upper = self._units.limits
        targets = a if self.control == "joint" else self._commanded + a
        self._commanded = np.clip(targets, lower, upper)
        ctrl = self.d_dev.ctrl.numpy()
        ctrl[:, self._act] = self._units.to_radians(self._commanded)
        self.d_dev.ctrl.assign(ctrl)
        self._physics()
        self._steps += 1
        obs, success, distance = self._read()
        env = self.env
        dense = np.where(success, 1.0, 1.0 - np.tanh(REACH_SCALE * distance))
        rewards = dense if env.reward_mode == "dense" else success.astype(float)
        terminated = success & env.terminate_on_success
        truncated = (self._steps >= self.max_episode_steps) & ~terminated
        info: dict[str, Any] = {"is_success": success.copy(), "goal_distance_m": distance.copy()}
        done = np.flatnonzero(terminated | truncated)
        if len(done):
            final_obs = np.full(self.num_envs, None, dtype=object)  # as SyncVectorEnv
            for i in done:
                final_obs[i] = {k: v[i].copy() for k, v in obs.items()}
            mask = np.zeros(self.num_envs, dtype=bool)
            mask[done] = True
            final_info = {k: np.where(mask, v, 0 * v) for k, v in info.items()}
            final_info.update({f"_{k}": mask for k in info})
            info = {**info, "final_obs": final_obs, "_final_obs": mask}
            info.update(final_info=final_info, _final_info=mask)
            self._upload(done, [None] * len(done))
            self.mjw.forward(self.m_dev, self.d_dev)
            new_obs, new_success, new_distance = self._read()
            for k in obs:
                obs[k][done] = new_obs[k][done]
            info["is_success"][done] = new_success[done]
            info["goal_distance_m"][done] = new_distance[done]
        mask = np.ones(self.num_envs, dtype=bool)
        info.update(_is_success=mask, _goal_distance_m=mask)
        return obs, rewards, terminated, truncated, info

    def close_extras(self, **kwargs: Any) -> None:
        self.env.close()


__all__ = ["WARP_CONTROLS", "WARP_TASKS", "WarpVectorEnv", "import_warp"]
