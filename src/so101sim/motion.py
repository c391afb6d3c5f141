"""Motions: trajectory profiles, moves, holds, and sequences of them.

A move of T seconds is exactly ``round(T / timestep)`` physics steps of simulated time. Its
targets are computed for the whole move at once (one array), then replayed by
:func:`so101sim.simulation.advance`; no per-step Python work.

Step i of a move (0-based, n steps) commands the profile at ``s = (i + 1) / n``: the last step
commands the target itself, and the first already moves away from the start.
"""

from __future__ import annotations

import logging
import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

import mujoco
import numpy as np

from .errors import DurationError, SettingError
from .model import arm_units
from .simulation import Observer, Trace, advance, commanded_target, measured_radians
from .trajectory import LimitedProfile
from .units import JOINT_NAMES, STARTING_POSE, ZERO_POSE, ArmUnits, Pose

log = logging.getLogger(__name__)

Profile = Callable[[np.ndarray, np.ndarray, int, float], np.ndarray]
"""``profile(start, target, n_steps, dt) -> (n, 6)`` targets in arm units (n may differ from
``n_steps`` if the profile must stretch the move)."""


def check_duration(duration: object, what: str = "duration") -> float:
    """Return ``duration`` as a float if it is a finite number > 0, else raise DurationError."""
    if isinstance(duration, bool) or not isinstance(duration, int | float | np.number):
        raise DurationError(f"{what} = {duration!r} is not a number; expected seconds > 0")
    d = float(duration)
    if not math.isfinite(d) or d <= 0:
        raise DurationError(f"{what} = {d} s is invalid; expected a finite number of seconds > 0")
    return d


def steps_for(duration: float, timestep: float) -> int:
    """Physics steps in ``duration`` seconds: ``round(duration / timestep)``, at least 1."""
    n = round(check_duration(duration) / timestep)
    if n == 0:
        log.warning(
            "duration %g s is shorter than half a physics step (%g s); it takes one step",
            duration,
            timestep,
        )
    return max(1, n)


def _shape(fn: Callable[[np.ndarray], np.ndarray]) -> Profile:
    def profile(start: np.ndarray, target: np.ndarray, n: int, dt: float) -> np.ndarray:
        s = fn(np.arange(1, n + 1) / n)[:, None]
        out = start + (target - start) * s
        out[-1] = target  # exact, whatever the rounding of the shape function
        return out

    profile.__doc__ = fn.__doc__
    return profile


def _linear(s: np.ndarray) -> np.ndarray:
    """Straight-line interpolation at constant speed (the lab's profile)."""
    return s


def _minimum_jerk(s: np.ndarray) -> np.ndarray:
    """Minimum-jerk polynomial 10s³ − 15s⁴ + 6s⁵: zero velocity and acceleration at both ends."""
    return s**3 * (10.0 - 15.0 * s + 6.0 * s**2)


PROFILES: dict[str, Profile] = {
    "linear": _shape(_linear),
    "minimum_jerk": _shape(_minimum_jerk),
    "limited": LimitedProfile(),
}
"""Profile name -> function. ``limited``: time-optimal under the STS3215's velocity,
acceleration and jerk limits (:mod:`so101sim.trajectory`)."""


def get_profile(name: str | Profile) -> Profile:
    """The profile called ``name`` (a profile function is returned as is); raises
    SettingError listing the valid names."""
    if callable(name):
        return name
    try:
        return PROFILES[name]
    except KeyError:
        raise SettingError(
            f"unknown profile {name!r}; valid profiles are {', '.join(sorted(PROFILES))}"
        ) from None


# ---------------------------------------------------------------------------- results
@dataclass(frozen=True)
class SegmentResult:
    """What one move or hold did. Poses are dicts in the arm's units; arrays are per step."""

    phase: str
    kind: str  # "move" | "hold"
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


def _result(
    units: ArmUnits,
    phase: str,
    kind: str,
    t0: float,
    start: np.ndarray,
    trace: Trace,
    d: mujoco.MjData,
    m: mujoco.MjModel,
) -> SegmentResult:
    commanded = units.from_radians(trace.ctrl)
    measured = units.from_radians(trace.qpos)
    err = np.abs(commanded - measured).max(axis=0) if len(trace) else np.zeros(len(JOINT_NAMES))
    reached = units.from_radians(measured_radians(m, d))
    target = commanded[-1] if len(trace) else start
    return SegmentResult(
        phase=phase,
        kind=kind,
        start_time=t0,
        end_time=float(d.time),
        steps=len(trace),
        start=units.array_to_pose(start),
        target=units.array_to_pose(target),
        reached=units.array_to_pose(reached),
        max_tracking_error=units.array_to_pose(err),
        completed=trace.completed,
        times=trace.time.copy(),
        commanded=commanded,
        measured=measured,
    )


def _start(m: mujoco.MjModel, d: mujoco.MjData, units: ArmUnits) -> np.ndarray:
    """Where a move starts: the last commanded target, else the measured pose."""
    q = commanded_target(d)
    return units.from_radians(q if q is not None else measured_radians(m, d))


