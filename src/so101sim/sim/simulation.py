"""The simulation: an SO-101 in MuJoCo, in the arm's units, owning its state.

:class:`Simulation` holds the model, the data and everything a run needs beyond them (whether
the arm was ever commanded, the observers, one wall-clock timeline per viewer), and moves the
arm: :meth:`~Simulation.move_to`, :meth:`~Simulation.hold`, :meth:`~Simulation.step`. Each
move is planned whole by its shape (:mod:`so101sim.sim.profiles`), then stepped by
:func:`so101sim.sim.stepping.advance`; the result is a :class:`SegmentResult`.

Re-exported here: the stepping pieces (:class:`Observer`, :class:`Trace`, :class:`Pacer`,
:class:`ViewerObserver`, :func:`advance`) and :class:`SegmentResult`. Apart: the arm's state in
its units (:mod:`.armstate`), planning a move (:mod:`.moveplan`), the robot's per-call path
(:mod:`.fastpath`).

One spelling per concept (issue 30): the measured pose is :meth:`~Simulation.pose` (a dict) or
:meth:`~Simulation.pose_array` (arm units, an array); a target is set by
:meth:`~Simulation.command` (a pose, joints left out keep theirs) or
:meth:`~Simulation.command_array` (all six). ``pose_values`` and ``command_joints`` (the
robot's per-call path) are deprecated: :func:`so101sim.sim.fastpath.pose_values` and
:func:`~so101sim.sim.fastpath.command_joints`. A move's timing is its ``shape=`` (``profile=``
is deprecated: "profile" names the arm profile, the servos' model).
"""

from __future__ import annotations

import logging
import threading
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

import mujoco
import numpy as np

from ..errors import SettingError
from ..exitgate import gated
from ..model.arm import ArmLike
from ..model.load import ArmIndex, arm_index, arm_units, load_model
from ..units import JOINT_NAMES, STARTING_POSE, ArmUnits, Pose
from ..validation import MAX_DURATION_S, check_count
from .armstate import ATTACHED, ArmState, ArmTargets, check_data
from .moveplan import Shape, TipPath, move_shape, plan_joint_move, plan_tip_move
from .observers import Observer, Pacer, Trace, ViewerObserver, close_at_exit
from .profiles import duration_warning, steps_for
from .results import TRACE_AUTO_STEPS, ErrorTracker, SegmentKind, SegmentResult, keep_trace
from .stepping import advance, advance_unobserved, measured_radians

if TYPE_CHECKING:
    from ..kinematics import Kinematics, TipPose

log = logging.getLogger(__name__)

__all__ = ["TRACE_AUTO_STEPS", "Observer", "Pacer", "SegmentResult", "Simulation", "Trace"]
__all__ += ["ViewerObserver", "advance", "measured_radians"]


