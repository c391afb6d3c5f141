"""The stepping kernel's batched entry: N worlds (each its own ``MjModel`` and ``MjData``)
stepped together, in C, on several cores.

:class:`WorldStepper` steps world ``i`` ``n[i]`` times holding its ``d.ctrl``, as
:func:`so101sim.sim.stepping.advance_unobserved` steps one world (``mj_step(nstep)``), and
bit for bit the same physics: each world goes through ``mujoco.rollout`` on its own
``MjData``, from its whole state and warm start, so the data ends holding that world's last
step (contacts, site poses, warm start) exactly as ``mj_step`` leaves it. ``nthread`` threads
(the calling one and ``nthread - 1`` workers) each take the next world nobody has taken yet;
``mujoco.rollout`` lets go of Python's lock while it steps, so the worlds' physics runs on all
the threads at once, and Python runs once per world per call (never per physics step). A
caller's Python for a world (``advance(after=...)``: an environment's observation and reward)
runs on the thread that stepped it, right after, while the other threads are inside MuJoCo.

Why not one ``rollout`` call over all the worlds: its ``MjData`` are the threads' scratch
space, not the worlds' (a world's data would not end holding its own contacts and warm
start, and the next step would start from another warm start: not the physics of a single
environment, bit for bit). One call per world on that world's data keeps it exact.

Divergence is checked as :func:`~so101sim.sim.stepping.advance_unobserved` checks it (time
went back: MuJoCo reset the data); a diverged world is stepped again from its start by
:func:`~so101sim.sim.stepping.step_block`, whose check raises.
"""

from __future__ import annotations

import copy
import os
import threading
from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor
from typing import Any

import mujoco
import numpy as np
from mujoco import rollout as _rollout

from ..errors import ClosedError
from ..exitgate import mujoco_call
from ..model.loadfriction import active_load_friction, load_friction
from ..validation import check_count
from .stepping import ADVICE, state_size, step_block, step_loaded

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
        self.shares: np.ndarray | None = None  # load friction's shares before the last step
        self.n = 0
        self.ctrl = np.empty((1, 0, m.nu))

    def step(self, runner: Any, k: int) -> bool:
        """Step ``k`` times holding ``d.ctrl``; False if MuJoCo reset the data (diverged)."""
        m, d = self.m, self.d
        loaded = active_load_friction(m)
        if loaded is not None:  # the kernel's loop, the load's friction set as it goes
            t0 = d.time
            mujoco.mj_getState(m, d, self.s0[0], _STATE)
            self.shares = d.userdata.copy()  # the friction's share: not in the saved state
            step_loaded(m, d, loaded, k)
            return d.time >= t0 + (k - 0.5) * m.opt.timestep
        if self.n != k:
            self.n = k
            self.ctrl = np.empty((1, k, m.nu))
        mujoco.mj_getState(m, d, self.s0[0], _STATE)
        self.warm[0] = d.qacc_warmstart
        self.ctrl[0] = d.ctrl
        # no states or sensor values recorded: the world's data ends holding the last step
        runner.rollout(
            [m],
            [d],
            self.s0,
            self.ctrl,
            control_spec=_CTRL,
            skip_checks=True,
            nstep=k,
            initial_warmstart=self.warm,
        )
        return d.time >= self.s0[0, 0] + (k - 0.5) * m.opt.timestep


class WorldStepper:
    """Steps N worlds together (see the module's text). ``models`` and ``datas``: one of each
    per world (a model may be shared); ``nthread``: threads that step (default: the cores this
    process may use; at most one per world; the calling thread is one of them). Close it (or
    use ``with``) to stop the threads.

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
        seen: set[int] = set()
        own = []  # a model with load friction is written as it steps: one copy per world
        for m in models:
            shared = id(m) in seen and load_friction(m) is not None
            own.append(copy.copy(m) if shared else m)
            seen.add(id(m))
        self._worlds = [_World(m, d) for m, d in zip(own, datas, strict=True)]
        self._local = threading.local()
        self._pool: ThreadPoolExecutor | None = (
            ThreadPoolExecutor(self.nthread - 1, thread_name_prefix="so101sim-batch")
            if self.nthread > 1
            else None
        )
        self._closed = False

    @property
    def num_worlds(self) -> int:
        return len(self._worlds)

    def _runner(self) -> Any:
        r = getattr(self._local, "runner", None)
        if r is None:  # one runner per thread; it steps on the calling thread
            r = self._local.runner = _rollout.Rollout(nthread=0)
        return r

    def _work(self, claim: Any, counts: np.ndarray, after: Any, errors: dict) -> None:
        """Take the next world not yet taken (``claim``) until none is left: step it, check
        it, then ``after(i)`` on this thread while the other threads step theirs."""
        runner = self._runner()
        worlds = self._worlds
        for i in claim:
            try:
                k = int(counts[i])
                if k > 0 and not worlds[i].step(runner, k):
                    self._diverged(i, k)
                if after is not None:
                    after(i)
            except Exception as exc:  # raised by advance(), the lowest world first
                errors[i] = exc

    def _diverged(self, i: int, k: int) -> None:
        """World ``i`` diverged: step it again from its start by ``step_block``, whose check
        finds the last good state and raises."""
        w = self._worlds[i]
        mujoco.mj_setState(w.m, w.d, w.s0[0], _STATE)
        if w.shares is not None:
            w.d.userdata[:] = w.shares
        step_block(
            w.m, w.d, np.repeat(w.d.ctrl[None], k, axis=0), advice=f"world {i}: {self.advice}"
        )

    def advance(
        self, steps: np.ndarray | list[int] | int, after: Callable[[int], Any] | None = None
    ) -> None:
        """Step world ``i`` ``steps[i]`` times (an int: every world that many), each holding
        its ``d.ctrl``, and check every world for divergence; then ``after(i)`` (if given),
        on the thread that stepped world ``i``, right after it (while the other threads step
        other worlds): it must touch world ``i`` only. Every world is stepped and checked
        whatever another one did; the error of the lowest world that failed is raised.

        Raises:
            SimulationDivergedError: a world's physics became unstable (the message names it
                and ends with the stepper's advice).
            ClosedError: the stepper was closed, or the interpreter is exiting.
            Exception: what ``after`` raised.
        """
        if self._closed:
            raise ClosedError("advance() on a closed WorldStepper; expected an open one")
        counts = np.broadcast_to(np.asarray(steps, dtype=np.int64), (self.num_worlds,))
        # one shared iterator: each world is taken once (next() on it holds Python's lock), by
        # whichever thread is free, so the threads stay busy however uneven the worlds are;
        # the results do not depend on which thread took which world
        claim = iter(range(self.num_worlds))
        errors: dict[int, Exception] = {}
        with mujoco_call():  # refused once the interpreter exits (exitgate)
            if self._pool is None:
                self._work(claim, counts, after, errors)
            else:
                jobs = [
                    self._pool.submit(self._work, claim, counts, after, errors)
                    for _ in range(self.nthread - 1)
                ]
                try:
                    self._work(claim, counts, after, errors)
                finally:
                    for job in jobs:
                        job.result()
        if errors:
            raise errors[min(errors)]

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
