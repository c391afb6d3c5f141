"""The arm's state in its units, as a :class:`~so101sim.sim.simulation.Simulation` holds it:
the clock, the measured pose, the commanded targets (kept in ``MjData.ctrl``) and whether the
arm was ever commanded (:class:`ArmTargets`, the part of ``Simulation`` that reads and sets
them), with the checks of what comes in (six finite numbers, data made for the model)."""

from __future__ import annotations

import threading
import warnings
import weakref
from dataclasses import dataclass, field
from typing import Any

import mujoco
import numpy as np

from ..errors import JointValueError, ModelError
from ..exitgate import gated
from ..model.arm import fill_delay_history
from ..model.load import ArmIndex
from ..units import JOINT_NAMES, ArmUnits, Pose
from . import fastpath
from .stepping import ViewerObserver


@dataclass
class ArmState:
    """What a :class:`Simulation` knows beyond ``MjData``: whether the arm was ever commanded
    (to tell "never commanded" from "commanded to 0"), and one viewer timeline per viewer."""

    commanded: bool = False
    viewers: weakref.WeakKeyDictionary[Any, ViewerObserver] = field(
        default_factory=weakref.WeakKeyDictionary
    )


# Handout-style code passes a bare (MjModel, MjData) to every call; Simulation.attach() wraps it,
# and this table lets successive wrappers of the same MjData share one ArmState (it never
# holds the MjData itself, so it keeps nothing alive).
ATTACHED: weakref.WeakKeyDictionary[mujoco.MjData, ArmState] = weakref.WeakKeyDictionary()


class ArmTargets:
    """The clock, the measured pose and the commanded targets of a simulation, in the arm's
    units (mixed into :class:`~so101sim.sim.simulation.Simulation`, which sets the
    attributes below)."""

    model: mujoco.MjModel
    data: mujoco.MjData
    index: ArmIndex
    units: ArmUnits
    lock: threading.RLock
    initial_pose: dict[str, float] | None
    _state: ArmState
    _qpos_list: list[int]
    _actuator_list: list[int]

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
        """Deprecated: :func:`so101sim.sim.fastpath.pose_values` (or :meth:`pose_array`)."""
        deprecated("Simulation.pose_values()", "so101sim.sim.fastpath.pose_values(sim)")
        return fastpath.pose_values(self)

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

        With ``check`` (the default) the values are checked against the joint limits first;
        pass ``check=False`` only for values already inside them. Six finite numbers are
        always required.

        Raises:
            JointValueError: not six finite numbers.
            JointLimitError: a value outside its joint's limits (with ``check``).
        """
        v = six_values(values)
        if check:
            v = self.units.check_limits(v)
        with self.lock:
            self._set_target(self.units.to_radians(v))

    def command_radians(self, q: np.ndarray) -> None:
        """Set all six position targets from radians: ``units.to_radians`` of six finite
        values inside the limits, converted by the caller (a vector environment converts
        every world's at once); :meth:`command_array` with ``check=False`` in one step."""
        with self.lock:
            self._set_target(q)

    def command_joints(self, indices: list[int], values: list[float]) -> None:
        """Deprecated: :func:`so101sim.sim.fastpath.command_joints` (or :meth:`command`)."""
        deprecated("Simulation.command_joints()", "so101sim.sim.fastpath.command_joints(sim)")
        fastpath.command_joints(self, indices, values)

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


def check_data(model: mujoco.MjModel, data: mujoco.MjData) -> None:
    """Raise ModelError if ``data`` was not made for ``model`` (their sizes differ)."""
    sizes = ("nq", "nv", "nu", "na", "nbody")
    if any(getattr(data.model, s) != getattr(model, s) for s in sizes):
        raise ModelError(
            "the MjData was made for another model (nq/nv/nu/nbody differ); expected "
            "mujoco.MjData(model) of the same model"
        )


def six_values(values: Any) -> np.ndarray:
    """``values`` as six finite floats (arm units), or a JointValueError saying what came."""
    try:
        v = np.asarray(values, dtype=float)
    except (TypeError, ValueError):
        raise JointValueError(
            f"targets = {values!r:.60} are not numbers; expected six numbers in arm units "
            f"({', '.join(JOINT_NAMES)})"
        ) from None
    if v.shape != (len(JOINT_NAMES),):
        raise JointValueError(
            f"targets have shape {v.shape}; expected six numbers in arm units, one per joint "
            f"({', '.join(JOINT_NAMES)})"
        )
    bad = np.flatnonzero(~np.isfinite(v))
    if bad.size:
        name = JOINT_NAMES[int(bad[0])]
        raise JointValueError(
            f"{name} = {v[bad[0]]} is not a finite number; expected six finite numbers in arm "
            "units (degrees, the gripper 0-100)"
        )
    return v


def deprecated(old: str, new: str) -> None:
    warnings.warn(
        f"{old} is deprecated and goes in the next release; use {new}",
        DeprecationWarning,
        stacklevel=3,
    )
