"""End-effector actions for the LeRobot-style follower: "put the tip there" as a joint action.

LeRobot drives the real SO-101 by end effector through a processor pipeline (a target or a
delta for the tip, bounds and a step limit, then inverse kinematics with placo). This is the
same for the simulated arm, in one call, with so101sim's own kinematics::

    from so101sim.robot.ee import ee_action

    obs = robot.get_observation()
    robot.send_action(ee_action(obs, tip=(0.20, 0.0, 0.05), pitch=-90))

:func:`ee_action` reads the joint positions in an observation (LeRobot's ``"<joint>.pos"``
keys; other keys, e.g. cameras, are ignored), computes where the tip is, moves the asked
target at most ``max_step_m`` (default :data:`MAX_STEP_M`, 1 cm) and ``max_angle_step_deg``
(default :data:`MAX_ANGLE_STEP_DEG`, 5°) from there along the straight line, and solves
inverse kinematics for it warm-started from the observed joints. Called once per control tick
(50 Hz: at most 0.5 m/s and 250°/s) it walks the tip to the target; :class:`EndEffectorController`
does the reading, the call and the sending. The action holds the five body joints (degrees),
and the gripper (0-100) only when ``gripper`` is given, so the gripper's own goal is left alone.

A target out of reach raises :class:`~so101sim.errors.UnreachableError` (nothing is sent), or
with ``clip=True`` the closest pose the tip can reach is used.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import mujoco
import numpy as np

from ..errors import JointNameError, SettingError
from ..kinematics import TipPose, for_model, solve_ik
from ..model.load import arm_units, load_model
from ..units import GRIPPER, GRIPPER_INDEX, JOINT_NAMES, LEROBOT_SUFFIX, check_number
from ..validation import check_positive, check_range

MAX_STEP_M = 0.01
"""The default largest move of the tip's target per call, in metres (0.5 m/s at 50 Hz)."""

MAX_ANGLE_STEP_DEG = 5.0
"""The default largest turn of the asked pitch or roll per call, in degrees."""

MAX_TARGET_M = 2.0
"""The largest |x|, |y| or |z| of a target accepted, in metres (the arm reaches 0.48 m)."""


def _model_of(source: Any, model: mujoco.MjModel | None) -> mujoco.MjModel:
    if model is not None:
        return model
    sim = getattr(source, "simulation", None)  # SO101SimFollower: its own model
    return sim.model if sim is not None else load_model()


def observed_values(observation: Mapping[str, Any], model: mujoco.MjModel) -> np.ndarray:
    """The six joints of a LeRobot observation (``"<joint>.pos"``) in arm units, each brought
    inside its limits (a joint resting on its stop may read a little past it).

    Raises:
        JointNameError: a joint's key is missing. JointValueError: a value is not a number.
    """
    values = np.empty(len(JOINT_NAMES))
    for i, name in enumerate(JOINT_NAMES):
        key = name + LEROBOT_SUFFIX
        if key not in observation:
            raise JointNameError(
                f"the observation has no {key!r}; expected the six joints' keys "
                f"({', '.join(n + LEROBOT_SUFFIX for n in JOINT_NAMES)}), as "
                "SO101SimFollower.get_observation() returns them"
            )
        values[i] = check_number(name, observation[key])
    lower, upper = arm_units(model).limits
    return np.clip(values, lower, upper)


def _wrap(deg: float) -> float:
    """An angle difference in -180..180 degrees."""
    return (deg + 180.0) % 360.0 - 180.0


@dataclass(frozen=True)
class _Step:
    """Where the tip is asked to go in this call: a position and the angles (or None)."""

    position: np.ndarray
    pitch: float | None
    roll: float | None