class Simulation(ArmTargets):
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
            check_data(self.model, data)
        self.data = data if data is not None else mujoco.MjData(self.model)
        self.index: ArmIndex = arm_index(self.model)
        self.units: ArmUnits = arm_units(self.model)
        self._qpos_list: list[int] = self.index.qpos.tolist()  # plain ints, for fastpath
        self._actuator_list: list[int] = self.index.actuator.tolist()
        self.observers: list[Observer] = []
        self.lock = threading.RLock()
        self._state = ArmState()
        self.initial_pose = dict(initial_pose) if initial_pose is not None else None
        if initial_pose is not None:
            self.set_pose(initial_pose)
        elif data is None:
            mujoco.mj_forward(self.model, self.data)

    @classmethod
    def attach(cls, model: mujoco.MjModel | None, data: mujoco.MjData) -> Simulation:
        """A Simulation driving an existing ``(model, data)`` (``model`` None: the data's own)
        as it is (nothing is reset or moved). Every Simulation attached to the same ``data``
        shares its commanded-target state and viewer timelines, so the lab's ``(m, d)``
        helpers can be called one after another as thin wrappers.

        Raises:
            SettingError: ``data`` is not a ``mujoco.MjData`` (e.g. None)."""
        if not isinstance(data, mujoco.MjData):
            raise SettingError(
                f"the simulation's data is {type(data).__name__}, not a mujoco.MjData; expected "
                "the d of m, d = so101sim.load_model(), mujoco.MjData(m)"
            )
        sim = cls(model if model is not None else data.model, data=data, initial_pose=None)
        state = ATTACHED.get(data)
        if state is None:
            state = ATTACHED[data] = ArmState(commanded=bool(data.ctrl.any()))
        sim._state = state
        return sim

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
            close_at_exit(viewer)  # a script's own launch_passive viewer: no segfault at its end
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
        if viewer is None and not observers and not self.observers and not keep_trace(trace, n):
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
            keep_trace=keep_trace(trace, n),
        )

    @gated  # no MuJoCo call left running at exit (exitgate)
    def plan_move(
        self,
        target: Pose,
        duration: float,
        *,
        shape: Shape | None = None,
        clip: bool = False,
        profile: Shape | None = None,
    ) -> tuple[np.ndarray, np.ndarray]:
        """Validate a move and compute all its targets: ``(start, targets)`` in arm units.
        Nothing moves. ``shape``: as for :meth:`move_to`.

        Raises:
            JointNameError, JointValueError, JointLimitError, DurationError, SettingError.
        """
        shape = move_shape(shape, profile)
        return plan_joint_move(self, target, duration, shape, clip)

    @gated  # no MuJoCo call left running at exit (exitgate)
    def move_to(
        self,
        target: Pose | None = None,
        duration: float | None = None,
        *,
        tip: Sequence[float] | None = None,
        pitch: float | None = None,
        roll: float | None = None,
        path: TipPath = "line",
        viewer: Any = None,
        observers: Sequence[Observer] = (),
        shape: Shape | None = None,
        clip: bool = False,
        phase: str = "move",
        trace: bool | None = None,
        profile: Shape | None = None,
    ) -> SegmentResult:
        """Move from the last commanded target to ``target`` (a pose) in ``duration`` s of
        simulated time; or move the gripper's tip to ``tip`` = (x, y, z) metres in the base
        frame (x forward, y left, z up), optionally with the tool's ``pitch`` (degrees above
        horizontal, -90 straight down) and ``roll``:

        * ``path="line"``: the tip follows a straight line (inverse kinematics at every step,
          following the ``linear`` or ``minimum_jerk`` shape's timing); the whole line is
          solved before anything moves, and a point out of reach raises
          :class:`~so101sim.errors.UnreachableError`;
        * ``path="joint"``: inverse kinematics for the end only, then a joint-space move of
          that ``shape``.

        ``shape``: how the targets go from start to goal (:mod:`so101sim.sim.profiles`):
        ``"linear"`` (default), ``"minimum_jerk"``, ``"limited"`` (as fast as the servos allow,
        no faster than ``duration``) or a function; ``profile=`` is its deprecated old name.

        The gripper keeps its target in a tip move. Returns a :class:`SegmentResult`
        (commanded and reached pose, largest tracking error per joint; per-step arrays when
        ``trace`` is True, or None and the move is at most :data:`TRACE_AUTO_STEPS` steps).
        Nothing moves if the target, duration or shape is invalid.
        """
        shape = move_shape(shape, profile)
        with self.lock:
            if tip is not None:
                start, targets = self.plan_tip_move(
                    tip, duration, pitch=pitch, roll=roll, path=path, shape=shape
                )
            else:
                if target is None:
                    raise SettingError("move_to needs a target pose or tip=(x, y, z) metres")
                start, targets = self.plan_move(target, duration, shape=shape, clip=clip)
            return self._segment("move", phase, start, targets, viewer, observers, trace)

    @gated  # no MuJoCo call left running at exit (exitgate)
    def plan_tip_move(
        self,
        tip: Sequence[float],
        duration: float | None,
        *,
        pitch: float | None = None,
        roll: float | None = None,
        path: TipPath = "line",
        shape: Shape | None = None,
        profile: Shape | None = None,
    ) -> tuple[np.ndarray, np.ndarray]:
        """Plan a move of the tip (see :meth:`move_to`): ``(start, targets)`` in arm units.
        Nothing moves.

        Raises:
            UnreachableError: the tip (or, for a line, some point of it) cannot be reached.
            DurationError, SettingError: a bad duration, path or shape.
        """
        shape = move_shape(shape, profile)
        return plan_tip_move(self, tip, duration, pitch=pitch, roll=roll, path=path, shape=shape)

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
        kind: SegmentKind,
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
        kind: SegmentKind,
        phase: str,
        start: np.ndarray,
        targets: np.ndarray,
        viewer: Any,
        observers: Sequence[Observer],
        trace: bool | None,
    ) -> SegmentResult:
        t0 = self.time
        keep = keep_trace(trace, len(targets))
        errors = ErrorTracker(self.units, start)
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
