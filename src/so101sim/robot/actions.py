"""What the simulated follower does with a LeRobot action before the arm sees it.

:func:`parse_action` checks the keys and values (bad input raises, and nothing changes);
:func:`clamp_relative` applies ``max_relative_target`` as LeRobot's
``ensure_safe_goal_position`` does; :func:`clip_to_limits` clips goals to the joint limits, as
the servos' position limits do on the real arm. The two safety steps return what they changed,
in LeRobot's warning layout, for the robot to log.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence

import numpy as np

from ..errors import JointNameError, JointValueError
from ..units import JOINT_NAMES, LEROBOT_SUFFIX, check_number
from .helpers import MOTOR_KEYS

CLAMP_TOLERANCE = 1e-4
"""Goals moved by at most this much by ``max_relative_target`` are not reported (LeRobot's)."""
CLIP_WARN_TOLERANCE = 1e-3
"""Goals this close to a limit are clipped without being reported."""

Changes = dict[str, dict[str, object]]
"""Per joint name, what a safety step changed (LeRobot's warning layout)."""


def parse_action(action: object) -> dict[str, float]:
    """Validate a LeRobot action: ``{"<joint>.pos": finite number}`` for some of the six joints.

    Returns ``{joint name: value}``. Raises before anything changes:

    Raises:
        JointNameError: not a dict, or a key that is not one of the six ``"<joint>.pos"`` keys
            (the message lists them).
        JointValueError: a value that is not a finite real number.
    """
    if not isinstance(action, Mapping):
        raise JointNameError(
            f"an action must be a dict keyed by {', '.join(MOTOR_KEYS)}, got "
            f"{type(action).__name__}"
        )
    goals = {}
    for key, value in action.items():  # the common case, checked in a few operations
        if type(value) is float and type(key) is str and key in _NAMES and math.isfinite(value):
            goals[_NAMES[key]] = value
        else:
            return dict(_action_item(k, v) for k, v in action.items())
    return goals


_NAMES = {key: key[: -len(LEROBOT_SUFFIX)] for key in MOTOR_KEYS}
JOINT_INDEX = {name: i for i, name in enumerate(JOINT_NAMES)}
"""Joint name -> its index in :data:`JOINT_NAMES`."""


def _action_item(key: object, value: object) -> tuple[str, float]:
    """``("<joint>.pos", value)`` -> ``(joint name, value as a float)``, checked."""
    if not (isinstance(key, str) and key in MOTOR_KEYS):
        raise JointNameError(
            f"unknown action key {key!r}; valid keys are {', '.join(MOTOR_KEYS)} "
            "(the robot's action_features)"
        )
    name = key[: -len(LEROBOT_SUFFIX)]
    try:
        return name, check_number(name, value)
    except JointValueError as exc:
        raise JointValueError(f"action {key!r}: {exc}") from None


def clamp_relative(
    names: Sequence[str], goal: np.ndarray, present: np.ndarray, caps: np.ndarray | None
) -> tuple[np.ndarray, Changes]:
    """Clamp each goal to ``present ± cap`` (``caps`` from
    :func:`~so101sim.robot.config.relative_caps`, None: no cap).

    ``names``, ``goal`` and ``present`` list the same joints. Returns the safe goals and, per
    joint moved by more than :data:`CLAMP_TOLERANCE`, its original and safe goal.
    """
    if caps is None:
        return goal, {}
    cap = caps[[JOINT_NAMES.index(n) for n in names]]
    safe = present + np.clip(goal - present, -cap, cap)
    changes: Changes = {
        n: {"original goal_pos": float(g), "safe goal_pos": float(s)}
        for n, g, s in zip(names, goal, safe, strict=True)
        if abs(s - g) > CLAMP_TOLERANCE
    }
    return safe, changes


def clip_to_limits(
    names: Sequence[str], goal: Sequence[float], limits: tuple[Sequence[float], Sequence[float]]
) -> tuple[list[float], Changes]:
    """Clip each goal to its joint's ``limits`` (``(lower, upper)``, six values each in
    :data:`JOINT_NAMES` order, arm units). Returns the clipped goals and, per joint moved by
    more than :data:`CLIP_WARN_TOLERANCE`, its original and clipped goal and the limits."""
    lo, hi = limits
    clipped: list[float] = []
    changes: Changes = {}
    for n, g in zip(names, goal, strict=True):
        i = JOINT_INDEX[n]
        low, high = float(lo[i]), float(hi[i])
        c = low if g < low else high if g > high else float(g)
        clipped.append(c)
        if abs(c - g) > CLIP_WARN_TOLERANCE:
            changes[n] = {
                "original goal_pos": float(g),
                "clipped goal_pos": c,
                "limits": (low, high),
            }
    return clipped, changes
