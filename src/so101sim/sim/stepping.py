"""Stepping: THE stepping kernel, simulated time, observers and pacing to the wall clock.

Every MuJoCo step so101sim takes goes through one of the two entry points of this kernel,
each in blocks, in C, inside the exit gate (:mod:`so101sim.exitgate`), with one divergence
check (:func:`_check_divergence`): :func:`step_block` (every step's state recorded, through
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
import threading
import time
import weakref
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

import mujoco
import numpy as np
from mujoco import rollout as _rollout

from ..errors import SimulationDivergedError
from ..exitgate import mujoco_call
from ..model.load import arm_index
from ..validation import check_range

log = logging.getLogger(__name__)

_STATE_SPEC = mujoco.mjtState.mjSTATE_FULLPHYSICS
_ROLLOUT_MIN_STEPS = 48  # below this, a Python loop costs less than rollout's per-call setup
_DIVERGENCE_WARNINGS = (
    mujoco.mjtWarning.mjWARN_BADQACC,
    mujoco.mjtWarning.mjWARN_BADQVEL,
    mujoco.mjtWarning.mjWARN_BADQPOS,
)


def measured_radians(m: mujoco.MjModel, d: mujoco.MjData) -> np.ndarray:
    """The arm's six joint angles in radians, read from ``d.qpos``."""
    return d.qpos[arm_index(m).qpos].copy()


# ---------------------------------------------------------------------------- pacing
MAX_PLAYBACK_SPEED = 1000.0
"""The fastest playback a :class:`Pacer` accepts, in multiples of real time."""
MIN_PLAYBACK_SPEED = 1e-3
"""The slowest playback a :class:`Pacer` accepts (1/1000 of real time)."""


class Pacer:
    """Keeps simulated time in step with the wall clock, for showing a run to a person.

    Each :meth:`wait` sleeps until the absolute wall-clock deadline of the given simulated time
    (``wall0 + (sim_time - sim0) / speed``), so errors never accumulate. If the run falls more
    than ``max_lag`` seconds behind (a slow machine, a dragged window), it re-anchors instead of
    racing to catch up. ``clock`` and ``sleep`` are injectable for tests.
    """

    def __init__(
        self,
        speed: float = 1.0,
        *,
        clock: Callable[[], float] = time.perf_counter,
        sleep: Callable[[float], Any] = time.sleep,
        max_lag: float = 0.25,
    ) -> None:
        self.speed = check_range(
            speed,
            "speed",
            low=MIN_PLAYBACK_SPEED,
            high=MAX_PLAYBACK_SPEED,
            expected=(
                f"a multiple of real time from {MIN_PLAYBACK_SPEED:g} to {MAX_PLAYBACK_SPEED:g} "
                "(1 = real time, 0.5 = half speed)"
            ),
        )
        self.clock = clock
        self.sleep = sleep
        self.max_lag = max_lag
        self._anchor: tuple[float, float] | None = None
        self.lag_events = 0

    def reset(self) -> None:
        """Forget the anchor: the next :meth:`wait` starts a new timeline."""
        self._anchor = None

    def wait(self, sim_time: float) -> float:
        """Sleep until ``sim_time`` is due on the wall clock; return the seconds slept."""
        now = self.clock()
        if self._anchor is None:
            self._anchor = (now, sim_time)
            return 0.0
        wall0, sim0 = self._anchor
        delay = wall0 + (sim_time - sim0) / self.speed - now
        if delay > 0:
            self.sleep(delay)
            return delay
        if -delay > self.max_lag:
            self.lag_events += 1
            log.debug("pacing %.3f s behind the wall clock; re-anchoring", -delay)
            self._anchor = (now, sim_time)
        return 0.0


# ---------------------------------------------------------------------------- observers
@dataclass
class Trace:
    """Per-step record of stepping: the time after each step, the target applied during it and
    the joint angles after it (radians, arm joint order)."""

    time: np.ndarray  # (n,)
    ctrl: np.ndarray  # (n, 6)
    qpos: np.ndarray  # (n, 6)
    completed: bool = True
    steps: int = -1  # steps taken; -1: len(time) (a trace may keep no per-step arrays)
    # the blocks observers see: every step's whole state (FULLPHYSICS rows: time, qpos, qvel,
    # ...), as the kernel recorded it; None in the trace a run returns
    states: np.ndarray | None = None

    def __len__(self) -> int:
        return self.steps if self.steps >= 0 else len(self.time)


