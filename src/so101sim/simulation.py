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
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import mujoco
import numpy as np
from mujoco import rollout as _rollout

from .errors import SettingError, SimulationDivergedError
from .model import ArmIndex, arm_index, arm_units, load_model
from .units import STARTING_POSE, ArmUnits, Pose

if TYPE_CHECKING:
    from .motion import SegmentResult

log = logging.getLogger(__name__)

_STATE_SPEC = mujoco.mjtState.mjSTATE_FULLPHYSICS
_ROLLOUT_MIN_STEPS = 48  # below this, a Python loop costs less than rollout's per-call setup
_DIVERGENCE_WARNINGS = (
    mujoco.mjtWarning.mjWARN_BADQACC,
    mujoco.mjtWarning.mjWARN_BADQVEL,
    mujoco.mjtWarning.mjWARN_BADQPOS,
)


# ---------------------------------------------------------------------------- commanded target
# The position targets live in d.ctrl, where MuJoCo reads them, so that a target written there
# directly (as the handout's own helpers do) is honoured. This set only records which MjData
# have been commanded through so101sim, to tell "never commanded" from "commanded to 0".
_commanded: weakref.WeakSet[mujoco.MjData] = weakref.WeakSet()


def commanded_target(d: mujoco.MjData) -> np.ndarray | None:
    """The arm's current position targets (radians, arm joint order), read from ``d.ctrl``;
    None if nothing was ever commanded (targets untouched since the data was made)."""
    q = d.ctrl[arm_index(d.model).actuator]
    if d not in _commanded and not q.any():
        return None
    return q.copy()


def set_commanded_target(m: mujoco.MjModel, d: mujoco.MjData, q: np.ndarray) -> None:
    """Command the arm's position actuators to ``q`` (radians, arm joint order)."""
    d.ctrl[arm_index(m).actuator] = q
    _commanded.add(d)


def measured_radians(m: mujoco.MjModel, d: mujoco.MjData) -> np.ndarray:
    """The arm's six joint angles in radians, read from ``d.qpos``."""
    return d.qpos[arm_index(m).qpos].copy()


# ---------------------------------------------------------------------------- pacing
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
        if (
            isinstance(speed, bool)
            or not isinstance(speed, int | float)
            or not (math.isfinite(speed) and speed > 0)
        ):
            raise SettingError(
                f"speed = {speed!r} is invalid; expected a finite multiple of real time > 0 "
                "(1 = real time, 0.5 = half speed)"
            )
        self.speed = speed
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

    @classmethod
    def empty(cls) -> Trace:
        return cls(np.empty(0), np.empty((0, 6)), np.empty((0, 6)))

    def __len__(self) -> int:
        return len(self.time)


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


_viewer_observers: weakref.WeakKeyDictionary[Any, ViewerObserver] = weakref.WeakKeyDictionary()


def viewer_observer(viewer: Any) -> ViewerObserver:
    """The one :class:`ViewerObserver` of ``viewer``, so that successive moves and holds on the
    same viewer share one wall-clock timeline (no pause, no catch-up between them)."""
    obs = _viewer_observers.get(viewer)
    if obs is None:
        obs = ViewerObserver(viewer)
        _viewer_observers[viewer] = obs
    return obs


# ---------------------------------------------------------------------------- stepping
def _check_divergence(
    m: mujoco.MjModel, d: mujoco.MjData, before: list[int], qpos: np.ndarray
) -> None:
    for w, n0 in zip(_DIVERGENCE_WARNINGS, before, strict=True):
        info = d.warning[w]
        if info.number > n0:
            raise SimulationDivergedError(
                f"the simulation diverged at t = {d.time:.3f} s: MuJoCo warned "
                f"{mujoco.mjtWarning(w).name} (index {info.lastinfo}) and reset the state; "
                "expected stable physics: check the model's gains, timestep and targets"
            )
    if not np.all(np.isfinite(qpos)):
        raise SimulationDivergedError(
            f"the simulation diverged at t = {d.time:.3f} s: the joint angles hold NaN or inf; "
            "expected finite state: check the model's gains, timestep and targets"
        )


_local = threading.local()


def _runner() -> _rollout.Rollout:
    """This thread's rollout runner (no thread pool: it steps on the calling thread)."""
    r = getattr(_local, "runner", None)
    if r is None:
        r = _local.runner = _rollout.Rollout(nthread=0)
    return r


