"""The simulation: an SO-101 in MuJoCo, in the arm's units, owning its state.

:class:`Simulation` holds the model, the data and everything a run needs beyond them (whether
the arm was ever commanded, the observers, one wall-clock timeline per viewer), and moves the
arm: :meth:`~Simulation.move_to`, :meth:`~Simulation.hold`, :meth:`~Simulation.step`. Each
move is planned whole by a profile (:mod:`so101sim.sim.profiles`), then stepped by
:func:`so101sim.sim.stepping.advance`; the result is a :class:`SegmentResult`.

The stepping pieces (:class:`Observer`, :class:`Trace`, :class:`Pacer`,
:class:`ViewerObserver`, :func:`advance`) are re-exported here from :mod:`so101sim.sim.stepping`.

Why this module is over 400 lines: it is the one class users drive, and its public methods
(each short, with its docstring) belong together; the stepping machinery is already apart.

Long on purpose: :class:`Simulation` is the sim layer's one public object; its methods
share its state (the commanded targets, the observers, the viewers' timelines) and are
its documentation, so it stays one class in one module.
"""

from __future__ import annotations

import logging
import threading
import weakref
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

import mujoco
import numpy as np

from ..errors import DurationError, ModelError, SettingError
from ..exitgate import gated
from ..model.arm import ArmLike, fill_delay_history
from ..model.load import ArmIndex, arm_index, arm_units, load_model
from ..units import JOINT_NAMES, STARTING_POSE, ArmUnits, Pose, unit_warnings
from ..validation import MAX_DURATION_S, check_choice, check_count
from .profiles import (
    MAX_MOVE_DURATION_S,
    Profile,
    duration_warning,
    fractions,
    get_profile,
    plan,
    steps_for,
)
from .stepping import (
    Observer,
    Pacer,
    Trace,
    ViewerObserver,
    advance,
    advance_unobserved,
    measured_radians,
)

if TYPE_CHECKING:
    from ..kinematics import Kinematics, TipPose

log = logging.getLogger(__name__)

