"""Stepping: THE stepping kernel and simulated time (its observers and the pacing to the wall
clock live in :mod:`.observers`, and are importable from here too).

Every MuJoCo step so101sim takes goes through one of the two entry points of this kernel,
each in blocks, in C, inside the exit gate (:mod:`so101sim.exitgate`), with one divergence
check (:mod:`.divergence`): :func:`step_block` (every step's state recorded, through
``mujoco.rollout``: the simulation's :func:`advance`, the robust preflight's rollouts) and
:func:`advance_unobserved` (nothing recorded, ``mj_step(nstep)``: a lockstep robot, an environment's
step, the pose finder, ``Simulation.step`` with nothing watching).

Simulated time is the clock of record: a run of N steps is N * timestep seconds of simulated
time whatever the machine's speed. :func:`advance` replays a precomputed block of targets in C
(``mujoco.rollout``), in blocks of at most a few thousand steps, so a move costs about what
``mj_step`` costs and memory stays bounded however long the run. Wall-clock pacing exists only
to show a run to a person: :class:`Pacer` sleeps to absolute deadlines, so it does not drift
however long the run.

Anything that wants to see a run (a viewer, a video recorder, a CSV log) is an
:class:`Observer`: it names the next simulated time it wants to be called at, and/or receives
every step's commanded and measured joint angles in blocks.

:class:`so101sim.sim.simulation.Simulation` is built on this module; most code uses it instead.
"""

from __future__ import annotations

import logging
import math
import weakref
from collections.abc import Sequence

import mujoco
import numpy as np

from ..errors import ModelError, SimulationDivergedError
from ..exitgate import mujoco_call
from ..model.load import arm_index
from ..model.loadfriction import active_load_friction
from ..model.twin import contact_twin
from .batch import BatchStepper  # the kernel for many models at once, importable from here
from .blocks import ROLLOUT_MIN_STEPS as _ROLLOUT_MIN_STEPS  # the rows of a block, in C or a loop
from .blocks import step_rows as _step_block
from .blocks import step_rows_on_twin as _step_twin
from .divergence import _DIVERGENCE_WARNINGS, _STATE_SPEC, ADVICE, _check_divergence, _warnings
from .loaded import step_loaded  # the kernel's steps of a model with load friction
from .observers import (  # the kernel's observers, importable from here as before
    MAX_PLAYBACK_SPEED,
    MAX_VIEWER_PERIOD,
    MIN_PLAYBACK_SPEED,
    Observer,
    Pacer,
    Trace,
    ViewerObserver,
)

log = logging.getLogger(__name__)


def measured_radians(m: mujoco.MjModel, d: mujoco.MjData) -> np.ndarray:
    """The arm's six joint angles in radians, read from ``d.qpos``."""
    return d.qpos[arm_index(m).qpos].copy()


# ---------------------------------------------------------------------------- stepping
_CHUNK = 4096
"""Physics steps per block at most: blocks of this size bound the memory a run needs, however
long it is (the per-step trace aside, which is kept only when asked for)."""


