"""The episodes of ``so101sim dataset``, simulated on worker processes (or Ray tasks) and
handed back in seed order.

Each worker runs so101sim's :func:`~so101sim.envs.run.expert_frames` (plain arguments) and
sends the episode's arrays back; at most ``2 × workers`` episodes are in flight (the frames
held in memory stay bounded). A worker's Mesa CPU rasteriser draws in the worker's own
thread (:func:`so101sim.gl.one_rasterizer_thread`): the workers already share the cores, and
a rasteriser thread only hands each frame over and back. (Not OpenMP's thread count: NumPy's
linear algebra rounds differently with another count, which changes the expert's plans, and
the same seed must give the same episode whatever the worker count.) Everything a worker is
handed to run lives in so101sim's core, so a worker never imports LeRobot, torch or this
plugin (importing this plugin's package imports LeRobot and torch: several CPU-seconds per
worker).
"""

from __future__ import annotations

import time
from collections.abc import Iterator
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass, field
from multiprocessing import get_context
from typing import TYPE_CHECKING, Any

import numpy as np

from so101sim.gl import one_rasterizer_thread

if TYPE_CHECKING:
    from .dataset import DatasetSettings

worker_init = one_rasterizer_thread
"""A worker's start: llvmpipe draws in the worker's thread (see the module's text)."""


def worker_pool(workers: int) -> ProcessPoolExecutor:
    """The process pool the episodes run on: ``workers`` spawned processes, each started by
    :data:`worker_init` (from so101sim's core: a worker imports neither LeRobot nor torch)."""
    ctx = get_context("spawn")  # MuJoCo's GL contexts and torch do not survive a fork
    return ProcessPoolExecutor(workers, mp_context=ctx, initializer=worker_init)


@dataclass(frozen=True)
class Episode:
    """One simulated episode as a worker hands it back."""

    seed: int
    success: bool
    success_frame: int | None
    states: np.ndarray  # (T, 6) float32
    actions: np.ndarray  # (T, 6) float32
    environment_state: np.ndarray | None = None  # (T, 7 * objects) float32
    images: dict[str, np.ndarray] = field(default_factory=dict)  # camera -> (T, h, w, 3)
    randomization: dict[str, Any] = field(default_factory=dict)
    sim_seconds: float = 0.0
    wall_seconds: float = 0.0


def _simulate(settings: DatasetSettings, seed: int) -> tuple[Any, float]:
    """In a worker: one episode (so101sim's, no LeRobot import) and its wall time."""
    from so101sim.envs import expert_frames

    start = time.perf_counter()
    frames = expert_frames(
        settings.task,
        seed,
        fps=settings.fps,
        cameras=tuple(settings.cameras),
        image_size=tuple(settings.image_size),
        randomize=settings.randomize,
        after_success_s=settings.after_success_s,
    )
    return frames, time.perf_counter() - start


def simulate_episode(settings: DatasetSettings, seed: int) -> Episode:
    """One episode of the task's expert from ``seed``."""
    return _episode(settings, *_simulate(settings, seed))


def _episode(settings: DatasetSettings, frames: Any, wall: float) -> Episode:
    return Episode(
        seed=frames.seed,
        success=frames.success,
        success_frame=frames.success_frame,
        states=frames.states,
        actions=frames.actions,
        environment_state=frames.environment_state if settings.environment_state else None,
        images=frames.images,
        randomization=jsonable(frames.randomization),
        sim_seconds=len(frames.actions) / settings.fps,
        wall_seconds=wall,
    )


def jsonable(value: Any) -> Any:
    if isinstance(value, dict):
        return {str(k): jsonable(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [jsonable(v) for v in value]
    if isinstance(value, np.ndarray):
        return value.tolist()
    if isinstance(value, np.generic):
        return value.item()
    return value


def _frames_kwargs(settings: DatasetSettings) -> dict[str, Any]:
    return {
        "fps": settings.fps,
        "cameras": tuple(settings.cameras),
        "image_size": tuple(settings.image_size),
        "randomize": settings.randomize,
        "after_success_s": settings.after_success_s,
    }


def episodes(settings: DatasetSettings, seeds: list[int]) -> Iterator[Episode]:
    """The episodes of ``seeds``, in that order, simulated by ``settings.workers`` workers
    (:func:`worker_pool`). The workers run so101sim's :func:`~so101sim.envs.run.expert_frames`
    (plain arguments); this process turns each into an :class:`Episode`."""
    from so101sim.envs import expert_frames

    kwargs = _frames_kwargs(settings)
    if settings.use_ray:
        from so101sim.envs import expert_frames_on_ray

        frames = expert_frames_on_ray(
            settings.task, seeds, address=settings.ray_address, workers=settings.workers, **kwargs
        )
        try:
            while True:
                start = time.perf_counter()
                try:
                    result = next(frames)
                except StopIteration:
                    break
                yield _episode(settings, result, time.perf_counter() - start)
        finally:
            frames.close()  # shuts down a cluster it started
        return
    if settings.workers == 1:
        for s in seeds:
            yield simulate_episode(settings, s)
        return
    ahead = 2 * settings.workers  # episodes in flight: bounds the frames held in memory
    with worker_pool(settings.workers) as pool:
        pending: list[Any] = []
        todo = iter(seeds)
        try:
            while True:
                for s in todo:
                    pending.append(pool.submit(expert_frames, settings.task, s, **kwargs))
                    if len(pending) >= ahead:
                        break
                if not pending:
                    return
                start = time.perf_counter()
                yield _episode(settings, pending.pop(0).result(), time.perf_counter() - start)
        finally:
            for fut in pending:
                fut.cancel()


__all__ = ["Episode", "episodes", "jsonable", "simulate_episode", "worker_init", "worker_pool"]