class Observer:
    """Something that watches a run. Override what you need; the defaults do nothing.

    * :meth:`next_time`: the simulated time of the next call to :meth:`on_time`
      (``math.inf``: none). Stepping stops at the first step that reaches it.
    * :meth:`on_time`: called with the live model and data; return False to stop the run
      (a viewer that was closed).
    * :meth:`on_steps`: each block of steps, as they are taken, with the phase's name.
    * :meth:`on_start`: once before each run of steps, with the live model and data.
    """

    def on_start(self, m: mujoco.MjModel, d: mujoco.MjData) -> None:
        return None

    def next_time(self) -> float:
        return math.inf

    def on_time(self, m: mujoco.MjModel, d: mujoco.MjData) -> bool:
        return True

    def on_steps(self, trace: Trace, phase: str) -> None:
        return None


_wall = time.perf_counter  # the real clock, even while a script's clock follows simulated time

MAX_VIEWER_PERIOD = 0.25
"""Simulated seconds between two viewer frames at most, however slowly the viewer draws."""


class ViewerObserver(Observer):
    """Syncs a viewer (anything with ``sync()`` and ``is_running()``) up to ``fps`` times per
    simulated second, paced to the wall clock by a :class:`Pacer`.

    A viewer whose ``sync()`` waits while it draws (MuJoCo's passive viewer: about 25 ms a
    frame with the full meshes on a CPU renderer) would slow the run below real time at 60
    frames a second; so the observer measures what a sync costs (a running mean) and syncs less
    often when needed: drawing then takes at most half the wall-clock time, and the run keeps
    real time (or ``speed`` times it) wherever the machine can step that fast, with fewer
    frames shown (at least one every :data:`MAX_VIEWER_PERIOD` simulated seconds)."""

    def __init__(self, viewer: Any, pacer: Pacer | None = None, fps: float = 60.0) -> None:
        self.viewer = viewer
        self.pacer = pacer if pacer is not None else Pacer()
        self.period = 1.0 / fps
        self.sync_cost = 0.0  # wall seconds a sync takes (running mean)
        self.syncs = 0
        self._next = -math.inf
        self._last = -math.inf

    def on_start(self, m: mujoco.MjModel, d: mujoco.MjData) -> None:
        if d.time < self._last:  # the clock went back (a reset): start a new timeline
            log.debug("simulated time went back to %.3f s; re-anchoring the viewer", d.time)
            self._next = -math.inf
            self.pacer.reset()

    def next_time(self) -> float:
        return self._next

    def on_time(self, m: mujoco.MjModel, d: mujoco.MjData) -> bool:
        if not self.viewer.is_running():
            return False
        self.pacer.wait(d.time)
        start = _wall()
        self.viewer.sync()
        cost = _wall() - start
        self.syncs += 1
        self.sync_cost = cost if self.syncs == 1 else 0.8 * self.sync_cost + 0.2 * cost
        period = max(self.period, min(MAX_VIEWER_PERIOD, 2.0 * self.sync_cost * self.pacer.speed))
        self._last = d.time
        self._next = d.time + period - 1e-9
        return True


# ---------------------------------------------------------------------------- stepping
_CHUNK = 4096
"""Physics steps per block at most: blocks of this size bound the memory a run needs, however
long it is (the per-step trace aside, which is kept only when asked for)."""


def _first_bad_step(states: np.ndarray, t0: float, dt: float, qpos_cols: np.ndarray) -> int | None:
    """Index of the first step of a block whose state is not a continuation of the run: time
    that went back (MuJoCo reset the data after a bad acceleration) or a NaN/inf joint angle."""
    k = len(states)
    expected = t0 + dt * np.arange(1, k + 1)
    bad = (states[:, 0] < expected - 0.5 * dt) | ~np.isfinite(states[:, qpos_cols]).all(axis=1)
    hits = np.flatnonzero(bad)
    return int(hits[0]) if hits.size else None


ADVICE = "Expected stable physics: check the model's gains, timestep and targets"
"""The end of a divergence message: what to do about it (a caller may give its own)."""


def _check_divergence(
    m: mujoco.MjModel,
    d: mujoco.MjData,
    states: np.ndarray,
    start_state: np.ndarray,
    qpos_cols: np.ndarray,
    advice: str = ADVICE,
) -> None:
    """THE divergence check of every stepping path (:func:`step_block`; :func:`advance_unobserved`
    steps a diverged block again to come here). Raise SimulationDivergedError if the block of
    ``states`` (FULLPHYSICS, one row per step) diverged, after putting ``d`` back to the last
    good state (the state when it happened); ``advice`` ends the message."""
    warned = [w for w in _DIVERGENCE_WARNINGS if d.warning[w].number > 0]
    t0, dt = float(start_state[0]), float(m.opt.timestep)
    i = _first_bad_step(states, t0, dt, qpos_cols)
    if i is None and not warned:
        return
    if i is None:  # warned without a visible jump (MuJoCo reset on the last step)
        i = len(states) - 1
    good = states[i - 1] if i > 0 else start_state
    mujoco.mj_setState(m, d, good, _STATE_SPEC)
    mujoco.mj_forward(m, d)
    when = float(good[0]) + dt
    if warned:
        w = warned[0]
        cause = (
            f"MuJoCo warned {mujoco.mjtWarning(w).name} (index {d.warning[w].lastinfo}) and "
            "would have reset the state"
        )
    else:
        cause = "the joint angles hold NaN or inf"
    for w in warned:
        d.warning[w].number = 0
    raise SimulationDivergedError(
        f"the simulation diverged at t = {when:.3f} s: {cause}; the state is left as it was "
        f"at t = {float(good[0]):.3f} s. {advice}"
    )


