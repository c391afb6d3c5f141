"""Many worlds at once: :func:`make_vec` gives a Gymnasium ``VectorEnv`` of N copies of a task
whose physics is stepped together, in C, on every core (:class:`so101sim.sim.batched.WorldStepper`).

Each world is a whole :class:`~so101sim.envs.So101TaskEnv` (its own compiled scene, arm
profile and randomisation, seeded on its own), so the observations, actions, rewards and
``info`` are those of N single environments, bit for bit; only the physics of a step is taken
for all the worlds in one call, and Python runs once per world per environment step (never
per physics step). Where the worlds allow it (:mod:`.batch`), the actions' joint targets and
the observations are computed for all the worlds at once (the same elementwise operations on
one row per world), and each world's success test, reward and ``info`` run on the thread that
stepped it, right after its physics, while the other threads are inside MuJoCo; resets (the
random draws) and everything shared stay on the calling thread, in world order.

Gymnasium 1.x conventions: ``metadata["autoreset_mode"]`` is ``AutoresetMode.SAME_STEP``: a
world whose episode ended is reset within the same ``step()``; the observation returned is the
new episode's first, and ``info["final_obs"]`` / ``info["final_info"]`` (masked by
``info["_final_obs"]`` / ``info["_final_info"]``) hold the last ones of the episode that ended.
Every key of a world's ``info`` is stacked over the worlds with its ``_key`` mask, as
``SyncVectorEnv`` does, so ``gymnasium.wrappers.vector.RecordEpisodeStatistics`` counts the
episodes right. ``reset(seed=s)`` seeds world i with ``s + i`` (a list: one seed per world).
"""

from __future__ import annotations

from copy import deepcopy
from typing import Any, ClassVar

import numpy as np
from gymnasium.vector import AutoresetMode, VectorEnv
from gymnasium.vector.utils import batch_space, concatenate, create_empty_array

from ..errors import ClosedError, SettingError
from ..sim.batched import WorldStepper
from ..validation import check_count
from .base import So101TaskEnv
from .batch import WorldBatch
from .run import make

MAX_WORLDS = 65_536


class WorldChecks:
    """What every vector environment of so101sim checks the same way (needs ``num_envs``,
    ``_closed`` and ``single_action_space``): a closed environment, the seeds, the actions."""

    num_envs: int
    _closed: bool
    single_action_space: Any

    def _check_open(self, what: str) -> None:
        if self._closed:
            raise ClosedError(
                f"{what}() on a closed vector environment; expected an open one (make a new "
                "one with make_vec after close())"
            )

    def _seeds(self, seed: int | list[int | None] | None) -> list[int | None]:
        if seed is None:
            return [None] * self.num_envs
        if isinstance(seed, int | np.integer):
            return [int(seed) + i for i in range(self.num_envs)]
        seeds = list(seed)
        if len(seeds) != self.num_envs:
            raise SettingError(
                f"{len(seeds)} seeds for {self.num_envs} worlds; expected one seed per world, "
                "an int (world i gets seed + i) or None"
            )
        return seeds

    def _action_rows(self, actions: Any) -> np.ndarray:
        actions = np.asarray(actions)
        if actions.shape[:1] != (self.num_envs,):
            raise SettingError(
                f"actions of shape {actions.shape}; expected ({self.num_envs}, "
                f"{', '.join(map(str, self.single_action_space.shape))}): one row per world"
            )
        return actions


