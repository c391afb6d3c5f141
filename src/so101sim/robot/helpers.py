"""Move and hold helpers for any robot with LeRobot's interface: the lab's motion, written once.

:func:`move_robot_to` and :func:`hold_robot` touch no hardware themselves: they only call
``robot.get_observation()`` and ``robot.send_action(...)`` and wait between calls, exactly as
code written for the real SO-101 through LeRobot does. So the same function drives:

* the real arm (LeRobot's ``SO101Follower``): waiting is ``time.sleep``;
* the simulated arm in real-time mode (:class:`so101sim.robot.SO101SimFollower`): the physics
  runs on its own while the helper sleeps;
* the simulated arm in lockstep mode: nothing moves unless simulated time is advanced, so
  waiting must advance it.

The difference lives in a :class:`Clock`: ``now()`` and ``sleep(seconds)``. :func:`clock_for`
asks the robot for its clock (``robot.clock``, which the simulated follower provides) and falls
back to the wall clock for anything else (the real arm). Waits go to absolute deadlines
(``t0 + i / fps``), so time spent in the robot's calls does not add up over a move.
"""

from __future__ import annotations

import logging
import time
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any, Protocol, runtime_checkable

import numpy as np

from ..errors import RateError
from ..units import JOINT_NAMES, LEROBOT_SUFFIX, Pose, parse_pose
from ..validation import MAX_RATE_HZ, check_duration, check_range

log = logging.getLogger(__name__)

MOTOR_KEYS: tuple[str, ...] = tuple(f"{n}{LEROBOT_SUFFIX}" for n in JOINT_NAMES)
"""LeRobot's keys for the six joints: ``"shoulder_pan.pos"`` ... ``"gripper.pos"``."""

DEFAULT_FPS = 50.0
"""Control rate of the helpers (goals per second), as in LeRobot's 50 Hz control loops."""


@runtime_checkable
class Clock(Protocol):
    """What the helpers need of time: read it, and wait a while."""

    def now(self) -> float:
        """The current time in seconds (any origin)."""
        ...

    def sleep(self, seconds: float) -> None:
        """Let ``seconds`` pass (the arm keeps moving meanwhile)."""
        ...


class WallClock:
    """The wall clock: ``time.perf_counter`` and ``time.sleep``. Right for the real arm."""

    def now(self) -> float:
        return time.perf_counter()

    def sleep(self, seconds: float) -> None:
        if seconds > 0:
            time.sleep(seconds)


def clock_for(robot: Any) -> Clock:
    """The clock to wait with on ``robot``: its ``clock`` attribute if it has one (the
    simulated follower), else the wall clock (LeRobot's robots)."""
    clock = getattr(robot, "clock", None)
    return clock if isinstance(clock, Clock) else WallClock()


def sleep_until(clock: Clock, deadline: float) -> None:
    """Wait until ``clock.now()`` reaches ``deadline`` (return at once if it has)."""
    remaining = deadline - clock.now()
    if remaining > 0:
        clock.sleep(remaining)


@dataclass(frozen=True)
class MotionRecord:
    """What a helper did, sampled once per control tick.

    ``target`` holds the goals sent last (LeRobot keys; empty for a hold, which sends none);
    ``reached`` is the observation after the last wait. ``times`` are the clock's times of the
    samples; ``observed`` (n, 6) the observed joint values (degrees, gripper 0–100) in
    :data:`~so101sim.units.JOINT_NAMES` order.
    """

    kind: str  # "move" | "hold"
    start_time: float
    end_time: float
    target: dict[str, float]
    reached: dict[str, float]
    actions_sent: int
    times: np.ndarray = field(repr=False)
    observed: np.ndarray = field(repr=False)

    @property
    def final_error(self) -> dict[str, float]:
        """``|target - reached|`` for each joint the helper commanded."""
        return {k: abs(v - self.reached[k]) for k, v in self.target.items()}


def _observed(obs: Mapping[str, Any]) -> np.ndarray:
    return np.array([float(obs[k]) for k in MOTOR_KEYS])


def _motors(obs: Mapping[str, Any]) -> dict[str, float]:
    return {k: float(obs[k]) for k in MOTOR_KEYS}


