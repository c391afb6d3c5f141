"""Many worlds past one machine: ``make_vec(task, N, backend="ray")`` splits the N worlds over
Ray actors (one CPU each, on the cluster at ``address``), each holding a
:class:`~so101sim.envs.worlds.So101VectorEnv` of its share; a step sends each actor its rows of
the actions and joins the answers in world order.

World i is the same world as in ``make_vec(task, N)`` (its own seed ``seed + i``, its own
randomisation), so the observations, rewards, ends and ``info`` are the same, bit for bit; only
where the worlds run differs. Ray is an optional extra (``pip install "so101sim[ray]"``),
imported only here; the cluster is joined (or started) as ``so101sim check --variants --ray``
does it (:func:`so101sim.preflight.distributed.connect_ray`).
"""

from __future__ import annotations

import contextlib
from copy import deepcopy
from typing import Any, ClassVar

import numpy as np
from gymnasium.vector import VectorEnv
from gymnasium.vector.utils import batch_space

from ..errors import SettingError
from ..preflight.distributed import connect_ray, import_ray
from ..validation import check_count
from .worlds import MAX_WORLDS, So101VectorEnv, WorldChecks

MAX_RAY_ACTORS = 1024


class _Worlds:
    """One actor's share of the worlds (runs in a Ray worker process)."""

    def __init__(self, task: str, num_envs: int, env_kwargs: dict[str, Any]) -> None:
        self.venv = So101VectorEnv(task, num_envs, nthread=1, **env_kwargs)

    def spaces(self) -> tuple[Any, Any, dict[str, Any], Any]:
        v = self.venv
        return v.single_observation_space, v.single_action_space, v.metadata, v.spec

    def reset(self, seeds: list[int | None], options: dict[str, Any] | None) -> tuple:
        return self.venv.reset(seed=seeds, options=options)

    def step(self, actions: np.ndarray) -> tuple:
        return self.venv.step(actions)

    def close(self) -> None:
        self.venv.close()


def split(count: int, parts: int) -> list[tuple[int, int]]:
    """``[start, stop)`` of ``parts`` nearly equal shares of ``0..count`` (the first ones one
    larger when it does not divide)."""
    base, extra = divmod(count, parts)
    out, start = [], 0
    for k in range(parts):
        stop = start + base + (1 if k < extra else 0)
        out.append((start, stop))
        start = stop
    return out


def concat_batches(parts: list[Any]) -> Any:
    """Batched observations (arrays, or dicts of them) joined along the worlds."""
    if isinstance(parts[0], dict):
        return {k: concat_batches([p[k] for p in parts]) for k in parts[0]}
    return np.concatenate(parts, axis=0)


def merge_infos(parts: list[dict[str, Any]], sizes: list[int]) -> dict[str, Any]:
    """Vector ``info`` dicts of consecutive shares of the worlds (each key with its ``_key``
    mask, as Gymnasium stacks them) as one over all the worlds; a key a share lacks is masked
    off there."""
    keys = list(dict.fromkeys(k for p in parts for k in p if f"_{k}" in p))
    out: dict[str, Any] = {}
    for key in keys:
        values = [p.get(key) for p in parts]
        if any(isinstance(v, dict) for v in values):
            out[key] = merge_infos([v if isinstance(v, dict) else {} for v in values], sizes)
        else:
            like = next(np.asarray(v) for v in values if v is not None)
            filled = []
            for v, n in zip(values, sizes, strict=True):
                if v is not None:
                    filled.append(np.asarray(v))
                elif like.dtype == object:
                    filled.append(np.full(n, None, dtype=object))
                else:
                    filled.append(np.zeros((n, *like.shape[1:]), dtype=like.dtype))
            out[key] = np.concatenate(filled, axis=0)
        masks = [
            p.get(f"_{key}", np.zeros(n, dtype=bool)) for p, n in zip(parts, sizes, strict=True)
        ]
        out[f"_{key}"] = np.concatenate(masks)
    return out


