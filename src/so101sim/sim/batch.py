"""The stepping kernel for many models at once (:mod:`so101sim.sim.stepping` steps one):
:class:`BatchStepper` rolls a batch of models out on a pool of threads, in C
(``mujoco.rollout``), inside the exit gate, then checks every final state for divergence.
"""

from __future__ import annotations

from collections.abc import Sequence

import mujoco
import numpy as np
from mujoco import rollout as _rollout

from ..errors import SimulationDivergedError
from ..exitgate import mujoco_call
from .divergence import ADVICE


class BatchStepper:
    """The stepping kernel for many models at once (a fit's parameter sets): each call steps
    every model ``nstep`` times from its state, holding its control, in C on a pool of
    ``threads`` (``mujoco.rollout``), then the divergence check on the final states. Use it as
    a context manager (the pool's threads end with the block)."""

    def __init__(self, threads: int) -> None:
        self._pool = _rollout.Rollout(nthread=threads)

    def __enter__(self) -> BatchStepper:
        self._pool.__enter__()
        return self

    def __exit__(self, *exc: object) -> None:
        self._pool.__exit__(*exc)

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
        with mujoco_call():  # refused once the interpreter exits (exitgate)
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


__all__ = ["BatchStepper"]
