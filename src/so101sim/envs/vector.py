"""The vector environments' one entry, :func:`make_vec`: the backend chosen by name (the N
worlds in this process, :mod:`.worlds`; on a GPU, :mod:`.warp`; over Ray actors,
:mod:`.rayvec`)."""

from __future__ import annotations

from typing import Any, Literal, get_args

from gymnasium.vector import VectorEnv

from ..validation import check_choice
from .worlds import MAX_WORLDS, So101VectorEnv

Backend = Literal["cpu", "warp", "ray"]
"""Where an environment's worlds step: MuJoCo on the CPU's cores, MuJoCo Warp on a GPU, or
Ray actors."""
BACKENDS: tuple[str, ...] = get_args(Backend)


def make_vec(
    task: str,
    num_envs: int = 1,
    *,
    backend: Backend = "cpu",
    nthread: int | None = None,
    **env_kwargs: Any,
) -> VectorEnv:
    """A vector environment of ``num_envs`` worlds of ``task`` (a task name such as
    ``"reach"`` or a Gymnasium id), each made with ``env_kwargs`` (the options of
    ``gym.make``).

    ``backend``: ``"cpu"`` (MuJoCo on every core: ``nthread`` threads, default the cores this
    process may use), ``"warp"`` (MuJoCo Warp on a CUDA GPU: the optional ``warp`` extra;
    see :mod:`so101sim.envs.warp`) or ``"ray"`` (the worlds split over Ray actors:
    ``address="local"`` starts a Ray here, ``"auto"`` or ``"host:port"`` joins a cluster;
    ``workers`` actors; see :mod:`so101sim.envs.rayvec`).

    Raises:
        SettingError: an unknown task or backend, a bad count or option.
        So101SimError: ``backend="warp"`` where MuJoCo Warp or a CUDA device is missing.
    """
    check_choice(backend, "backend", BACKENDS)
    if backend == "ray":
        from .rayvec import RayVectorEnv  # imported here only: it needs the optional Ray

        return RayVectorEnv(task, num_envs, **env_kwargs)
    if backend == "warp":
        from .warp import WarpVectorEnv  # imported here only: it needs the optional extra

        return WarpVectorEnv(task, num_envs, **env_kwargs)
    return So101VectorEnv(task, num_envs, nthread=nthread, **env_kwargs)


__all__ = ["BACKENDS", "MAX_WORLDS", "Backend", "So101VectorEnv", "make_vec"]
