"""Time-optimal moves under velocity, acceleration and jerk limits: the ``limited`` profile.

The profile is planned with `ruckig <https://github.com/pantor/ruckig>`_: every joint moves
under its own velocity, acceleration and jerk limits, starting and ending at rest, and the
joints are time-synchronised (``Synchronization.Time``) so that they all arrive together. The
trajectory is sampled at the physics timestep.

A move asked to take longer than the limits need takes exactly the time asked (ruckig's
``minimum_duration``). A move asked to take less is **stretched** to the shortest time the
limits allow, with a warning in the log, or refused with :class:`TrajectoryLimitError` in
strict mode (``LimitedProfile(strict=True)``, or, before a run, the motion planner:
``plan_segments(..., strict=True)`` in :mod:`so101sim.motion.plan`).

Default limits (:data:`STS3215_LIMITS`), in degrees of joint rotation, for the SO-101's Feetech
STS3215 servos (7.4 V version, 1/345 gearing, on the follower arm):

* **velocity 180 °/s.** The servo's no-load speed is 0.192 s/60° ≈ 312 °/s (52 rpm) at 7.4 V
  (DFRobot/Feetech ST3215 datasheet); the 12 V version does 45 rpm ≈ 270 °/s; the Goal_Velocity
  register tops out at 3400 steps/s ≈ 299 °/s (4096 steps per turn). Under load a servo runs
  slower than its no-load speed, so the default keeps ~40 % headroom below the register maximum.
* **acceleration 1000 °/s².** LeRobot writes ``Acceleration = 254`` to every motor
  (``FeetechMotorsBus.configure_motors``); the register counts 100 steps/s², so 254 is
  25 400 steps/s² ≈ 2233 °/s². The default is under half of that, which keeps the simulated
  actuators of the shipped model well inside their force limit on the lab's moves.
* **jerk 10 000 °/s³.** The servo has no jerk setting; this figure (full acceleration reached in
  0.1 s) is a smoothness choice, not a servo figure.

The gripper joint gets the same figures in degrees, converted to its 0–100 scale with the
shipped model's gripper range (110° for 100 units).
"""

from __future__ import annotations

import logging
import math
from collections.abc import Iterable, Sequence
from dataclasses import dataclass

import numpy as np
from ruckig import InputParameter, Result, Ruckig, Synchronization, Trajectory

from ..errors import SettingError, TrajectoryLimitError
from ..model.load import default_units
from ..units import JOINT_NAMES, ArmUnits
from ..validation import check_range, escape_controls

log = logging.getLogger(__name__)

_N = len(JOINT_NAMES)


@dataclass(frozen=True)
class JointLimits:
    """Per-joint limits in degrees of joint rotation (gripper included), JOINT_NAMES order."""

    velocity: tuple[float, ...]  # deg/s
    acceleration: tuple[float, ...]  # deg/s²
    jerk: tuple[float, ...]  # deg/s³

    def __post_init__(self) -> None:
        expected = f"{_N} finite numbers > 0 (one per joint: {', '.join(JOINT_NAMES)})"
        for what in ("velocity", "acceleration", "jerk"):
            given = tuple(getattr(self, what))
            if len(given) != _N:
                raise SettingError(f"{what} limits = {given!r} are invalid; expected {expected}")
            values = tuple(
                check_range(v, f"{what} limit of {name}", low=0.0, low_open=True, expected=expected)
                for name, v in zip(JOINT_NAMES, given, strict=True)
            )
            object.__setattr__(self, what, values)

    @classmethod
    def uniform(cls, velocity: float, acceleration: float, jerk: float) -> JointLimits:
        """The same limits for all six joints."""
        return cls((velocity,) * _N, (acceleration,) * _N, (jerk,) * _N)

    def in_arm_units(self, units: ArmUnits) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(velocity, acceleration, jerk) in arm units per s, s², s³ (gripper: 0–100 units)."""
        per_deg = units.per_degree()
        return (
            np.array(self.velocity) * per_deg,
            np.array(self.acceleration) * per_deg,
            np.array(self.jerk) * per_deg,
        )


STS3215_LIMITS = JointLimits.uniform(velocity=180.0, acceleration=1000.0, jerk=10_000.0)
"""Conservative STS3215 limits; see the module's documentation for the figures and sources."""