def step_block(
    m: mujoco.MjModel,
    d: mujoco.MjData,
    ctrl_full: np.ndarray,
    *,
    sensordata: np.ndarray | None = None,
    scratch: np.ndarray | None = None,
    advice: str = ADVICE,
    contact_counts: np.ndarray | None = None,
    actuator_forces: np.ndarray | None = None,
) -> np.ndarray:
    """The stepping kernel with every step recorded: ``len(ctrl_full)`` steps (at most a few
    thousand: callers cut longer runs into blocks) from ``d``'s state, applying row i of
    ``ctrl_full`` (all ``m.nu`` actuators) during step i, in C (``mujoco.rollout`` on this
    thread; a plain ``mj_step`` loop for a few steps, the same physics bit for bit), inside the
    exit gate, then the one divergence check. Returns the state after each step (FULLPHYSICS
    layout: time, qpos, qvel, ...) and fills ``sensordata`` (``(k, m.nsensordata)``) if given.
    ``d`` is left holding the last step's result.

    ``contact_counts`` (``(k,)``), if given, is filled with each step's contact count (the
    contacts MuJoCo found before integrating): a long block is then stepped on the model's
    contact twin (:mod:`so101sim.model.twin`, the same physics with a contact sensor); where
    the model has none, it is filled with -1 (not recorded). Not with ``sensordata``. With
    it, ``actuator_forces`` (``(k, m.nu)``), if given, is filled with the force each actuator
    applied during each step (``d.actuator_force``; the twin's ``actuatorfrc`` sensors), except
    where the counts are -1.

    Raises:
        SimulationDivergedError: MuJoCo reported an unstable state, or the state is not finite;
            ``d`` is left in the last good state. The message ends with ``advice``.
        ClosedError: the interpreter is exiting (:mod:`so101sim.exitgate`).
    """
    s0 = scratch if scratch is not None else np.empty(state_size(m))
    for w in _DIVERGENCE_WARNINGS:  # MuJoCo's reset zeroes them too: count from 0 every block
        d.warning[w].number = 0
    with mujoco_call():  # refused once the interpreter exits (exitgate)
        mujoco.mj_getState(m, d, s0, _STATE_SPEC)
        loaded = active_load_friction(m)
        if loaded is not None:  # a Python loop: the load's friction set as it goes
            states = _step_block(m, d, ctrl_full, s0, sensordata, contact_counts,
                                 actuator_forces, loaded)  # fmt: skip
        elif contact_counts is None:
            states = _step_block(m, d, ctrl_full, s0, sensordata)
        elif len(ctrl_full) < _ROLLOUT_MIN_STEPS:  # a Python loop: d.ncon after each step
            states = _step_block(m, d, ctrl_full, s0, None, contact_counts, actuator_forces)
        else:
            twin = contact_twin(m)
            if twin is None:
                contact_counts[:] = -1
                states = _step_block(m, d, ctrl_full, s0, None)
            else:
                states = _step_twin(m, d, twin, ctrl_full, s0, contact_counts, actuator_forces)
        try:
            _check_divergence(m, d, states, s0, _watched_qpos(m), advice)
        except SimulationDivergedError:
            if loaded is not None:  # the share of the last good state (the block's may be NaN)
                loaded.update(m, d)
            raise
    return states


def _watched_qpos(m: mujoco.MjModel) -> np.ndarray:
    """The state columns the divergence check reads: the arm's joint angles, or every ``qpos``
    of a model that is not an SO-101 (the servo bench)."""
    try:
        return 1 + arm_index(m).qpos
    except ModelError:
        return 1 + np.arange(m.nq)


def _block_size(observers: Sequence[Observer], now: float, dt: float, left: int) -> int:
    """Steps until the first observer's next call is due (0: due now), at most one chunk."""
    t_next = min((o.next_time() for o in observers), default=math.inf)
    if t_next <= now + 1e-12:
        return 0
    if math.isinf(t_next):
        return min(left, _CHUNK)
    return min(left, _CHUNK, max(1, math.ceil((t_next - now) / dt - 1e-9)))


def advance_unobserved(
    m: mujoco.MjModel,
    d: mujoco.MjData,
    target: np.ndarray | None,
    n: int,
    dt: float = 0.0,
    scratch: np.ndarray | None = None,
    *,
    advice: str = ADVICE,
) -> int:
    """The stepping kernel with nothing recorded: step ``n`` times commanding ``target``
    (radians, arm joint order; None: the targets in ``d.ctrl``, all actuators held), in
    MuJoCo's own loop (``mj_step(nstep=k)``, the same physics bit for bit as
    :func:`step_block`), blocks of at most :data:`_CHUNK` steps, each inside the exit gate.
    Kept lean (a lockstep robot calls it for every action): it reads back only the time.
    ``dt``: the model's timestep if the caller has it; ``scratch``: a buffer of
    :func:`state_size` floats the caller keeps for it. Returns ``n``.

    Divergence: MuJoCo checks every step's positions, velocities and accelerations and resets
    the data when one is bad (not finite, or beyond ``mjMAXVAL``), so a block diverged when its
    time went back; only at time 0 (a reset looks like the start) are the warnings read too.
    The block is then stepped again from its start by :func:`step_block`, whose divergence
    check (the only one) finds the last good state and raises.

    Raises:
        SimulationDivergedError: as :func:`step_block` (the message ends with ``advice``).
        ClosedError: the interpreter is exiting (:mod:`so101sim.exitgate`).
    """
    if target is not None:
        d.ctrl[arm_index(m).actuator] = target
    s0 = scratch if scratch is not None else np.empty(state_size(m))
    dt = dt or m.opt.timestep
    loaded = active_load_friction(m)
    done = 0
    while done < n:
        k = min(n - done, _CHUNK)
        with mujoco_call():  # refused once the interpreter exits (exitgate)
            mujoco.mj_getState(m, d, s0, _STATE_SPEC)
            t0 = float(s0[0])
            at_start = t0 < dt
            warned = _warnings(d) if at_start else 0
            if loaded is None:
                mujoco.mj_step(m, d, nstep=k)
            else:  # its friction's share is in userdata, not in the saved state
                shares = d.userdata.copy()
                step_loaded(m, d, loaded, k)
        if d.time < t0 + (k - 0.5) * dt or (at_start and _warnings(d) != warned):
            mujoco.mj_setState(m, d, s0, _STATE_SPEC)
            if loaded is not None:
                d.userdata[:] = shares
            step_block(m, d, np.repeat(d.ctrl[None], k, axis=0), advice=advice)
        done += k
    return n