def check_fps(fps: object) -> float:
    """Return ``fps`` as a float if it is a finite number > 0 and at most
    :data:`~so101sim.validation.MAX_RATE_HZ`, else raise RateError."""
    return check_range(
        fps,
        "fps",
        low=0.0,
        high=MAX_RATE_HZ,
        low_open=True,
        expected=f"a finite number per second > 0, at most {MAX_RATE_HZ:g}",
        error=RateError,
    )


def move_robot_to(
    robot: Any,
    desired: Pose,
    duration: float,
    *,
    fps: float = DEFAULT_FPS,
    clock: Clock | None = None,
) -> MotionRecord:
    """Move ``robot`` in a straight line (per joint) from where it is to ``desired`` over
    ``duration`` seconds, sending ``fps`` goals per second.

    ``desired`` is keyed by joint name or LeRobot key (``"elbow_flex"`` or
    ``"elbow_flex.pos"``); joints left out are not commanded. The move starts from the
    observed position (a real arm does not tell its last goal), and the last goal sent is
    ``desired`` itself. Works on any robot with LeRobot's ``get_observation``/``send_action``.

    Raises (before anything moves): JointNameError/JointValueError for a bad pose,
    DurationError for a bad duration, RateError for a bad fps.
    """
    goal = parse_pose(desired, partial=True)
    duration = check_duration(duration)
    fps = check_fps(fps)
    clock = clock if clock is not None else clock_for(robot)
    names = list(goal)
    keys = [f"{n}{LEROBOT_SUFFIX}" for n in names]
    obs = robot.get_observation()
    start = np.array([float(obs[k]) for k in keys])
    end = np.array([goal[n] for n in names])
    n = max(1, round(duration * fps))
    t0 = clock.now()
    times, observed = [], []
    sent: dict[str, float] = {}
    for i in range(1, n + 1):
        if i > 1:
            obs = robot.get_observation()
        times.append(clock.now())
        observed.append(_observed(obs))
        s = i / n
        values = end if i == n else start + (end - start) * s
        sent = dict(robot.send_action(dict(zip(keys, values.tolist(), strict=True))))
        sleep_until(clock, t0 + i / fps)
    reached = _motors(robot.get_observation())
    log.debug("move to %s in %.3f s: %d goals", goal, duration, n)
    return MotionRecord(
        kind="move",
        start_time=t0,
        end_time=clock.now(),
        target={k: float(v) for k, v in sent.items()},
        reached=reached,
        actions_sent=n,
        times=np.array(times),
        observed=np.array(observed).reshape(-1, len(JOINT_NAMES)),
    )


def hold_robot(
    robot: Any,
    duration: float,
    *,
    fps: float = DEFAULT_FPS,
    clock: Clock | None = None,
) -> MotionRecord:
    """Hold the arm where it was last sent for ``duration`` seconds.

    The motors (real or simulated) keep their last goal by themselves, so this sends nothing:
    re-sending the *observed* position, as the lab handout did, lets the arm creep down under
    gravity. It only waits, reading the observation ``fps`` times per second.

    Raises: DurationError for a bad duration, RateError for a bad fps.
    """
    duration = check_duration(duration)
    fps = check_fps(fps)
    clock = clock if clock is not None else clock_for(robot)
    n = max(1, round(duration * fps))
    t0 = clock.now()
    times, observed = [], []
    for i in range(1, n + 1):
        obs = robot.get_observation()
        times.append(clock.now())
        observed.append(_observed(obs))
        sleep_until(clock, t0 + i / fps)
    reached = _motors(robot.get_observation())
    return MotionRecord(
        kind="hold",
        start_time=t0,
        end_time=clock.now(),
        target={},
        reached=reached,
        actions_sent=0,
        times=np.array(times),
        observed=np.array(observed).reshape(-1, len(JOINT_NAMES)),
    )


def wait_seconds(robot: Any, seconds: float) -> None:
    """Let ``seconds`` pass on ``robot``'s clock (``time.sleep`` on the real arm)."""
    clock_for(robot).sleep(check_duration(seconds, "seconds", allow_zero=True))


__all__ = [
    "DEFAULT_FPS",
    "MOTOR_KEYS",
    "Clock",
    "MotionRecord",
    "WallClock",
    "check_fps",
    "clock_for",
    "hold_robot",
    "move_robot_to",
    "sleep_until",
    "wait_seconds",
]