class LimitedProfile:
    """The ``limited`` profile: ``profile(start, target, n_steps, dt) -> (n, 6)`` arm-unit
    targets, time-optimal under ``limits``, all joints arriving together.

    ``n`` is ``n_steps`` when the limits allow the move in ``n_steps * dt`` seconds; otherwise
    the move is stretched to the shortest whole number of steps the limits allow (a logged
    warning), or, with ``strict``, refused with :class:`TrajectoryLimitError`.
    """

    def __init__(
        self,
        limits: JointLimits = STS3215_LIMITS,
        *,
        strict: bool = False,
        units: ArmUnits | None = None,
    ) -> None:
        self.limits = limits
        self.strict = strict
        self._units = units

    @property
    def units(self) -> ArmUnits:
        return self._units if self._units is not None else default_units()

    def _input(self, start: np.ndarray, target: np.ndarray) -> InputParameter:
        v, a, j = self.limits.in_arm_units(self.units)
        inp = InputParameter(_N)
        inp.current_position = np.asarray(start, dtype=float).tolist()
        inp.target_position = np.asarray(target, dtype=float).tolist()
        inp.current_velocity = [0.0] * _N
        inp.current_acceleration = [0.0] * _N
        inp.target_velocity = [0.0] * _N
        inp.target_acceleration = [0.0] * _N
        inp.max_velocity = v.tolist()
        inp.max_acceleration = a.tolist()
        inp.max_jerk = j.tolist()
        inp.synchronization = Synchronization.Time
        return inp

    def _plan(self, inp: InputParameter) -> Trajectory:
        traj = Trajectory(_N)
        result = Ruckig(_N).calculate(inp, traj)
        if result not in (Result.Working, Result.Finished):
            raise TrajectoryLimitError(
                f"ruckig could not plan the move ({result.name}); expected finite start and "
                "target poses and limits > 0"
            )
        return traj

    def minimum_duration(self, start: np.ndarray, target: np.ndarray) -> float:
        """The shortest time (s) in which the limits allow the move from rest to rest."""
        if np.array_equal(start, target):
            return 0.0
        return float(self._plan(self._input(start, target)).duration)

    def __call__(self, start: np.ndarray, target: np.ndarray, n: int, dt: float) -> np.ndarray:
        start = np.asarray(start, dtype=float)
        target = np.asarray(target, dtype=float)
        if np.array_equal(start, target):
            return np.repeat(target[None], n, axis=0)
        inp = self._input(start, target)
        t_min = float(self._plan(inp).duration)
        needed = minimum_steps(t_min, dt)
        if n < needed:
            message = (
                f"a move of {n * dt:.3f} s is shorter than the {t_min:.3f} s the joint limits "
                f"allow (velocity {_fmt(self.limits.velocity)} °/s, acceleration "
                f"{_fmt(self.limits.acceleration)} °/s², jerk {_fmt(self.limits.jerk)} °/s³)"
            )
            if self.strict:
                raise TrajectoryLimitError(
                    f"{message}; give it a duration of at least {needed * dt:.3f} s, or allow "
                    "stretching (no --strict)"
                )
            log.warning("%s; stretching it to %.3f s", message, needed * dt)
            n = needed
        inp.minimum_duration = n * dt
        traj = self._plan(inp)
        times = np.minimum(np.arange(1, n + 1) * dt, traj.duration)
        out = np.array([traj.at_time(float(t))[0] for t in times])
        out[-1] = target  # exact, whatever the rounding of the last sample
        return out


def minimum_steps(t_min: float, dt: float) -> int:
    """The fewest whole physics steps of ``dt`` s that a move needing ``t_min`` s can take:
    ``ceil(t_min / dt)`` (at least 1). A ``limited`` move of ``n`` steps is short, stretched
    or refused, exactly when ``n`` is below this."""
    return max(1, math.ceil(t_min / dt - 1e-9))


def _fmt(values: Iterable[float]) -> str:
    values = tuple(values)
    return f"{values[0]:g}" if len(set(values)) == 1 else "/".join(f"{v:g}" for v in values)


@dataclass(frozen=True)
class ShortMove:
    """A ``limited`` move asked to take less time than the limits allow."""

    index: int  # position of the step in the motion (0-based)
    phase: str
    requested: float  # s, whole physics steps
    minimum: float  # s, the limits' exact minimum (ruckig)
    needed: float  # s, the shortest duration that passes: minimum rounded up to whole steps


def short_move(
    profile: LimitedProfile,
    index: int,
    phase: str,
    start: np.ndarray,
    goal: np.ndarray,
    n: int,
    dt: float,
) -> ShortMove | None:
    """The move ``index`` of a motion (``phase``), ``n`` steps of ``dt`` s from ``start`` to
    ``goal`` (arm units) with ``profile``, as a :class:`ShortMove` if it is too short for the
    limits (the same test as the profile's own, so both agree), else None. The motion planner
    (:func:`so101sim.motion.plan.plan_segments`) asks this of every ``limited`` move, from the
    start it planned for it."""
    t_min = profile.minimum_duration(start, goal)
    needed = minimum_steps(t_min, dt)
    if n >= needed:
        return None
    return ShortMove(index, phase, n * dt, t_min, needed * dt)


def too_short(short: Sequence[ShortMove], dt: float) -> TrajectoryLimitError:
    """The error that refuses a motion (strict mode) whose ``limited`` moves ``short`` are too
    short for the joint limits, naming the first."""
    s = short[0]
    return TrajectoryLimitError(
        f"step {s.index + 1} ({escape_controls(s.phase, lines=False)}) asks for "
        f"{s.requested:.3f} s but the joint limits "
        f"need at least {s.needed:.3f} s ({s.minimum:.4f} s rounded up to whole "
        f"{dt * 1000:g} ms steps); lengthen it to {s.needed:.3f} s or more, or run "
        f"without --strict to stretch it ({len(short)} move(s) too short in all)"
    )


__all__ = [
    "STS3215_LIMITS",
    "JointLimits",
    "LimitedProfile",
    "ShortMove",
    "minimum_steps",
    "short_move",
    "too_short",
]
