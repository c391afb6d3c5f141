"""The scripted expert's episodes past one machine: :func:`~so101sim.envs.run.expert_frames`
as Ray tasks (``so101sim dataset --ray ADDRESS``), one episode a task, results in seed order.

Ray is an optional extra (``pip install "so101sim[ray]"``), imported only when asked for; the
cluster is joined (or started) as ``so101sim check --variants --ray`` does it
(:func:`so101sim.preflight.distributed.connect_ray`). An episode depends only on its seed and
settings, so the episodes are the same as on worker processes, seed for seed.
"""

from __future__ import annotations

from collections.abc import Iterator, Sequence
from typing import Any

from ..preflight.distributed import connect_ray, import_ray
from ..validation import check_count
from .run import ExpertFrames, expert_frames

MAX_RAY_EPISODES = 1_000_000
"""The most episodes submitted in one call."""


def expert_frames_on_ray(
    task: str,
    seeds: Sequence[int],
    *,
    address: str = "local",
    workers: int | None = None,
    **frames_kwargs: Any,
) -> Iterator[ExpertFrames]:
    """The episodes of ``seeds`` (``expert_frames(task, seed, **frames_kwargs)`` each) run as
    Ray tasks on the cluster at ``address`` ("local": one started here with ``workers`` CPUs;
    "auto"; ``host:port``), yielded in seed order as they are ready. A cluster this call
    started is shut down when the generator ends or is closed.

    Raises:
        SettingError: Ray is not installed, no cluster answers at ``address``, or too many
            seeds.
    """
    check_count(len(seeds), "episodes", maximum=MAX_RAY_EPISODES)
    ray = import_ray()
    started = connect_ray(address, num_cpus=workers if address == "local" else None)
    try:
        remote = ray.remote(num_cpus=1)(expert_frames)
        refs = [remote.remote(task, int(s), **frames_kwargs) for s in seeds]
        for ref in refs:
            yield ray.get(ref)
    finally:
        if started:
            ray.shutdown()


__all__ = ["MAX_RAY_EPISODES", "expert_frames_on_ray"]