_local = threading.local()


def _runner() -> _rollout.Rollout:
    """This thread's rollout runner (no thread pool: it steps on the calling thread)."""
    r = getattr(_local, "runner", None)
    if r is None:
        r = _local.runner = _rollout.Rollout(nthread=0)
    return r


def _step_block(
    m: mujoco.MjModel,
    d: mujoco.MjData,
    ctrl_full: np.ndarray,
    s0: np.ndarray,
    sensordata: np.ndarray | None = None,
) -> np.ndarray:
    """Take ``len(ctrl_full)`` steps from the state ``s0`` (that of ``d``), applying row i of
    ``ctrl_full`` (all actuators) during step i; return the state after each step
    (FULLPHYSICS layout), and fill ``sensordata`` (one row per step) if given."""
    k = len(ctrl_full)
    states = np.empty((k, len(s0)))
    if k >= _ROLLOUT_MIN_STEPS:
        _runner().rollout(
            [m],
            [d],
            s0[None],
            np.ascontiguousarray(ctrl_full[None]),
            control_spec=mujoco.mjtState.mjSTATE_CTRL.value,
            skip_checks=True,
            nstep=k,
            initial_warmstart=d.qacc_warmstart[None].copy(),
            state=states[None],
            sensordata=(
                np.empty((1, k, m.nsensordata)) if sensordata is None else sensordata[None]
            ),
        )
        # rollout leaves d holding the last step's result; make ctrl match it, as a loop would.
        d.ctrl[:] = ctrl_full[-1]
    else:
        for i in range(k):
            d.ctrl[:] = ctrl_full[i]
            mujoco.mj_step(m, d)
            mujoco.mj_getState(m, d, states[i], _STATE_SPEC)
            if sensordata is not None:
                sensordata[i] = d.sensordata
    return states


def step_block(
    m: mujoco.MjModel,
    d: mujoco.MjData,
    ctrl_full: np.ndarray,
    *,
    sensordata: np.ndarray | None = None,
    scratch: np.ndarray | None = None,
    advice: str = ADVICE,
) -> np.ndarray:
    """The stepping kernel with every step recorded: ``len(ctrl_full)`` steps (at most a few
    thousand: callers cut longer runs into blocks) from ``d``'s state, applying row i of
    ``ctrl_full`` (all ``m.nu`` actuators) during step i, in C (``mujoco.rollout`` on this
    thread; a plain ``mj_step`` loop for a few steps, the same physics bit for bit), inside the
    exit gate, then the one divergence check. Returns the state after each step (FULLPHYSICS
    layout: time, qpos, qvel, ...) and fills ``sensordata`` (``(k, m.nsensordata)``) if given.
    ``d`` is left holding the last step's result.

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
        states = _step_block(m, d, ctrl_full, s0, sensordata)
        _check_divergence(m, d, states, s0, 1 + arm_index(m).qpos, advice)
    return states


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
    done = 0
    while done < n:
        k = min(n - done, _CHUNK)
        with mujoco_call():  # refused once the interpreter exits (exitgate)
            mujoco.mj_getState(m, d, s0, _STATE_SPEC)
            t0 = float(s0[0])
            at_start = t0 < dt
            warned = _warnings(d) if at_start else 0
            mujoco.mj_step(m, d, nstep=k)
        if d.time < t0 + (k - 0.5) * dt or (at_start and _warnings(d) != warned):
            mujoco.mj_setState(m, d, s0, _STATE_SPEC)
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


def _warnings(d: mujoco.MjData) -> int:
    return sum(d.warning[w].number for w in _DIVERGENCE_WARNINGS)


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
    for o in observers:
        o.on_start(m, d)
    while done < n:
        k = _block_size(observers, d.time, dt, n - done)
        if k:
            ctrl_full = np.repeat(d.ctrl[None], k, axis=0)
            ctrl_full[:, idx.actuator] = targets[done : done + k]
            states = step_block(m, d, ctrl_full, scratch=s0)
            block = Trace(
                states[:, 0], targets[done : done + k], states[:, qpos_cols], states=states
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