_state_sizes: weakref.WeakKeyDictionary[mujoco.MjModel, int] = weakref.WeakKeyDictionary()


def state_size(m: mujoco.MjModel) -> int:
    """``mj_stateSize`` of the saved state, looked up once per model."""
    size = _state_sizes.get(m)
    if size is None:
        size = _state_sizes[m] = mujoco.mj_stateSize(m, _STATE_SPEC)
    return size


def advance(
    m: mujoco.MjModel,
    d: mujoco.MjData,
    targets: np.ndarray,
    observers: Sequence[Observer] = (),
    phase: str = "",
    *,
    keep_trace: bool = True,
) -> Trace:
    """Step ``len(targets)`` times, commanding row i of ``targets`` (radians, arm joint order)
    during step i. Observers are called at the simulated times they ask for, and see every
    step in blocks of at most a few thousand steps.

    Returns the per-step :class:`Trace` (empty arrays unless ``keep_trace``; its length is the
    steps taken either way); ``completed`` is False if an observer stopped the run.

    Raises:
        SimulationDivergedError: MuJoCo reported an unstable state, or the state is not finite;
            ``d`` is left in the last good state.
        ClosedError: the interpreter is exiting (:mod:`so101sim.exitgate`).
    """
    idx = arm_index(m)
    targets = np.asarray(targets, dtype=float).reshape(-1, len(idx.actuator))
    n = len(targets)
    qpos_cols = 1 + idx.qpos  # FULLPHYSICS state: [time, qpos..., qvel..., ...]
    kept = n if keep_trace else 0
    times, qpos = np.empty(kept), np.empty((kept, len(idx.qpos)))
    dt = m.opt.timestep
    done = 0
    completed = True
    s0 = np.empty(state_size(m))
    counting = any(getattr(o, "wants_contact_counts", False) for o in observers)
    for o in observers:
        o.on_start(m, d)
    while done < n:
        k = _block_size(observers, d.time, dt, n - done)
        if k:
            ctrl_full = np.repeat(d.ctrl[None], k, axis=0)
            ctrl_full[:, idx.actuator] = targets[done : done + k]
            counts = np.empty(k) if counting else None
            forces = np.empty((k, m.nu)) if counting else None
            states = step_block(
                m, d, ctrl_full, scratch=s0, contact_counts=counts, actuator_forces=forces
            )
            if counts is not None and k and counts[0] < 0:
                counts = forces = None  # no contact twin: not recorded
            block = Trace(
                states[:, 0],
                targets[done : done + k],
                states[:, qpos_cols],
                states=states,
                contact_counts=counts,
                actuator_forces=forces,
            )
            if keep_trace:
                times[done : done + k] = block.time
                qpos[done : done + k] = block.qpos
            done += k
            for o in observers:
                o.on_steps(block, phase)
        for o in observers:
            if o.next_time() <= d.time + 1e-12 and o.on_time(m, d) is False:
                completed = False
        if not completed:
            break
    if keep_trace:
        return Trace(times[:done], targets[:done], qpos[:done], completed, done)
    return Trace(times, targets[:0], qpos, completed, done)


__all__ = [
    "ADVICE",
    "MAX_PLAYBACK_SPEED",
    "MAX_VIEWER_PERIOD",
    "MIN_PLAYBACK_SPEED",
    "BatchStepper",
    "Observer",
    "Pacer",
    "Trace",
    "ViewerObserver",
    "advance",
    "advance_unobserved",
    "measured_radians",
    "state_size",
    "step_block",
    "step_loaded",
]