class RayVectorEnv(WorldChecks, VectorEnv):
    """N worlds of one task over Ray actors (see the module's text); made by
    ``make_vec(task, N, backend="ray", address=..., workers=...)``."""

    metadata: ClassVar[dict[str, Any]] = dict(So101VectorEnv.metadata)

    def __init__(
        self,
        task: str,
        num_envs: int,
        *,
        address: str = "local",
        workers: int | None = None,
        **env_kwargs: Any,
    ) -> None:
        self.num_envs = check_count(num_envs, "num_envs", minimum=1, maximum=MAX_WORLDS)
        if workers is not None:
            check_count(workers, "workers", minimum=1, maximum=MAX_RAY_ACTORS)
        if env_kwargs.get("render_mode") is not None:
            raise SettingError(
                f"render_mode={env_kwargs['render_mode']!r} with backend='ray'; expected None "
                "(the worlds run in other processes: render on the cpu backend)"
            )
        ray = import_ray()
        self._started = connect_ray(address, num_cpus=workers if address == "local" else None)
        try:
            cpus = int(ray.cluster_resources().get("CPU", 1))
            count = min(self.num_envs, workers or max(1, cpus))
            self._shares = split(self.num_envs, count)
            actor = ray.remote(num_cpus=1)(_Worlds)
            self._actors = [actor.remote(task, b - a, env_kwargs) for a, b in self._shares]
            obs_space, act_space, metadata, spec = ray.get(self._actors[0].spaces.remote())
        except BaseException:
            self._shutdown(ray)
            raise
        self._ray = ray
        self.task = task
        self.render_mode = None
        self.metadata = {**self.metadata, **metadata}
        self.spec = spec
        self.single_observation_space = obs_space
        self.single_action_space = act_space
        self.observation_space = batch_space(obs_space, self.num_envs)
        self.action_space = batch_space(act_space, self.num_envs)
        self._closed = False

    @property
    def workers(self) -> int:
        """The Ray actors the worlds are split over."""
        return len(self._shares)

    def _sizes(self) -> list[int]:
        return [b - a for a, b in self._shares]

    def reset(
        self, *, seed: int | list[int | None] | None = None, options: dict[str, Any] | None = None
    ) -> tuple[Any, dict[str, Any]]:
        """Reset every world; world i gets ``seed + i`` (a list: one seed per world)."""
        self._check_open("reset")
        seeds = self._seeds(seed)
        refs = [
            actor.reset.remote(seeds[a:b], options)
            for actor, (a, b) in zip(self._actors, self._shares, strict=True)
        ]
        parts = self._ray.get(refs)
        obs = concat_batches([p[0] for p in parts])
        return obs, merge_infos([p[1] for p in parts], self._sizes())

    def step(self, actions: Any) -> tuple[Any, np.ndarray, np.ndarray, np.ndarray, dict[str, Any]]:
        """One control period in every world, each actor stepping its share at once."""
        self._check_open("step")
        actions = self._action_rows(actions)
        refs = [
            actor.step.remote(actions[a:b])
            for actor, (a, b) in zip(self._actors, self._shares, strict=True)
        ]
        parts = self._ray.get(refs)
        obs = concat_batches([p[0] for p in parts])
        rewards, terminated, truncated = (np.concatenate([p[k] for p in parts]) for k in (1, 2, 3))
        infos = merge_infos([p[4] for p in parts], self._sizes())
        return deepcopy(obs), rewards, terminated, truncated, infos

    def _shutdown(self, ray: Any) -> None:
        for actor in getattr(self, "_actors", []):
            with contextlib.suppress(Exception):  # an actor already gone: nothing to close
                ray.get(actor.close.remote())
            ray.kill(actor)
        self._actors = []
        if self._started:
            ray.shutdown()
            self._started = False

    def close_extras(self, **kwargs: Any) -> None:
        """Close every actor's worlds, stop the actors, and a cluster this started."""
        if not getattr(self, "_closed", True):
            self._closed = True
            self._shutdown(self._ray)


__all__ = ["MAX_RAY_ACTORS", "RayVectorEnv", "concat_batches", "merge_infos", "split"]
