"""The lab handout's helpers, with the handout's names and arguments, working correctly.

A student's ``so101_mujoco_utils`` script runs on these unchanged::

    from so101sim.lab import set_initial_pose, move_to_pose, hold_position

What differs from the handout, and why:

* **Units.** Degrees are ``rad * 180 / π`` with the exact π (the handout uses 3.14159). The
  gripper's 0–100 maps linearly onto the gripper joint's range (0 = closed = lower limit,
  100 = open = upper limit); the handout's ``qpos * 100 / π`` puts 100 at π rad, far outside
  the joint's −10°..100° range.
* **Time.** The handout times moves with the wall clock while stepping as fast as it can, so a
  "2 s" move runs however many physics steps the machine manages in 2 wall seconds (a bare
  stepping loop ran 181,010 to 225,458 steps, 362 to 451 simulated seconds, in four tries on a
  2-core machine: ``bench/bench_wallclock_handout.py``) and differs from run to run.
  Here a move of T seconds is exactly ``round(T / timestep)`` physics steps (1000 for 2 s at
  0.002 s): deterministic. With a viewer it is paced to the wall clock in real time by
  sleeping to absolute deadlines, so it neither races ahead nor drifts; where the machine
  cannot step and draw that fast, it logs a warning the first time it falls behind.
* **Holding.** The handout's ``hold_position`` re-reads the measured pose, which sags a little
  under gravity, and commands that, so the arm creeps down the longer it holds. Here it holds
  the last *commanded* target; before any command it holds the pose it finds.
* **Validation.** Unknown or missing joint names, non-numeric or non-finite values, targets
  outside the joint limits and durations ≤ 0 raise a clear :class:`~so101sim.So101SimError`
  before anything moves. ``clip=True`` (a keyword the handout's helpers did not have) clips
  targets to the joint limits instead of refusing them.

* **The end of the script.** Given MuJoCo's own passive viewer, the helpers make sure the
  script ends cleanly after its ``with launch_passive(...)`` block (the simulation calls
  :func:`so101sim.viewer.close_at_exit`): without it the process often segfaulted on the way
  out while the viewer's thread was still taking its window down.

``viewer`` may be ``None`` to run headless.
"""

from __future__ import annotations

import logging
from collections.abc import Callable, Sequence
from typing import Any

import mujoco
import numpy as np

from ..errors import JointValueError, SettingError
from ..model.load import default_units
from ..preflight.check import Thresholds, describe
from ..preflight.judge import judge
from ..preflight.measure import StepRecorder, collect
from ..preflight.states import StateRecorder, derivable
from ..sim.simulation import Observer, SegmentResult, Simulation
from ..units import JOINT_NAMES, Pose
from .arming import attached

log = logging.getLogger(__name__)

__all__ = [
    "convert_to_dictionary",
    "convert_to_list",
    "hold_position",
    "move_to_pose",
    "send_position_command",
    "set_initial_pose",
]


def convert_to_dictionary(qpos: Sequence[float] | np.ndarray) -> dict[str, float]:
    """Joint angles in radians (the first six values of ``qpos``) -> the arm's units.

    Body joints in degrees (exact π), gripper on 0–100 over the gripper joint's range (the
    shipped model's). The handout's ``qpos[5] * 100 / 3.14159`` for the gripper was wrong (see
    the module docs).
    """
    try:
        q = np.asarray(qpos, dtype=float).reshape(-1)[: len(JOINT_NAMES)]
    except (TypeError, ValueError) as exc:
        raise JointValueError(
            f"qpos = {qpos!r} is not a list of numbers ({exc}); expected d.qpos, six or more "
            "joint angles in radians"
        ) from None
    if len(q) < len(JOINT_NAMES):
        raise JointValueError(
            f"qpos has {len(q)} values; expected at least {len(JOINT_NAMES)} joint angles in "
            f"radians ({', '.join(JOINT_NAMES)})"
        )
    units = default_units()
    return units.array_to_pose(units.from_radians(q))


def convert_to_list(position_dict: Pose) -> list[float]:
    """A pose in the arm's units -> six joint angles in radians, in the arm's joint order.

    The inverse of :func:`convert_to_dictionary`. Raises JointNameError for unknown or missing
    joints and JointValueError for values that are not finite numbers.
    """
    units = default_units()
    return units.to_radians(units.pose_to_array(position_dict, check_limits=False)).tolist()