def _bounded(
    now: TipPose,
    goal: np.ndarray,
    pitch: float | None,
    roll: float | None,
    max_step_m: float,
    max_angle_deg: float,
) -> _Step:
    """The point at most ``max_step_m`` from the tip towards ``goal``, and the angles turned
    as far along (at most ``max_angle_deg``); all the way if within both."""
    turns = [_wrap(a - b) for a, b in ((pitch, now.pitch), (roll, now.roll)) if a is not None]
    distance = float(np.linalg.norm(goal - now.position))
    fraction = min(
        1.0,
        max_step_m / distance if distance > 0 else 1.0,
        *(max_angle_deg / abs(t) for t in turns if t != 0),
    )
    if fraction >= 1.0:
        return _Step(goal, pitch, roll)

    def turned(asked: float | None, current: float) -> float | None:
        return None if asked is None else _wrap(current + fraction * _wrap(asked - current))

    return _Step(
        now.position + fraction * (goal - now.position),
        turned(pitch, now.pitch),
        turned(roll, now.roll),
    )


def _target(now: TipPose, tip: Sequence[float] | None, delta: Sequence[float] | None) -> np.ndarray:
    if (tip is None) == (delta is None):
        raise SettingError("give tip=(x, y, z) or delta=(dx, dy, dz) metres, exactly one of them")
    what, given = ("tip", tip) if tip is not None else ("delta", delta)
    vector = isinstance(given, np.ndarray | Sequence) and not isinstance(given, str | bytes)
    if not vector or len(given) != 3:  # type: ignore[arg-type]
        raise SettingError(f"{what} = {given!r} is not three numbers; expected (x, y, z) metres")
    xyz = np.array(
        [
            check_range(v, f"{what} {a}", low=-MAX_TARGET_M, high=MAX_TARGET_M, unit=" m")
            for a, v in zip("xyz", given, strict=True)  # type: ignore[arg-type]
        ]
    )
    return xyz if tip is not None else now.position + xyz


def _step_bounds(max_step_m: object, max_angle_step_deg: object) -> tuple[float, float]:
    """The step bounds, checked: metres in (0, 0.1], degrees in (0, 180]."""
    return (
        check_positive(max_step_m, "max_step_m", maximum=0.1, unit=" m"),
        check_positive(max_angle_step_deg, "max_angle_step_deg", maximum=180.0, unit="°"),
    )


def ee_action(
    source: Mapping[str, Any] | Any,
    *,
    tip: Sequence[float] | None = None,
    delta: Sequence[float] | None = None,
    pitch: float | None = None,
    roll: float | None = None,
    gripper: float | None = None,
    max_step_m: float = MAX_STEP_M,
    max_angle_step_deg: float = MAX_ANGLE_STEP_DEG,
    clip: bool = False,
    model: mujoco.MjModel | None = None,
) -> dict[str, float]:
    """A joint action (``{"<joint>.pos": value}``, degrees; gripper 0-100) that moves the tip
    one bounded step towards a target.

    Args:
        source: an observation (LeRobot's keys) or a robot with ``get_observation()`` (read
            once here).
        tip: the target (x, y, z), metres in the base frame (x forward, y left, z up); or
        delta: the target relative to where the tip is now (metres). Exactly one of them;
            each coordinate within ±:data:`MAX_TARGET_M`.
        pitch, roll: the tool's asked angles in degrees (-180..180; pitch -90 points straight
            down); None keeps them free (IK stays near the present ones).
        gripper: the gripper's goal (0-100), or None to leave it out of the action.
        max_step_m: the most the tip's target moves from the tip in this call, metres
            (> 0, at most 0.1); max_angle_step_deg: the most pitch or roll turns (> 0, at
            most 180). The step is along the straight line to the target.
        clip: for a target out of reach, the closest reachable pose instead of an error.
        model: the model to solve on (default: the robot's own, else the shipped one).

    Raises:
        UnreachableError: the step's target is out of reach (unless ``clip``).
        SettingError, JointNameError, JointValueError: bad numbers or keys.
    """
    step_m, step_deg = _step_bounds(max_step_m, max_angle_step_deg)
    asked = {k: v for k, v in (("pitch", pitch), ("roll", roll)) if v is not None}
    angles = {k: check_range(v, k, low=-180.0, high=180.0, unit="°") for k, v in asked.items()}
    m = _model_of(source, model)
    lower, upper = arm_units(m).limits
    lo, hi = float(lower[GRIPPER_INDEX]), float(upper[GRIPPER_INDEX])
    grip = None if gripper is None else check_range(gripper, "gripper", low=lo, high=hi)
    observation = source if isinstance(source, Mapping) else source.get_observation()
    current = observed_values(observation, m)
    now = for_model(m).tip_array(current)
    goal = _target(now, tip, delta)
    step = _bounded(now, goal, angles.get("pitch"), angles.get("roll"), step_m, step_deg)
    result = solve_ik(
        step.position, pitch=step.pitch, roll=step.roll, initial=current, closest=clip, model=m
    )
    action = {
        name + LEROBOT_SUFFIX: float(v)
        for name, v in zip(JOINT_NAMES, result.values, strict=True)
        if name != GRIPPER
    }
    if grip is not None:
        action[GRIPPER + LEROBOT_SUFFIX] = grip
    return action


