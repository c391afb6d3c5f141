"""The simulation: simulated time, stepping, and pacing to the wall clock.

Simulated time is the clock of record: a run of N steps is N * timestep seconds of simulated
time whatever the machine's speed. Stepping replays a precomputed block of targets in C
(``mujoco.rollout``), so a move costs about what ``mj_step`` costs. Wall-clock pacing exists
only to show a run to a person: :class:`Pacer` sleeps to absolute deadlines, so it does not
drift however long the run.

Anything that wants to see a run (a viewer, a video recorder, a CSV log) is an
:class:`Observer`: it names the next simulated time it wants to be called at, and/or receives
every step's commanded and measured joint angles in blocks.
"""

from __future__ import annotations

import logging
import math
import threading
import time
import weakref
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import mujoco
import numpy as np
from mujoco import rollout as _rollout

from .errors import ModelError, SettingError, SimulationDivergedError
from .model import ArmIndex, arm_index, arm_units, load_model
from .profiles import (
    MAX_MOVE_DURATION_S,
    Profile,
    duration_warning,
    get_profile,
    plan,
    steps_for,
)
from .units import JOINT_NAMES, STARTING_POSE, ArmUnits, Pose, unit_warnings
from .validation import MAX_DURATION_S, check_count, check_range

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
MAX_SPEED = 1000.0
"""The fastest playback a :class:`Pacer` accepts, in multiples of real time."""
MIN_SPEED = 1e-3
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
            low=MIN_SPEED,
            high=MAX_SPEED,
            expected=(
                f"a multiple of real time from {MIN_SPEED:g} to {MAX_SPEED:g} "
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


class ViewerObserver(Observer):
    """Syncs a viewer (anything with ``sync()`` and ``is_running()``) ``fps`` times per simulated
    second, paced to the wall clock by a :class:`Pacer`."""

    def __init__(self, viewer: Any, pacer: Pacer | None = None, fps: float = 60.0) -> None:
        self.viewer = viewer
        self.pacer = pacer if pacer is not None else Pacer()
        self.period = 1.0 / fps
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
        self.viewer.sync()
        self._last = d.time
        self._next = d.time + self.period - 1e-9
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


def _check_divergence(
    m: mujoco.MjModel,
    d: mujoco.MjData,
    states: np.ndarray,
    start_state: np.ndarray,
    qpos_cols: np.ndarray,
) -> None:
    """Raise SimulationDivergedError if the block of ``states`` (FULLPHYSICS, one row per step)
    diverged, after putting ``d`` back to the last good state (the state when it happened)."""
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
        f"at t = {float(good[0]):.3f} s. Expected stable physics: check the model's gains, "
        "timestep and targets"
    )


_local = threading.local()


def _runner() -> _rollout.Rollout:
    """This thread's rollout runner (no thread pool: it steps on the calling thread)."""
    r = getattr(_local, "runner", None)
    if r is None:
        r = _local.runner = _rollout.Rollout(nthread=0)
    return r


def _step_block(
    m: mujoco.MjModel, d: mujoco.MjData, ctrl_full: np.ndarray, s0: np.ndarray
) -> np.ndarray:
    """Take ``len(ctrl_full)`` steps from the state ``s0`` (that of ``d``), applying row i of
    ``ctrl_full`` (all actuators) during step i; return the state after each step
    (FULLPHYSICS layout)."""
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
            sensordata=np.empty((1, k, m.nsensordata)),
        )
        # rollout leaves d holding the last step's result; make ctrl match it, as a loop would.
        d.ctrl[:] = ctrl_full[-1]
    else:
        for i in range(k):
            d.ctrl[:] = ctrl_full[i]
            mujoco.mj_step(m, d)
            mujoco.mj_getState(m, d, states[i], _STATE_SPEC)
    return states


