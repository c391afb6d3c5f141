"""The stepping kernel's batched entry: N worlds (each its own ``MjModel`` and ``MjData``)
stepped together, in C, on several cores.

:class:`WorldStepper` steps world ``i`` ``n[i]`` times holding its ``d.ctrl``, as
:func:`so101sim.sim.stepping.advance_unobserved` steps one world (``mj_step(nstep)``), and
bit for bit the same physics: each world goes through ``mujoco.rollout`` on its own
``MjData``, from its whole state and warm start, so the data ends holding that world's last
step (contacts, site poses, warm start) exactly as ``mj_step`` leaves it. ``nthread`` worker
threads take a contiguous share of the worlds each; ``mujoco.rollout`` lets go of Python's
lock while it steps, so the worlds' physics runs on all the threads at once, and Python runs
once per world per call (never per physics step).

Why not one ``rollout`` call over all the worlds: its ``MjData`` are the threads' scratch
space, not the worlds' (a world's data would not end holding its own contacts and warm
start, and the next step would start from another warm start: not the physics of a single
environment, bit for bit). One call per world on that world's data keeps it exact.

Divergence is checked as :func:`~so101sim.sim.stepping.advance_unobserved` checks it (time
went back: MuJoCo reset the data); a diverged world is stepped again from its start by
:func:`~so101sim.sim.stepping.step_block`, whose check raises.
"""

from __future__ import annotations

import os
import threading
from concurrent.futures import ThreadPoolExecutor
from typing import Any

import mujoco
import numpy as np
from mujoco import rollout as _rollout

from ..errors import ClosedError
from ..exitgate import mujoco_call
from ..validation import check_count
from .stepping import ADVICE, state_size, step_block

_STATE = mujoco.mjtState.mjSTATE_FULLPHYSICS
_CTRL = mujoco.mjtState.mjSTATE_CTRL.value
MAX_THREADS = 256


def default_threads() -> int:
    """The cores this process may use (``os.sched_getaffinity``, else ``os.cpu_count``)."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except AttributeError:  # not on every platform
        return max(1, os.cpu_count() or 1)


class _World:
    """One world's buffers for its rollout call (allocated once, reused every call)."""

    def __init__(self, m: mujoco.MjModel, d: mujoco.MjData) -> None:
        self.m, self.d = m, d
        self.s0 = np.empty((1, state_size(m)))
        self.warm = np.empty((1, m.nv))
        self.n = 0
        self.ctrl = np.empty((1, 0, m.nu))
        self.states = np.empty((1, 0, state_size(m)))
        self.sensors = np.empty((1, 0, m.nsensordata))

    def buffers(self, n: int) -> None:
        if self.n != n:
            m = self.m
            self.n = n
            self.ctrl = np.empty((1, n, m.nu))
            self.states = np.empty((1, n, state_size(m)))
            self.sensors = np.empty((1, n, m.nsensordata))


class WorldStepper:
    """Steps N worlds together (see the module's text). ``models`` and ``datas``: one of each
    per world (a model may be shared); ``nthread``: worker threads (default: the cores this
    process may use; at most one per world). Close it (or use ``with``) to stop the threads.

    Raises:
        SettingError: no worlds, a different number of models and datas, or a bad ``nthread``.
    """

    def __init__(
        self,
        models: list[mujoco.MjModel],
        datas: list[mujoco.MjData],
        nthread: int | None = None,
        *,
        advice: str = ADVICE,
    ) -> None:
        n = check_count(len(datas), "number of worlds", minimum=1, maximum=1_000_000)
        check_count(len(models), "number of models", minimum=n, maximum=n)
        threads = default_threads() if nthread is None else nthread
        threads = check_count(threads, "nthread", minimum=1, maximum=MAX_THREADS)
        self.nthread = min(threads, n)
        self.advice = advice
        self._worlds = [_World(m, d) for m, d in zip(models, datas, strict=True)]
        share = -(-n // self.nthread)
        self._groups = [range(i, min(n, i + share)) for i in range(0, n, share)]
        self._local = threading.local()
        self._pool: ThreadPoolExecutor | None = (
            ThreadPoolExecutor(self.nthread, thread_name_prefix="so101sim-batch")
            if self.nthread > 1
            else None
        )
        self._closed = False

    @property
    def num_worlds(self) -> int:
        return len(self._worlds)

    def _runner(self) -> Any:
        r = getattr(self._local, "runner", None)
        if r is None:  # one runner per worker thread; it steps on the calling thread
            r = self._local.runner = _rollout.Rollout(nthread=0)
        return r

    def _step_group(self, group: range, steps: np.ndarray) -> None:
        runner = self._runner()
        for i in group:
            k = int(steps[i])
            if k <= 0:
                continue
            w = self._worlds[i]
            m, d = w.m, w.d
            w.buffers(k)
            mujoco.mj_getState(m, d, w.s0[0], _STATE)
            w.warm[0] = d.qacc_warmstart
            w.ctrl[0] = d.ctrl
            runner.rollout(
                [m],
                [d],
                w.s0,
                w.ctrl,
                control_spec=_CTRL,
                skip_checks=True,
                nstep=k,
                initial_warmstart=w.warm,
                state=w.states,
                sensordata=w.sensors,
            )

    def advance(self, steps: np.ndarray | list[int] | int) -> None:
        """Step world ``i`` ``steps[i]`` times (an int: every world that many), each holding
        its ``d.ctrl``, then check every world for divergence.

        Raises:
            SimulationDivergedError: a world's physics became unstable (the message names it
                and ends with the stepper's advice).
            ClosedError: the stepper was closed, or the interpreter is exiting.
        """
        if self._closed:
            raise ClosedError("advance() on a closed WorldStepper; expected an open one")
        counts = np.broadcast_to(np.asarray(steps, dtype=np.int64), (self.num_worlds,))
        with mujoco_call():  # refused once the interpreter exits (exitgate)
            if self._pool is None:
                self._step_group(self._groups[0], counts)
            else:
                jobs = [self._pool.submit(self._step_group, g, counts) for g in self._groups]
                for job in jobs:
                    job.result()
        for i, w in enumerate(self._worlds):
            k = int(counts[i])
            if k <= 0:
                continue
            t0 = float(w.s0[0, 0])
            if w.d.time < t0 + (k - 0.5) * w.m.opt.timestep:  # MuJoCo reset it: diverged
                mujoco.mj_setState(w.m, w.d, w.s0[0], _STATE)
                step_block(
                    w.m,
                    w.d,
                    np.repeat(w.d.ctrl[None], k, axis=0),
                    advice=f"world {i}: {self.advice}",
                )

    def close(self) -> None:
        """Stop the worker threads (harmless to repeat)."""
        self._closed = True
        if self._pool is not None:
            self._pool.shutdown(wait=True)
            self._pool = None

    def __enter__(self) -> WorldStepper:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


__all__ = ["MAX_THREADS", "WorldStepper", "default_threads"]
