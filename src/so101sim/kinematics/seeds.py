"""Where IK's attempts start: closed-form answers of the planar chain for the likeliest
wrist rolls and pitches, then random in-limit poses.

The closed form (:func:`.geometry.closed_form`) needs a tip position, a pitch and a wrist
roll. A goal fixes some of them; the others are tried in turn, the likeliest first:

* an asked pitch and roll are used as they are;
* an approach direction gives the pitch (pointing forward or back), and the wrist roll that
  turns the arm's plane onto it (the tip sits 7.9 mm off the roll axis, so the roll moves the
  plane);
* a whole tool frame gives the pitch and roll for each way the arm can face;
* what is left free starts at the warm start's value, then steps away from it: the roll by
  30°, a position-only goal's pitch by 10°.
"""

from __future__ import annotations

import math
from collections.abc import Iterator

import numpy as np

from .core import Kinematics, cross
from .geometry import PlanarArm, closed_form, planar_arm_of
from .goal import Goal

PITCH_STEP = math.radians(10.0)
"""Position only: the pitches tried in closed form, this far apart from the warm start's."""
ROLL_STEP = math.radians(30.0)
"""A free roll: the wrist rolls tried in closed form, this far apart from the warm start's."""


def _wrap(angle: float) -> float:
    return (angle + math.pi) % (2.0 * math.pi) - math.pi


def _around(start: float, step: float) -> list[float]:
    """``start``, then ``start ± step``, ``± 2 step``, ... once round the circle."""
    n = round(math.pi / step)
    turns = [sign * k * step for k in range(1, n + 1) for sign in (1, -1)]
    return [start] + [_wrap(start + t) for t in turns[:-1]]


def _headings(goal: Goal, arm: PlanarArm) -> list[float]:
    """Headings of the arm's plane that can hold the asked pointing direction."""
    a = goal.approach if goal.rotation is None else goal.rotation[:, 0]
    if a is not None and math.hypot(a[0], a[1]) > 1e-6:
        h = math.atan2(a[1], a[0])
    else:  # pointing straight up or down: face the target
        h = math.atan2(goal.position[1] - arm.pan_point[1], goal.position[0] - arm.pan_point[0])
    return [h, _wrap(h + math.pi)]


def _facing(goal: Goal, heading: float, roll0: float) -> tuple[float, float]:
    """(pitch, wrist roll) of the asked tool frame for the arm's plane at ``heading``."""
    assert goal.rotation is not None
    a, side = goal.rotation[:, 0], goal.rotation[:, 1]
    h = np.array([math.cos(heading), math.sin(heading), 0.0])
    n = np.array([-math.sin(heading), math.cos(heading), 0.0])
    roll = math.atan2(-(cross(n, side) @ a), n @ side)
    return math.atan2(a[2], a @ h), _wrap(roll - roll0)


def _candidates(
    arm: PlanarArm, goal: Goal, start: np.ndarray, start_pitch: float, roll0: float
) -> Iterator[tuple[float, float]]:
    """``(pitch, wrist_roll)`` pairs for the closed form, the likeliest first."""
    if goal.rotation is not None:
        for heading in _headings(goal, arm):
            yield _facing(goal, heading, roll0)
        return
    if goal.approach is not None and goal.roll is None:
        yield from _along_approach(arm, goal, goal.approach)
    rolls = [_wrap(goal.roll - roll0)] if goal.roll is not None else _around(start[4], ROLL_STEP)
    for roll in rolls:
        for pitch in _pitches(goal, start_pitch):
            yield pitch, roll


def _along_approach(arm: PlanarArm, goal: Goal, a: np.ndarray) -> Iterator[tuple[float, float]]:
    """(pitch, wrist roll) pairs that put the arm's plane along a tilted approach: the tip
    sits off the roll axis, so the roll sets how far the plane passes beside the pan axis."""
    level = math.hypot(a[0], a[1])
    if level <= 1e-6:  # straight up or down: any plane will do
        return
    dx, dy = goal.position[0] - arm.pan_point[0], goal.position[1] - arm.pan_point[1]
    for heading, sign in zip(_headings(goal, arm), (1.0, -1.0), strict=True):
        lateral = -dx * math.sin(heading) + dy * math.cos(heading)
        for roll in arm.rolls_for_lateral(lateral):
            yield math.atan2(a[2], sign * level), roll


def _pitches(goal: Goal, start_pitch: float) -> list[float]:
    if goal.pitch is not None:
        return [goal.pitch]
    if goal.approach is not None:
        a = goal.approach
        level = math.hypot(a[0], a[1])
        return [math.atan2(a[2], level), math.atan2(a[2], -level)]
    return _around(start_pitch, PITCH_STEP)  # position only: keep the tool's pitch if it reaches


def seeds(kin: Kinematics, goal: Goal, start: np.ndarray) -> Iterator[np.ndarray]:
    """Closed-form starting points (radians, five body joints) inside the joint limits: for
    each candidate pitch and roll, the answers nearest ``start`` first. Call with
    ``kin.lock`` held."""
    arm = planar_arm_of(kin)
    if arm is None:
        return
    start_pitch = kin.frame_at(start).pitch
    for pitch, roll in _candidates(arm, goal, start, start_pitch, kin.roll_at_zero):
        found = [
            q
            for q in closed_form(arm, goal.position, pitch, roll)
            if np.all(q >= kin.lower - 1e-9) and np.all(q <= kin.upper + 1e-9)
        ]
        yield from sorted(found, key=lambda q: float(np.abs(q - start).sum()))


def random_starts(kin: Kinematics, goal: Goal, count: int, seed: int) -> Iterator[np.ndarray]:
    """``count`` random in-limit poses drawn with ``seed`` (an asked roll set on the wrist)."""
    rng = np.random.default_rng(seed)
    for _ in range(count):
        q0 = rng.uniform(kin.lower, kin.upper)
        if goal.roll is not None:  # the roll is the wrist_roll joint, offset: start there
            q0[4] = np.clip(_wrap(goal.roll - kin.roll_at_zero), kin.lower[4], kin.upper[4])
        yield q0