def _model_of(d: object) -> mujoco.MjModel:
    """The model of the simulation's data ``d``; SettingError if ``d`` is not an MjData."""
    if not isinstance(d, mujoco.MjData):
        raise SettingError(
            f"the simulation's data is {type(d).__name__}, not a mujoco.MjData; expected "
            "the d of m, d = so101sim.load_model(), mujoco.MjData(m)"
        )
    return d.model


def set_initial_pose(d: mujoco.MjData, position_dict: Pose, *, clip: bool = False) -> None:
    """Place the arm at ``position_dict`` (at rest) and command it to stay there.

    Unlike the handout, this also sets the position targets, so the arm holds the pose rather
    than falling towards the targets' default of 0 on the first step.
    """
    with attached(_model_of(d), d) as sim:  # SettingError: d is not an MjData
        sim.set_pose(position_dict, clip=clip)


def send_position_command(d: mujoco.MjData, position_dict: Pose, *, clip: bool = False) -> None:
    """Set the position actuators' targets to ``position_dict`` (all six joints).

    MuJoCo's position actuators then pull each joint towards its target with the model's PD
    gains. Raises before changing anything if a name, value or limit is wrong.
    """
    with attached(_model_of(d), d) as sim:
        sim.command_array(sim.units.pose_to_array(position_dict, clip=clip), check=False)


def move_to_pose(
    m: mujoco.MjModel,
    d: mujoco.MjData,
    viewer: Any,
    desired_position: Pose,
    duration: float,
    *,
    clip: bool = False,
) -> SegmentResult:
    """Move in a straight line (per joint) from the last commanded target to
    ``desired_position`` over ``duration`` seconds of simulated time.

    Exactly ``round(duration / timestep)`` physics steps; with a ``viewer``, paced to the wall
    clock. Returns the move's :class:`~so101sim.sim.simulation.SegmentResult` (the handout
    returned nothing; ignoring the result is fine). If the viewer is closed, returns early.
    """
    with attached(m, d) as sim:
        return _watched(
            sim,
            "move_to_pose",
            lambda obs: sim.move_to(
                desired_position, duration, viewer=viewer, observers=obs, clip=clip,
                phase="move_to_pose", trace=True,
            ),
        )  # fmt: skip


def hold_position(
    m: mujoco.MjModel, d: mujoco.MjData, viewer: Any, duration: float
) -> SegmentResult:
    """Hold the last commanded target for ``duration`` seconds of simulated time.

    Before any command, holds the pose it finds. (The handout re-read the sagging measured pose
    and let the arm creep under gravity.)
    """
    with attached(m, d) as sim:
        return _watched(
            sim,
            "hold_position",
            lambda obs: sim.hold(
                duration, viewer=viewer, observers=obs, phase="hold_position", trace=True
            ),
        )


def _watched(
    sim: Simulation, what: str, run: Callable[[list[Observer]], SegmentResult]
) -> SegmentResult:
    """Run one helper's segment, then log one warning per problem ``so101sim check`` would find
    in it (tracking error, saturated actuator, contact) with the time and the joint or bodies:
    the lab helpers say when a run went wrong. The figures come after the segment from the
    states the stepping kernel recorded, block by block in C (:class:`StateRecorder`,
    vectorised, or MuJoCo's own from the model's sensor twin); a model with neither (actuator
    forces that do not follow from the states, and no twin) is watched after every step
    instead (:class:`StepRecorder`)."""
    rec: StateRecorder | StepRecorder
    exact = derivable(sim.model)  # the same test as so101sim check's
    rec = StateRecorder(sim.model) if exact else StepRecorder(sim.model)
    seg = run([rec])
    th = Thresholds()
    measured = collect(sim.model, [], [seg], rec, th.max_effort)
    for finding in judge(measured, th):
        if finding.failed:
            what_went_wrong = describe(finding, th).split(": ", 1)[1]
            log.warning(
                "%s (%.3f-%.3f s): %s; run `so101sim check` on the motion for the full report",
                what,
                seg.start_time,
                seg.end_time,
                what_went_wrong,
            )
    return seg