def _block_size(observers: Sequence[Observer], now: float, dt: float, left: int) -> int:
    """Steps until the first observer's next call is due (0: due now), at most one chunk."""
    t_next = min((o.next_time() for o in observers), default=math.inf)
    if t_next <= now + 1e-12:
        return 0
    if math.isinf(t_next):
        return min(left, _CHUNK)
    return min(left, _CHUNK, max(1, math.ceil((t_next - now) / dt - 1e-9)))


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
    s0 = np.empty(mujoco.mj_stateSize(m, _STATE_SPEC))
    for w in _DIVERGENCE_WARNINGS:  # MuJoCo's reset zeroes them too: count from 0 every block
        d.warning[w].number = 0
    for o in observers:
        o.on_start(m, d)
    while done < n:
        k = _block_size(observers, d.time, dt, n - done)
        if k:
            ctrl_full = np.repeat(d.ctrl[None], k, axis=0)
            ctrl_full[:, idx.actuator] = targets[done : done + k]
            mujoco.mj_getState(m, d, s0, _STATE_SPEC)
            states = _step_block(m, d, ctrl_full, s0)
            _check_divergence(m, d, states, s0, qpos_cols)
            block = Trace(states[:, 0], targets[done : done + k], states[:, qpos_cols])
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


# ---------------------------------------------------------------------------- results
@dataclass(frozen=True)
class SegmentResult:
    """What one move or hold did. Poses are dicts in the arm's units; arrays are per step."""

    phase: str
    kind: str  # "move" | "hold" | "step"
    start_time: float
    end_time: float
    steps: int
    start: dict[str, float]  # commanded pose at the start
    target: dict[str, float]  # final commanded pose
    reached: dict[str, float]  # measured pose at the end
    max_tracking_error: dict[str, float]  # max |commanded - measured| over the segment
    completed: bool
    times: np.ndarray = field(repr=False)  # (n,) simulated time after each step
    commanded: np.ndarray = field(repr=False)  # (n, 6) arm units
    measured: np.ndarray = field(repr=False)  # (n, 6) arm units

    @property
    def duration(self) -> float:
        return self.end_time - self.start_time

    @property
    def final_error(self) -> dict[str, float]:
        """|target - reached| per joint at the end of the segment."""
        return {n: abs(self.target[n] - self.reached[n]) for n in JOINT_NAMES}

    @property
    def worst_tracking_error(self) -> tuple[str, float]:
        """(joint, error) of the largest tracking error over the segment."""
        name = max(self.max_tracking_error, key=self.max_tracking_error.__getitem__)
        return name, self.max_tracking_error[name]


# ---------------------------------------------------------------------------- the object
@dataclass
class _ArmState:
    """What a :class:`Simulation` knows beyond ``MjData``: whether the arm was ever commanded
    (to tell "never commanded" from "commanded to 0"), and one viewer timeline per viewer."""

    commanded: bool = False
    viewers: weakref.WeakKeyDictionary[Any, ViewerObserver] = field(
        default_factory=weakref.WeakKeyDictionary
    )


# Handout-style code passes a bare (MjModel, MjData) to every call; Simulation.attach() wraps it,
# and this table lets successive wrappers of the same MjData share one _ArmState (it never
# holds the MjData itself, so it keeps nothing alive).
_attached: weakref.WeakKeyDictionary[mujoco.MjData, _ArmState] = weakref.WeakKeyDictionary()