def _step_block(m: mujoco.MjModel, d: mujoco.MjData, ctrl_full: np.ndarray) -> np.ndarray:
    """Take ``len(ctrl_full)`` steps, applying row i of ``ctrl_full`` (all actuators) during step
    i; return the state after each step (FULLPHYSICS layout)."""
    k = len(ctrl_full)
    nstate = mujoco.mj_stateSize(m, _STATE_SPEC)
    states = np.empty((k, nstate))
    if k >= _ROLLOUT_MIN_STEPS:
        s0 = np.empty((1, nstate))
        mujoco.mj_getState(m, d, s0[0], _STATE_SPEC)
        _runner().rollout(
            [m],
            [d],
            s0,
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


def advance(
    m: mujoco.MjModel,
    d: mujoco.MjData,
    targets: np.ndarray,
    observers: Sequence[Observer] = (),
    phase: str = "",
) -> Trace:
    """Step ``len(targets)`` times, commanding row i of ``targets`` (radians, arm joint order)
    during step i. Observers are called at the simulated times they ask for.

    Returns the per-step :class:`Trace`; ``completed`` is False if an observer stopped the run.

    Raises:
        SimulationDivergedError: MuJoCo reported an unstable state, or the state is not finite.
    """
    idx = arm_index(m)
    targets = np.asarray(targets, dtype=float).reshape(-1, len(idx.actuator))
    n = len(targets)
    ctrl_full = np.repeat(d.ctrl[None], n, axis=0)
    ctrl_full[:, idx.actuator] = targets
    qpos_cols = 1 + idx.qpos  # FULLPHYSICS state: [time, qpos..., qvel..., ...]
    times = np.empty(n)
    qpos = np.empty((n, len(idx.qpos)))
    dt = m.opt.timestep
    done = 0
    completed = True
    warn_before = [d.warning[w].number for w in _DIVERGENCE_WARNINGS]
    for o in observers:
        o.on_start(m, d)
    while done < n:
        t_next = min((o.next_time() for o in observers), default=math.inf)
        if t_next <= d.time + 1e-12:
            k = 0
        elif math.isinf(t_next):
            k = n - done
        else:
            k = min(n - done, max(1, math.ceil((t_next - d.time) / dt - 1e-9)))
        if k:
            states = _step_block(m, d, ctrl_full[done : done + k])
            times[done : done + k] = states[:, 0]
            qpos[done : done + k] = states[:, qpos_cols]
            _check_divergence(m, d, warn_before, qpos[done : done + k])
            block = Trace(times[done : done + k], targets[done : done + k], qpos[done : done + k])
            done += k
            for o in observers:
                o.on_steps(block, phase)
        for o in observers:
            if o.next_time() <= d.time + 1e-12 and o.on_time(m, d) is False:
                completed = False
        if not completed:
            break
    if done:
        _commanded.add(d)
    return Trace(times[:done], targets[:done], qpos[:done], completed)


# ---------------------------------------------------------------------------- the object
class Simulation:
    """An SO-101 in MuJoCo: model, data and clock, in the arm's units.

    >>> sim = Simulation()                      # shipped model, arm in its rest pose
    >>> r = sim.move_to(ZERO_POSE, 2.0)         # 2 s of simulated time, 1000 steps
    >>> r.max_tracking_error["shoulder_lift"]   # degrees

    ``observers`` (a viewer, a recorder, a log) see every run; ``lock`` guards the data for
    callers that share the simulation between threads.
    """

    def __init__(
        self,
        model: mujoco.MjModel | str | Path | None = None,
        *,
        initial_pose: Pose | None = STARTING_POSE,
    ) -> None:
        self.model: mujoco.MjModel = (
            model if isinstance(model, mujoco.MjModel) else load_model(model)
        )
        self.data = mujoco.MjData(self.model)
        self.index: ArmIndex = arm_index(self.model)
        self.units: ArmUnits = arm_units(self.model)
        self.observers: list[Observer] = []
        self.lock = threading.RLock()
        self.initial_pose = dict(initial_pose) if initial_pose is not None else None
        if initial_pose is not None:
            self.set_pose(initial_pose)
        else:
            mujoco.mj_forward(self.model, self.data)

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
        return self.units.from_radians(measured_radians(self.model, self.data))

    def commanded(self) -> dict[str, float]:
        """The last commanded target (the measured pose before any command), rounded to 1e-9
        so that a commanded 60 reads 60, not 59.99999999999999 after the trip through radians."""
        return self.units.array_to_pose(np.round(self.commanded_array(), 9) + 0.0)

    def commanded_array(self) -> np.ndarray:
        q = commanded_target(self.data)
        if q is None:
            return self.pose_array()
        return self.units.from_radians(q)

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
            set_commanded_target(self.model, self.data, q)
            mujoco.mj_forward(self.model, self.data)

    def command(self, pose: Pose, *, clip: bool = False) -> dict[str, float]:
        """Set the position targets; joints left out keep their last target. Returns the full
        target that is now commanded (arm units)."""
        values = self.units.pose_to_array(pose, base=self.commanded_array(), clip=clip)
        with self.lock:
            set_commanded_target(self.model, self.data, self.units.to_radians(values))
        return self.units.array_to_pose(values)

    def reset(self) -> None:
        """Back to time 0 at the initial pose."""
        with self.lock:
            mujoco.mj_resetData(self.model, self.data)
            _commanded.discard(self.data)
        if self.initial_pose is not None:
            self.set_pose(self.initial_pose)

    # -- stepping
    def step(self, n: int = 1, *, viewer: Any = None) -> Trace:
        """Take ``n`` physics steps holding the current target."""
        if isinstance(n, bool) or not isinstance(n, int | np.integer) or n < 0:
            raise SettingError(f"n = {n!r} is invalid; expected a whole number of steps >= 0")
        target = self.units.to_radians(self.commanded_array())
        with self.lock:
            return advance(
                self.model,
                self.data,
                np.repeat(target[None], n, axis=0),
                self._observers(viewer),
                "step",
            )

    def _observers(self, viewer: Any) -> list[Observer]:
        obs = list(self.observers)
        if viewer is not None:
            obs.append(viewer_observer(viewer))
        return obs

    def move_to(
        self,
        target: Pose,
        duration: float,
        *,
        profile: str = "linear",
        viewer: Any = None,
        clip: bool = False,
        phase: str = "move",
    ) -> SegmentResult:
        """Move from the last commanded target to ``target`` in ``duration`` s of simulated time.

        Returns a :class:`so101sim.motion.SegmentResult` (commanded and reached pose, largest
        tracking error per joint). Nothing moves if the target or duration is invalid.
        """
        from .motion import move

        with self.lock:
            return move(
                self.model,
                self.data,
                target,
                duration,
                profile=profile,
                observers=self._observers(viewer),
                clip=clip,
                phase=phase,
            )

    def hold(self, duration: float, *, viewer: Any = None, phase: str = "hold") -> SegmentResult:
        """Hold the last commanded target for ``duration`` s of simulated time."""
        from .motion import hold

        with self.lock:
            return hold(
                self.model, self.data, duration, observers=self._observers(viewer), phase=phase
            )