__all__ = [
    "TRACE_AUTO_STEPS",
    "Observer",
    "Pacer",
    "SegmentResult",
    "Simulation",
    "Trace",
    "ViewerObserver",
    "advance",
    "measured_radians",
]


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

    ``arm`` (optional): an arm profile (``"official"``, ``"sts3215"``, a TOML path) applied to
    the servos at load (:mod:`so101sim.model.arm`) when so101sim loads the model; None is the
    default, ``sts3215`` (the fitted servos; see :func:`so101sim.model.load_model`).
    """

    def __init__(
        self,
        model: mujoco.MjModel | str | Path | None = None,
        *,
        data: mujoco.MjData | None = None,
        initial_pose: Pose | None = STARTING_POSE,
        arm: ArmLike = None,
    ) -> None:
        if arm is not None and isinstance(model, mujoco.MjModel):
            raise SettingError(
                "arm= applies when so101sim loads the model; expected a path (or None) with "
                "arm=, or a model loaded with load_model(path, arm=...)"
            )
        self.model: mujoco.MjModel = (
            model if isinstance(model, mujoco.MjModel) else load_model(model, arm=arm)
        )
        if data is not None:
            _check_data(self.model, data)
        self.data = data if data is not None else mujoco.MjData(self.model)
        self.index: ArmIndex = arm_index(self.model)
        self.units: ArmUnits = arm_units(self.model)
        self._qpos_list: list[int] = self.index.qpos.tolist()  # plain ints, for pose_values
        self._actuator_list: list[int] = self.index.actuator.tolist()  # for command_joints
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

    def pose_values(self) -> list[float]:
        """:meth:`pose_array` as six plain floats, bit for bit, without NumPy arrays (the
        robot's per-call path)."""
        q = self.data.qpos.tolist()
        return self.units.values_from_radians([q[i] for i in self._qpos_list])

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

    @gated  # no MuJoCo call left running at exit (exitgate)
    def set_pose(self, pose: Pose, *, clip: bool = False) -> None:
        """Place the arm at ``pose`` at rest (velocities zero) and command it to stay there."""
        values = self.units.pose_to_array(pose, clip=clip)
        q = self.units.to_radians(values)
        with self.lock:
            self.data.qpos[self.index.qpos] = q
            self.data.qvel[self.index.dof] = 0.0
            self._set_target(q)
            # the delayed servos' history first, so the forces mj_forward computes are those
            # of an arm holding the pose (not of a goal still at the history's zeros)
            fill_delay_history(self.model, self.data)
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

    def command_joints(self, indices: list[int], values: list[float]) -> None:
        """Set the targets of some joints (indices into :data:`JOINT_NAMES`) to ``values``, arm
        units already checked and inside the limits (the robot's per-action path: no arrays)."""
        to_radians, act = self.units.joint_to_radians, self._actuator_list
        with self.lock:
            ctrl = self.data.ctrl
            for i, v in zip(indices, values, strict=True):
                ctrl[act[i]] = to_radians(i, v)
            self._state.commanded = True

    def _set_target(self, q: np.ndarray) -> None:
        self.data.ctrl[self.index.actuator] = q
        self._state.commanded = True

    @gated  # no MuJoCo call left running at exit (exitgate)
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
    @gated  # no MuJoCo call left running at exit (exitgate)
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
        arr = np.asarray(targets, dtype=float).reshape(-1, len(JOINT_NAMES))
        if len(arr) > 1 and arr.strides[0] == 0:  # one target held (a broadcast view): convert
            q = np.broadcast_to(self.units.to_radians(arr[:1]), arr.shape)  # one row, not n
        else:
            q = self.units.to_radians(arr)
        with self.lock:
            if len(q):
                self._state.commanded = True
            obs = self._observers(viewer, observers)
            return advance(self.model, self.data, q, obs, phase, keep_trace=keep_trace)

    @gated  # no MuJoCo call left running at exit (exitgate)
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
        if viewer is None and not observers and not self.observers and not _keep(trace, n):
            with self.lock:  # nothing watches: MuJoCo's own loop, on the targets as set
                q = None if self.was_commanded else self.units.to_radians(self.pose_array())
                self._state.commanded = True
                advance_unobserved(self.model, self.data, q, n)
            empty = np.empty((0, len(JOINT_NAMES)))
            return Trace(np.empty(0), empty, empty, True, n)
        target = self.commanded_array()
        return self.advance(
            np.broadcast_to(target, (n, len(target))),
            viewer=viewer,
            observers=observers,
            phase="step",
            keep_trace=_keep(trace, n),
        )

    @gated  # no MuJoCo call left running at exit (exitgate)
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

    @gated  # no MuJoCo call left running at exit (exitgate)
    def move_to(
        self,
        target: Pose | None = None,
        duration: float | None = None,
        *,
        tip: Sequence[float] | None = None,
        pitch: float | None = None,
        roll: float | None = None,
        path: str = "line",
        viewer: Any = None,
        observers: Sequence[Observer] = (),
        profile: str | Profile = "linear",
        clip: bool = False,
        phase: str = "move",
        trace: bool | None = None,
    ) -> SegmentResult:
        """Move from the last commanded target to ``target`` (a pose) in ``duration`` s of
        simulated time; or move the gripper's tip to ``tip`` = (x, y, z) metres in the base
        frame (x forward, y left, z up), optionally with the tool's ``pitch`` (degrees above
        horizontal, -90 straight down) and ``roll``:

        * ``path="line"``: the tip follows a straight line (inverse kinematics at every step,
          following the ``linear`` or ``minimum_jerk`` profile's timing); the whole line is
          solved before anything moves, and a point out of reach raises
          :class:`~so101sim.errors.UnreachableError`;
        * ``path="joint"``: inverse kinematics for the end only, then a joint-space move with
          ``profile``.

        The gripper keeps its target in a tip move. Returns a :class:`SegmentResult`
        (commanded and reached pose, largest tracking error per joint; per-step arrays when
        ``trace`` is True, or None and the move is at most :data:`TRACE_AUTO_STEPS` steps).
        Nothing moves if the target, duration or profile is invalid.
        """
        with self.lock:
            if tip is not None:
                start, targets = self.plan_tip_move(
                    tip, duration, pitch=pitch, roll=roll, path=path, profile=profile
                )
            else:
                if target is None:
                    raise SettingError("move_to needs a target pose or tip=(x, y, z) metres")
                start, targets = self.plan_move(target, duration, profile=profile, clip=clip)
            return self._segment("move", phase, start, targets, viewer, observers, trace)

    @gated  # no MuJoCo call left running at exit (exitgate)
    def plan_tip_move(
        self,
        tip: Sequence[float],
        duration: float | None,
        *,
        pitch: float | None = None,
        roll: float | None = None,
        path: str = "line",
        profile: str | Profile = "linear",
    ) -> tuple[np.ndarray, np.ndarray]:
        """Plan a move of the tip (see :meth:`move_to`): ``(start, targets)`` in arm units.
        Nothing moves.

        Raises:
            UnreachableError: the tip (or, for a line, some point of it) cannot be reached.
            DurationError, SettingError: a bad duration, path or profile.
        """
        from ..kinematics import plan_line, solve_ik  # imported here: only tip moves need it
        from ..kinematics.paths import MAX_LINE_STEPS

        _ = self.kinematics  # held here, so that the planner's calls share it
        check_choice(path, "path", ("line", "joint"))
        n = steps_for(_required(duration), self.timestep, maximum=MAX_MOVE_DURATION_S)
        if path == "line" and n > MAX_LINE_STEPS:  # a model with a very short timestep
            raise SettingError(
                f"a straight tip line of {duration:g} s is {n} physics steps of "
                f"{self.timestep * 1000:g} ms; expected at most {MAX_LINE_STEPS} steps "
                f"({MAX_LINE_STEPS * self.timestep:g} s with this model): split it into "
                "shorter lines, or use path='joint'"
            )
        start = self.commanded_array()
        if path == "joint":
            goal = solve_ik(tip, pitch=pitch, roll=roll, initial=start, model=self.model)
            prof = get_profile(profile, self.units)
            return start, plan(start, goal.values, n, self.timestep, prof)
        line = plan_line(
            start, tip, fractions(profile, n), pitch=pitch, roll=roll, model=self.model
        )
        return start, line.targets

    @gated  # no MuJoCo call left running at exit (exitgate)
    def tip(self) -> TipPose:
        """Where the gripper's tip is now (measured): position in metres in the base frame and
        orientation (:class:`~so101sim.kinematics.TipPose`)."""
        return self.kinematics.tip_array(self.pose_array())

    @property
    def kinematics(self) -> Kinematics:
        """The model's shared :class:`~so101sim.kinematics.Kinematics`, made on first use and
        held by this simulation (the table of :func:`~so101sim.kinematics.for_model` holds
        none: it would keep the model alive)."""
        kin = self.__dict__.get("_kinematics")
        if kin is None:
            from ..kinematics import for_model  # imported here: only tip queries need it

            kin = self.__dict__["_kinematics"] = for_model(self.model)
        return kin

    @gated  # no MuJoCo call left running at exit (exitgate)
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

    @gated  # no MuJoCo call left running at exit (exitgate)
    def run_targets(
        self,
        kind: str,
        phase: str,
        start: np.ndarray,
        targets: np.ndarray,
        *,
        viewer: Any = None,
        observers: Sequence[Observer] = (),
        trace: bool | None = None,
    ) -> SegmentResult:
        """Step a segment already planned (and checked): ``targets`` (n, 6) arm units from the
        commanded ``start``, as :meth:`move_to` (``kind`` "move") or :meth:`hold` ("hold")
        would after planning it (:func:`so101sim.motion.plan.run_plan` runs a plan this way)."""
        with self.lock:
            return self._segment(kind, phase, start, targets, viewer, observers, trace)

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
        # along contiguous rows: NumPy reduces them several times faster than columns
        error = np.ascontiguousarray(np.abs(commanded - measured).T)
        self.max = np.maximum(self.max, error.max(axis=1))
        self.last = commanded[-1]


def _required(duration: float | None) -> float:
    if duration is None:
        raise DurationError("duration is missing; expected the move's length in seconds > 0")
    return duration


def _check_data(model: mujoco.MjModel, data: mujoco.MjData) -> None:
    """Raise ModelError if ``data`` was not made for ``model`` (their sizes differ)."""
    sizes = ("nq", "nv", "nu", "na", "nbody")
    if any(getattr(data.model, s) != getattr(model, s) for s in sizes):
        raise ModelError(
            "the MjData was made for another model (nq/nv/nu/nbody differ); expected "
            "mujoco.MjData(model) of the same model"
        )