class Simulation:
    """An SO-101 in MuJoCo: model, data and clock, in the arm's units.

    >>> sim = Simulation()                      # shipped model, arm in its rest pose
    >>> r = sim.move_to(ZERO_POSE, 2.0)         # 2 s of simulated time, 1000 steps
    >>> r.max_tracking_error["shoulder_lift"]   # degrees

    The simulation owns its state: the position targets (kept in ``data.ctrl``, where MuJoCo
    reads them, so a target written there directly is honoured), the observers that see every
    run (a recorder, a log), and one wall-clock timeline per viewer. ``lock`` guards the data
    for callers that share the simulation between threads.

    ``data`` (optional) is an existing ``MjData`` of ``model`` to drive instead of a new one;
    :meth:`attach` is the way for handout-style code that holds a bare ``(model, data)``.
    """

    def __init__(
        self,
        model: mujoco.MjModel | str | Path | None = None,
        *,
        data: mujoco.MjData | None = None,
        initial_pose: Pose | None = STARTING_POSE,
    ) -> None:
        self.model: mujoco.MjModel = (
            model if isinstance(model, mujoco.MjModel) else load_model(model)
        )
        if data is not None:
            _check_data(self.model, data)
        self.data = data if data is not None else mujoco.MjData(self.model)
        self.index: ArmIndex = arm_index(self.model)
        self.units: ArmUnits = arm_units(self.model)
        self.observers: list[Observer] = []
        self.lock = threading.RLock()
        self._state = _ArmState()
        self.initial_pose = dict(initial_pose) if initial_pose is not None else None
        if initial_pose is not None:
            self.set_pose(initial_pose)
        elif data is None:
            mujoco.mj_forward(self.model, self.data)

    @classmethod
    def attach(cls, model: mujoco.MjModel, data: mujoco.MjData) -> Simulation:
        """A Simulation driving an existing ``(model, data)`` as it is (nothing is reset or
        moved). Every Simulation attached to the same ``data`` shares its commanded-target
        state and viewer timelines, so the lab's ``(m, d)`` helpers can be called one after
        another as thin wrappers."""
        sim = cls(model, data=data, initial_pose=None)
        state = _attached.get(data)
        if state is None:
            state = _attached[data] = _ArmState(commanded=bool(data.ctrl.any()))
        sim._state = state
        return sim

    # -- clock
    @property
    def time(self) -> float:
        """Simulated time in seconds."""
        return float(self.data.time)

    @property
    def timestep(self) -> float:
        """The physics timestep in seconds (0.002 for the shipped model)."""
        return float(self.model.opt.timestep)

    # -- state in the arm's units
    def pose(self) -> dict[str, float]:
        """The measured pose: body joints in degrees, gripper 0–100."""
        return self.units.array_to_pose(self.pose_array())

    def pose_array(self) -> np.ndarray:
        """The measured pose as an array in arm units."""
        return self.units.from_radians(self.data.qpos[self.index.qpos])

    def commanded(self) -> dict[str, float]:
        """The last commanded target (the measured pose before any command), rounded to 1e-9
        so that a commanded 60 reads 60, not 59.99999999999999 after the trip through radians."""
        return self.units.array_to_pose(np.round(self.commanded_array(), 9) + 0.0)

    def commanded_array(self) -> np.ndarray:
        """The position targets in arm units, read from ``data.ctrl``; the measured pose if the
        arm was never commanded (targets untouched since the data was made)."""
        q = self.data.ctrl[self.index.actuator]
        if not self._state.commanded and not q.any():
            return self.pose_array()
        return self.units.from_radians(q)

    @property
    def was_commanded(self) -> bool:
        """Whether a target was ever set (through so101sim or written to ``data.ctrl``)."""
        return self._state.commanded or bool(self.data.ctrl[self.index.actuator].any())

    def limits(self) -> dict[str, tuple[float, float]]:
        """Joint name -> (lower, upper) in the arm's units."""
        return self.units.limits_dict()

    def set_pose(self, pose: Pose, *, clip: bool = False) -> None:
        """Place the arm at ``pose`` at rest (velocities zero) and command it to stay there."""
        values = self.units.pose_to_array(pose, clip=clip)
        q = self.units.to_radians(values)
        with self.lock:
            self.data.qpos[self.index.qpos] = q
            self.data.qvel[self.index.dof] = 0.0
            self._set_target(q)
            mujoco.mj_forward(self.model, self.data)

    def command(self, pose: Pose, *, clip: bool = False) -> dict[str, float]:
        """Set the position targets; joints left out keep their last target. Returns the full
        target that is now commanded (arm units)."""
        values = self.units.pose_to_array(pose, base=self.commanded_array(), clip=clip)
        self.command_array(values, check=False)
        return self.units.array_to_pose(values)

    def command_array(self, values: np.ndarray, *, check: bool = True) -> None:
        """Set all six position targets from an array in arm units (JOINT_NAMES order).

        With ``check`` (the default) the values are checked against the joint limits first
        (:class:`~so101sim.errors.JointLimitError`); pass ``check=False`` only for values
        already validated."""
        v = np.asarray(values, dtype=float)
        if check:
            v = self.units.check_limits(v)
        with self.lock:
            self._set_target(self.units.to_radians(v))

    def _set_target(self, q: np.ndarray) -> None:
        self.data.ctrl[self.index.actuator] = q
        self._state.commanded = True

    def reset(self) -> None:
        """Back to time 0 at the initial pose."""
        with self.lock:
            mujoco.mj_resetData(self.model, self.data)
            self._state.commanded = False
        if self.initial_pose is not None:
            self.set_pose(self.initial_pose)

    # -- observers
    def viewer_observer(self, viewer: Any) -> Observer:
        """The one :class:`ViewerObserver` of ``viewer`` for this simulation, so that
        successive moves and holds on the same viewer share one wall-clock timeline (no pause,
        no catch-up between them). A viewer that is itself an :class:`Observer` (a recorder
        standing in for the viewer) is used as it is.

        Raises:
            SettingError: ``viewer`` has no ``sync()`` and ``is_running()``.
        """
        if isinstance(viewer, Observer):
            return viewer
        missing = [a for a in ("sync", "is_running") if not callable(getattr(viewer, a, None))]
        if missing:
            raise SettingError(
                f"viewer = {viewer!r} has no {' or '.join(f'{a}()' for a in missing)}; expected "
                "None (headless), mujoco.viewer.launch_passive(m, d) or so101sim.record(...)"
            )
        obs = self._state.viewers.get(viewer)
        if obs is None:
            obs = self._state.viewers[viewer] = ViewerObserver(viewer)
        return obs

    def _observers(self, viewer: Any, extra: Sequence[Observer]) -> list[Observer]:
        obs = [*self.observers, *extra]
        if viewer is not None:
            obs.append(self.viewer_observer(viewer))
        return obs

    # -- stepping
    def advance(
        self,
        targets: np.ndarray,
        *,
        viewer: Any = None,
        observers: Sequence[Observer] = (),
        phase: str = "",
        keep_trace: bool = True,
    ) -> Trace:
        """Step ``len(targets)`` times, commanding row i of ``targets`` (arm units, shape
        ``(n, 6)``) during step i; every observer sees the run. The returned :class:`Trace`
        holds per-step arrays only with ``keep_trace``."""
        q = self.units.to_radians(np.asarray(targets, dtype=float).reshape(-1, len(JOINT_NAMES)))
        with self.lock:
            if len(q):
                self._state.commanded = True
            obs = self._observers(viewer, observers)
            return advance(self.model, self.data, q, obs, phase, keep_trace=keep_trace)

    def step(
        self,
        n: int = 1,
        *,
        viewer: Any = None,
        observers: Sequence[Observer] = (),
        trace: bool | None = None,
    ) -> Trace:
        """Take ``n`` physics steps holding the current target. The :class:`Trace` keeps
        per-step arrays when ``trace`` is True, or (None) when ``n`` is at most
        :data:`TRACE_AUTO_STEPS`."""
        n = check_count(n, "n", unit=" steps", maximum=round(MAX_DURATION_S / self.timestep))
        target = self.commanded_array()
        return self.advance(
            np.broadcast_to(target, (n, len(target))),
            viewer=viewer,
            observers=observers,
            phase="step",
            keep_trace=_keep(trace, n),
        )

    def plan_move(
        self,
        target: Pose,
        duration: float,
        *,
        profile: str | Profile = "linear",
        clip: bool = False,
    ) -> tuple[np.ndarray, np.ndarray]:
        """Validate a move and compute all its targets: ``(start, targets)`` in arm units.
        Nothing moves.

        Raises:
            JointNameError, JointValueError, JointLimitError, DurationError, SettingError.
        """
        goal = self.units.pose_to_array(target, clip=clip)
        n = steps_for(duration, self.timestep, maximum=MAX_MOVE_DURATION_S)
        for warning in unit_warnings(goal):
            log.warning("%s", warning)
        if (w := duration_warning(float(duration), "move duration")) is not None:
            log.warning("%s", w)
        prof = get_profile(profile, self.units)
        start = self.commanded_array()
        return start, plan(start, goal, n, self.timestep, prof)

    def move_to(
        self,
        target: Pose,
        duration: float,
        *,
        viewer: Any = None,
        observers: Sequence[Observer] = (),
        profile: str | Profile = "linear",
        clip: bool = False,
        phase: str = "move",
        trace: bool | None = None,
    ) -> SegmentResult:
        """Move from the last commanded target to ``target`` in ``duration`` s of simulated time.

        Returns a :class:`SegmentResult` (commanded and reached pose, largest tracking error per
        joint; per-step arrays when ``trace`` is True, or None and the move is at most
        :data:`TRACE_AUTO_STEPS` steps). Nothing moves if the target, duration or profile is
        invalid.
        """
        with self.lock:
            start, targets = self.plan_move(target, duration, profile=profile, clip=clip)
            return self._segment("move", phase, start, targets, viewer, observers, trace)

    def hold(
        self,
        duration: float,
        *,
        viewer: Any = None,
        observers: Sequence[Observer] = (),
        phase: str = "hold",
        trace: bool | None = None,
    ) -> SegmentResult:
        """Hold the last commanded target (the measured pose, before any command) for
        ``duration`` s of simulated time (per-step arrays in the result as for
        :meth:`move_to`). Memory stays flat however long the hold, unless the trace is kept."""
        n = steps_for(duration, self.timestep)
        if (w := duration_warning(float(duration), "hold duration")) is not None:
            log.warning("%s", w)
        with self.lock:
            start = self.commanded_array()
            targets = np.broadcast_to(start, (n, len(start)))
            return self._segment("hold", phase, start, targets, viewer, observers, trace)

    def _segment(
        self,
        kind: str,
        phase: str,
        start: np.ndarray,
        targets: np.ndarray,
        viewer: Any,
        observers: Sequence[Observer],
        trace: bool | None,
    ) -> SegmentResult:
        t0 = self.time
        keep = _keep(trace, len(targets))
        errors = _ErrorTracker(self.units, start)
        tr = self.advance(
            targets, viewer=viewer, observers=[*observers, errors], phase=phase, keep_trace=keep
        )
        empty = np.empty((0, len(start)))
        return SegmentResult(
            phase=phase,
            kind=kind,
            start_time=t0,
            end_time=self.time,
            steps=len(tr),
            start=self.units.array_to_pose(start),
            target=self.units.array_to_pose(errors.last),
            reached=self.pose(),
            max_tracking_error=self.units.array_to_pose(errors.max),
            completed=tr.completed,
            times=tr.time.copy(),
            commanded=self.units.from_radians(tr.ctrl) if keep else empty,
            measured=self.units.from_radians(tr.qpos) if keep else empty,
        )