@dataclass
class EndEffectorController:
    """Drives a robot (``get_observation``/``send_action``, e.g. :class:`SO101SimFollower`)
    by its tip: each :meth:`send` computes :func:`ee_action` with this controller's step
    bounds and sends it.

    Each step starts from the pose this controller commanded last (the measured pose before
    its first send, or after :meth:`reset`): a real servo sags under the arm's weight and lags
    its goal (the default arm profile, ``sts3215``, by a centimetre or more at the tip), and
    steps taken from the measured tip would chase the sag (each target a step from a tip that
    sits lower than the last target) and stall short of the goal. So the target moves at most
    ``max_step_m`` per call, and the arm follows it as its servos do.

    Example (50 Hz, lockstep: each ``send_action`` advances 0.02 s)::

        ee = EndEffectorController(robot, max_step_m=0.005)
        for _ in range(100):
            ee.send(tip=(0.20, 0.0, 0.05), pitch=-90)
    """

    robot: Any
    max_step_m: float = MAX_STEP_M
    max_angle_step_deg: float = MAX_ANGLE_STEP_DEG
    clip: bool = False

    def __post_init__(self) -> None:
        self.max_step_m, self.max_angle_step_deg = _step_bounds(
            self.max_step_m, self.max_angle_step_deg
        )
        self._sent: dict[str, float] | None = None

    def reset(self) -> None:
        """Forget the last target: the next step starts from the measured pose."""
        self._sent = None

    def tip(self) -> TipPose:
        """Where the robot's tip is now (from one observation)."""
        m = _model_of(self.robot, None)
        return for_model(m).tip_array(observed_values(self.robot.get_observation(), m))

    def action(self, **target: Any) -> dict[str, float]:
        """:func:`ee_action` from the last target sent (a fresh observation before the first;
        ``tip=``/``delta=``, ``pitch=``, ...)."""
        source: Any = self.robot
        if self._sent is not None:
            observation = dict(self.robot.get_observation())
            observation.update(self._sent)  # the joints as commanded, the rest as measured
            source = observation
        return ee_action(
            source,
            max_step_m=self.max_step_m,
            max_angle_step_deg=self.max_angle_step_deg,
            clip=self.clip,
            model=_model_of(self.robot, None),
            **target,
        )

    def send(self, **target: Any) -> dict[str, float]:
        """Compute :meth:`action` and send it; returns what the robot sent."""
        sent = self.robot.send_action(self.action(**target))
        body = {k: float(v) for k, v in sent.items() if k != GRIPPER + LEROBOT_SUFFIX}
        self._sent = body if len(body) == len(JOINT_NAMES) - 1 else None
        return sent


__all__ = [
    "MAX_ANGLE_STEP_DEG",
    "MAX_STEP_M",
    "MAX_TARGET_M",
    "EndEffectorController",
    "ee_action",
    "observed_values",
]
