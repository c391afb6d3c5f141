"""The stepping kernel for many models at once (:mod:`so101sim.sim.stepping` steps one):
:class:`BatchStepper` rolls a batch of models out on a pool of threads, in C
(``mujoco.rollout``), inside the exit gate, then checks every final state for divergence.
"""

from __future__ import annotations

import weakref
from collections.abc import Sequence
from concurrent.futures import ThreadPoolExecutor

import mujoco
import numpy as np
from mujoco import rollout as _rollout

from ..errors import SimulationDivergedError
from ..exitgate import mujoco_call
from ..model.loadfriction import LoadFriction, active_load_friction
from .divergence import ADVICE
from .loaded import step_loaded

_STATE = mujoco.mjtState.mjSTATE_FULLPHYSICS


class BatchStepper:
    """The stepping kernel for many models at once (a fit's parameter sets): each call steps
    every model ``nstep`` times from its state, holding its control, in C on a pool of
    ``threads`` (``mujoco.rollout``), then the divergence check on the final states. Use it as
    a context manager (the pool's threads end with the block).

    A batch with load-dependent friction (:mod:`so101sim.model.loadfriction`) is stepped with
    ``mj_step`` in a Python loop per model instead, the friction set as the stepping kernel
    sets it, on ``threads`` threads (MuJoCo lets go of Python's lock while it steps)."""

    def __init__(self, threads: int) -> None:
        self._threads = threads
        self._pool = _rollout.Rollout(nthread=threads)
        self._loop: ThreadPoolExecutor | None = None
        # per model with load friction: its time, servo torques and friction after its last step
        self._last: weakref.WeakKeyDictionary[mujoco.MjModel, tuple] = weakref.WeakKeyDictionary()

    def __enter__(self) -> BatchStepper:
        self._pool.__enter__()
        return self

    def __exit__(self, *exc: object) -> None:
        self._pool.__exit__(*exc)
        if self._loop is not None:
            self._loop.shutdown(wait=True)
            self._loop = None

    def step(
        self,
        models: Sequence[mujoco.MjModel],
        datas: Sequence[mujoco.MjData],
        states: np.ndarray,
        control: np.ndarray,
        nstep: int,
        advice: str = ADVICE,
    ) -> np.ndarray:
        """The states (FULLPHYSICS, ``(len(models), size)``) after ``nstep`` steps of each
        model from row b of ``states`` with its ``control`` row (``(len(models), 1, nu)``).

        Raises:
            SimulationDivergedError: a state is not finite; ``advice`` ends the message.
        """
        loaded = [active_load_friction(m) for m in models]
        with mujoco_call():  # refused once the interpreter exits (exitgate)
            if any(x is not None for x in loaded):
                out = self._step_loaded(models, datas, loaded, states, control, nstep)
            else:
                st, _ = self._pool.rollout(models, datas, states, control, nstep=nstep)
                out = st[:, -1, :].copy()
        dt = np.array([m.opt.timestep for m in models])
        reset = out[:, 0] < states[:, 0] + (nstep - 0.5) * dt  # MuJoCo reset a bad state
        bad = ~np.isfinite(out).all(axis=1) | reset
        if bad.any():
            raise SimulationDivergedError(
                f"the simulation of batch entry {int(np.argmax(bad))} diverged (its state not "
                f"finite, or reset by MuJoCo). {advice}"
            )
        return out

    def _step_loaded(
        self,
        models: Sequence[mujoco.MjModel],
        datas: Sequence[mujoco.MjData],
        loaded: list[LoadFriction | None],
        states: np.ndarray,
        control: np.ndarray,
        nstep: int,
    ) -> np.ndarray:
        """:meth:`step` for a batch with load friction: model b stepped on data b mod
        ``len(datas)``, one share of the batch per data, in parallel."""
        out = np.empty_like(states)

        def share(first: int) -> None:
            d = datas[first]
            for b in range(first, len(models), len(datas)):
                m = models[b]
                mujoco.mj_setState(m, d, states[b], _STATE)
                d.qacc_warmstart[:] = 0.0  # as a rollout without a warm start begins
                d.ctrl[:] = control[b, 0]
                if loaded[b] is None:
                    mujoco.mj_step(m, d, nstep=nstep)
                else:  # the torque and friction of its last step (not in a FULLPHYSICS state)
                    last = self._last.get(m)
                    if last is not None and last[0] == states[b, 0]:
                        d.actuator_force[:] = last[1]
                        d.userdata[:] = last[2]
                    else:  # not stepped here before: the torque at this state
                        mujoco.mj_forward(m, d)
                        loaded[b].update(m, d)
                    step_loaded(m, d, loaded[b], nstep)
                    self._last[m] = (float(d.time), d.actuator_force.copy(), d.userdata.copy())
                mujoco.mj_getState(m, d, out[b], _STATE)

        n = min(len(datas), len(models))
        if n == 1:
            share(0)
        else:
            if self._loop is None:
                self._loop = ThreadPoolExecutor(self._threads, thread_name_prefix="so101sim-fit")
            for job in [self._loop.submit(share, i) for i in range(n)]:
                job.result()
        return out


__all__ = ["BatchStepper"]