TRACE_AUTO_STEPS = 60_000
"""Segments of at most this many steps (two minutes at 2 ms) keep their per-step trace unless
told otherwise; longer ones keep only their summary, so memory stays flat."""


def _keep(trace: bool | None, n: int) -> bool:
    return n <= TRACE_AUTO_STEPS if trace is None else bool(trace)


class _ErrorTracker(Observer):
    """The largest |commanded - measured| per joint (arm units) and the last commanded target,
    computed block by block, so a segment needs no per-step arrays for its summary."""

    def __init__(self, units: ArmUnits, start: np.ndarray) -> None:
        self.units = units
        self.max = np.zeros(len(start))
        self.last = np.asarray(start, dtype=float)

    def on_steps(self, trace: Trace, phase: str) -> None:
        commanded = self.units.from_radians(trace.ctrl)
        measured = self.units.from_radians(trace.qpos)
        self.max = np.maximum(self.max, np.abs(commanded - measured).max(axis=0))
        self.last = commanded[-1]


def _check_data(model: mujoco.MjModel, data: mujoco.MjData) -> None:
    """Raise ModelError if ``data`` was not made for ``model`` (their sizes differ)."""
    sizes = ("nq", "nv", "nu", "na", "nbody")
    if any(getattr(data.model, s) != getattr(model, s) for s in sizes):
        raise ModelError(
            "the MjData was made for another model (nq/nv/nu/nbody differ); expected "
            "mujoco.MjData(model) of the same model"
        )