# ---------------------------------------------------------------------------- moves and holds
def plan_move(
    m: mujoco.MjModel,
    d: mujoco.MjData,
    target: Pose,
    duration: float,
    *,
    profile: str | Profile = "linear",
    clip: bool = False,
) -> tuple[np.ndarray, np.ndarray]:
    """Validate a move and compute all its targets: ``(start, targets)`` in arm units.

    Raises (before anything moves):
        JointNameError, JointValueError, JointLimitError, DurationError, SettingError.
    """
    units = arm_units(m)
    goal = units.pose_to_array(target, clip=clip)
    n = steps_for(duration, m.opt.timestep)
    plan = get_profile(profile)
    start = _start(m, d, units)
    return start, plan(start, goal, n, m.opt.timestep)


def move(
    m: mujoco.MjModel,
    d: mujoco.MjData,
    target: Pose,
    duration: float,
    *,
    profile: str | Profile = "linear",
    observers: Sequence[Observer] = (),
    clip: bool = False,
    phase: str = "move",
) -> SegmentResult:
    """Move the arm from its last commanded target to ``target`` over ``duration`` simulated
    seconds, then return what happened."""
    units = arm_units(m)
    start, targets = plan_move(m, d, target, duration, profile=profile, clip=clip)
    t0 = float(d.time)
    trace = advance(m, d, units.to_radians(targets), observers, phase)
    return _result(units, phase, "move", t0, start, trace, d, m)


def hold(
    m: mujoco.MjModel,
    d: mujoco.MjData,
    duration: float,
    *,
    observers: Sequence[Observer] = (),
    phase: str = "hold",
) -> SegmentResult:
    """Hold the last commanded target (the measured pose, before any command) for ``duration``
    simulated seconds."""
    units = arm_units(m)
    n = steps_for(duration, m.opt.timestep)
    start = _start(m, d, units)
    t0 = float(d.time)
    trace = advance(m, d, np.repeat(units.to_radians(start)[None], n, axis=0), observers, phase)
    return _result(units, phase, "hold", t0, start, trace, d, m)


# ---------------------------------------------------------------------------- sequences
@dataclass(frozen=True)
class Move:
    """Move to ``target`` over ``duration`` seconds with ``profile``."""

    target: Pose
    duration: float
    profile: str | Profile = "linear"
    phase: str = "move"


@dataclass(frozen=True)
class Hold:
    """Hold the last target for ``duration`` seconds."""

    duration: float
    phase: str = "hold"


Step = Move | Hold


@dataclass(frozen=True)
class RunResult:
    """The segments of a motion, in order. ``completed`` is False if it was cut short."""

    segments: list[SegmentResult]

    @property
    def completed(self) -> bool:
        return all(s.completed for s in self.segments)

    @property
    def end_time(self) -> float:
        return self.segments[-1].end_time if self.segments else 0.0


LAB_MOTION: tuple[Step, ...] = (
    Move(ZERO_POSE, 2.0, phase="to_zero"),
    Hold(2.0, phase="hold"),
    Move(STARTING_POSE, 2.0, phase="return"),
)
"""The lab's motion: from the rest pose to all zeros in 2 s, hold 2 s, back in 2 s."""


def validate_steps(m: mujoco.MjModel, steps: Sequence[Step], *, clip: bool = False) -> None:
    """Check every step's target, profile and duration before anything moves."""
    units = arm_units(m)
    for step in steps:
        check_duration(step.duration, f"{step.phase} duration")
        if isinstance(step, Move):
            units.pose_to_array(step.target, clip=clip)
            get_profile(step.profile)


def run_motion(
    m: mujoco.MjModel,
    d: mujoco.MjData,
    steps: Sequence[Step] = LAB_MOTION,
    *,
    observers: Sequence[Observer] = (),
    clip: bool = False,
) -> RunResult:
    """Run a sequence of moves and holds; stops early if an observer (a closed viewer) says so.

    Every step is validated before the first one runs.
    """
    validate_steps(m, steps, clip=clip)
    segments: list[SegmentResult] = []
    for step in steps:
        if isinstance(step, Move):
            seg = move(
                m,
                d,
                step.target,
                step.duration,
                profile=step.profile,
                observers=observers,
                clip=clip,
                phase=step.phase,
            )
        else:
            seg = hold(m, d, step.duration, observers=observers, phase=step.phase)
        segments.append(seg)
        if not seg.completed:
            log.info("run stopped during %s at t = %.3f s", seg.phase, seg.end_time)
            break
    return RunResult(segments)


__all__ = [
    "LAB_MOTION",
    "PROFILES",
    "STARTING_POSE",
    "Hold",
    "Move",
    "RunResult",
    "SegmentResult",
    "check_duration",
    "hold",
    "move",
    "plan_move",
    "run_motion",
    "steps_for",
]