class So101VectorEnv(WorldChecks, VectorEnv):
    """N worlds of one task stepped together (see the module's text); made by :func:`make_vec`."""

    metadata: ClassVar[dict[str, Any]] = {
        "autoreset_mode": AutoresetMode.SAME_STEP,
        "render_modes": [],
    }

    def __init__(
        self, task: str, num_envs: int, *, nthread: int | None = None, **env_kwargs: Any
    ) -> None:
        self.num_envs = check_count(num_envs, "num_envs", minimum=1, maximum=MAX_WORLDS)
        if env_kwargs.get("render_mode") == "human":
            raise SettingError(
                "render_mode='human' in a vector environment; expected None or 'rgb_array'"
            )
        first: So101TaskEnv = make(task, **env_kwargs).unwrapped
        # one compiled model for every world unless a draw changes it per world (the physics'
        # or the look's randomisation): 64 copies of it do not fit in the caches, one does
        shared = not first.randomize.active and not first.jitter.active
        more = {**env_kwargs, "shared_model": first.model} if shared else env_kwargs
        self.envs = [first, *(make(task, **more).unwrapped for _ in range(self.num_envs - 1))]
        self.shared_model = shared
        self.task = task
        self.render_mode = first.render_mode
        self.metadata = {
            **self.metadata,
            "render_modes": list(first.metadata["render_modes"]),
            "render_fps": first.metadata["render_fps"],
        }
        self.spec = first.spec
        self.single_observation_space = first.observation_space
        self.single_action_space = first.action_space
        self.observation_space = batch_space(self.single_observation_space, self.num_envs)
        self.action_space = batch_space(self.single_action_space, self.num_envs)
        self._stepper = WorldStepper(
            [e.model for e in self.envs], [e.sim.data for e in self.envs], nthread
        )
        self._obs = create_empty_array(self.single_observation_space, self.num_envs)
        self._no_results = [None] * self.num_envs
        self._results: list[Any] = list(self._no_results)
        self._extras: list[Any] = list(self._no_results)
        self._batch = WorldBatch(self.envs)
        # each world's reward and info (and its observation, unless taken for all the worlds
        # at once) on the thread that stepped it, right after its physics (while the other
        # threads step theirs): it touches that world only. Not with cameras: a renderer
        # draws on the thread that made its context
        self._after = None if first.cameras else self._finisher()
        self._closed = False

    def _finisher(self) -> Any:
        batched = self._batch.batch_observations
        finish = [env._judge_step if batched else env._finish_step for env in self.envs]
        results, extras = self._results, self._extras
        if batched and self._batch.extra:
            extra = [env._extra_state for env in self.envs]

            def after_extra(i: int) -> None:
                results[i] = finish[i]()
                extras[i] = extra[i]()

            return after_extra

        def after(i: int) -> None:
            results[i] = finish[i]()

        return after

    @property
    def nthread(self) -> int:
        """The worker threads that step the worlds."""
        return self._stepper.nthread

    def reset(
        self, *, seed: int | list[int | None] | None = None, options: dict[str, Any] | None = None
    ) -> tuple[Any, dict[str, Any]]:
        """Reset every world (``seed``: see the module's text; ``options`` go to each world's
        ``reset``)."""
        self._check_open("reset")
        infos: dict[str, Any] = {}
        observations = []
        for i, (env, s) in enumerate(zip(self.envs, self._seeds(seed), strict=True)):
            obs, info = env.reset(seed=s, options=options)
            observations.append(obs)
            infos = self._add_info(infos, info, i)
        self._obs = concatenate(self.single_observation_space, observations, self._obs)
        return deepcopy(self._obs), infos

    def step(self, actions: Any) -> tuple[Any, np.ndarray, np.ndarray, np.ndarray, dict[str, Any]]:
        """One control period in every world, the physics of all of them stepped together.

        Raises:
            SettingError: an action is not valid (the message names the world).
            SimulationDivergedError: a world's physics became unstable.
            ClosedError: the environment was closed.
        """
        self._check_open("step")
        actions = self._action_rows(actions)
        self._command(actions)
        steps = np.array([env._physics_steps() for env in self.envs], dtype=np.int64)
        results = self._results
        batched = self._after is not None and self._batch.batch_observations
        self._stepper.advance(steps, self._after)
        if self._after is None:  # frames to draw: on this thread (a renderer's GL context)
            for i, env in enumerate(self.envs):
                results[i] = env._finish_step()
        elif batched:  # every world's observation at once, into the batch
            self._batch.observe(self._obs, self._extras)
        if batched:
            rew, term, trunc, each = zip(*results, strict=True)
            observations: list[Any] = []
        else:
            obs_each, rew, term, trunc, each = zip(*results, strict=True)
            observations = list(obs_each)
        results[:] = self._no_results
        rewards = np.array(rew, dtype=np.float64)
        terminated, truncated = np.array(term, dtype=bool), np.array(trunc, dtype=bool)
        step_infos = list(each)
        infos: dict[str, Any] = {}
        for i in np.flatnonzero(terminated | truncated).tolist():
            obs = {k: v[i].copy() for k, v in self._obs.items()} if batched else observations[i]
            infos = self._add_info(infos, {"final_obs": obs, "final_info": step_infos[i]}, i)
            obs, step_infos[i] = self.envs[i].reset()
            if batched:
                for k, v in obs.items():
                    self._obs[k][i] = v
            else:
                observations[i] = obs
        infos = self._stack_infos(infos, step_infos)
        if not batched:
            self._obs = concatenate(self.single_observation_space, observations, self._obs)
        return deepcopy(self._obs), rewards, terminated, truncated, infos

    def _command(self, actions: np.ndarray) -> None:
        """Every world's joint targets for its row of ``actions``: for all the worlds at once
        where they allow it (:mod:`.batch`), else world by world.

        Raises:
            SettingError: an action is not valid (the message names the world).
        """
        valid = self._batch.valid_actions(actions) if self._batch.batch_actions else None
        if valid is not None:
            self._batch.command(valid)
            return
        for i, env in enumerate(self.envs):
            try:
                targets = env.actions.targets(actions[i], env.sim.commanded_array())
            except SettingError as exc:
                raise SettingError(f"world {i}: {exc}") from None
            env.sim.command_array(targets, check=False)

    def _stack_infos(self, infos: dict[str, Any], each: list[dict[str, Any]]) -> dict[str, Any]:
        """Every world's ``info`` stacked as ``_add_info`` stacks it, the keys every world has
        with plain numbers at once (one array per key, not one call per world)."""
        every = np.ones(self.num_envs, dtype=bool)
        keys = each[0].keys()
        if all(info.keys() == keys for info in each):
            plain = [
                k for k in each[0] if type(each[0][k]) in (bool, int, float) and k not in infos
            ]
            for k in plain:
                infos[k] = np.array([info[k] for info in each], dtype=type(each[0][k]))
                infos[f"_{k}"] = every.copy()
            if len(plain) == len(keys):
                return infos
            rest = [{k: v for k, v in info.items() if k not in plain} for info in each]
        else:
            rest = each
        for i, info in enumerate(rest):
            if info:
                infos = self._add_info(infos, info, i)
        return infos

    def render(self) -> tuple[np.ndarray, ...] | None:
        """Each world's frame (``render_mode="rgb_array"``), else None."""
        self._check_open("render")
        if self.render_mode != "rgb_array":
            return None
        return tuple(env.render() for env in self.envs)

    def close_extras(self, **kwargs: Any) -> None:
        """Stop the stepping threads and close every world."""
        self._closed = True
        self._stepper.close()
        for env in self.envs:
            env.close()


__all__ = ["MAX_WORLDS", "So101VectorEnv", "WorldChecks"]
