"""How an environment's actions become the arm's joint targets (arm units: degrees, gripper
0-100), for the three control modes:

* ``"joint"``: the six targets themselves (absolute), as a LeRobot policy sends them to the
  real SO-101's ``send_action``;
* ``"joint_delta"``: a change of the targets per step, at most ``max_delta`` (degrees, or
  gripper units) per joint;
* ``"ee_delta"``: a move of the tip (dx, dy, dz metres in the base frame, at most ``ee_step``
  each; dpitch, droll degrees, at most ``ee_turn`` each) and the gripper's target (0-100),
  turned into joint targets with the kinematics module's inverse kinematics.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal, get_args

import mujoco
import numpy as np
from gymnasium import spaces

from ..errors import SettingError
from ..kinematics import for_model, solve_ik
from ..units import GRIPPER_INDEX, ArmUnits
from ..validation import check_choice, check_range, shown

ControlMode = Literal["joint", "joint_delta", "ee_delta"]
"""How an action is read: joint targets, joint steps, or end-effector steps."""
CONTROL_MODES: tuple[str, ...] = get_args(ControlMode)
EE_WORKSPACE_M = ((-0.1, 0.45), (-0.4, 0.4), (0.0, 0.45))
"""Where an ``ee_delta`` tip target is kept (x, y, z ranges in metres, base frame)."""
PITCH_RANGE_DEG = (-180.0, 180.0)


@dataclass(frozen=True)
class ControlSettings:
    """The control mode and its step limits (see the module's text)."""

    mode: ControlMode = "joint"
    max_delta: float = 10.0
    ee_step: float = 0.02
    ee_turn: float = 10.0

    def validated(self) -> ControlSettings:
        return ControlSettings(
            mode=check_choice(self.mode, "control mode", CONTROL_MODES),
            max_delta=check_range(self.max_delta, "max_delta", low=0.0, high=90.0, low_open=True),
            ee_step=check_range(
                self.ee_step, "ee_step", low=0.0, high=0.2, low_open=True, unit=" m"
            ),
            ee_turn=check_range(self.ee_turn, "ee_turn", low=0.0, high=90.0, low_open=True),
        )


class ActionMap:
    """Turns actions into joint targets for one model, keeping what the ``ee_delta`` mode
    integrates (the tip target, its pitch and roll)."""

    def __init__(self, model: mujoco.MjModel, units: ArmUnits, settings: ControlSettings) -> None:
        self.model = model
        self.kinematics = for_model(model)  # held: for_model's table holds none
        self.units = units
        self.settings = s = settings.validated()
        lower, upper = units.limits
        self.lower, self.upper = lower, upper
        if s.mode == "joint":
            low, high = lower, upper
        elif s.mode == "joint_delta":
            high = np.full(len(lower), s.max_delta)
            low = -high
        else:
            step, turn = s.ee_step, s.ee_turn
            low = np.array([-step, -step, -step, -turn, -turn, lower[GRIPPER_INDEX]])
            high = np.array([step, step, step, turn, turn, upper[GRIPPER_INDEX]])
        self.space = spaces.Box(low.astype(np.float32), high.astype(np.float32), dtype=np.float32)
        self._tip = np.zeros(3)
        self._pitch = 0.0
        self._roll = 0.0

    def reset(self, commanded: np.ndarray) -> None:
        """Start from the commanded pose (the ``ee_delta`` target is where it puts the tip)."""
        tip = self.kinematics.tip_array(commanded)
        self._tip, self._pitch, self._roll = tip.position.copy(), tip.pitch, tip.roll

    def targets(self, action: np.ndarray, commanded: np.ndarray) -> np.ndarray:
        """The joint targets (arm units, within the limits) for ``action``, the arm being
        commanded to ``commanded`` now.

        Raises:
            SettingError: the action has the wrong shape or holds NaN or inf.
        """
        try:  # a string, a dict or a huge int is not an action, as NaN or a wrong shape is not
            a = np.asarray(action, dtype=float).reshape(-1)
        except (TypeError, ValueError, OverflowError):
            a = np.full(0, np.nan)
        if a.shape != self.space.shape or not np.isfinite(a).all():
            raise SettingError(
                f"action {shown(action)} is invalid; expected {self.space.shape[0]} finite "
                f"numbers for control mode {self.settings.mode!r}"
            )
        if self.settings.mode in ("joint", "joint_delta"):
            return self.joint_targets(a, commanded)
        return self._ee_targets(np.clip(a, self.space.low, self.space.high), commanded)

    def joint_targets(self, a: np.ndarray, commanded: np.ndarray | None) -> np.ndarray:
        """The targets of valid (finite) ``joint``/``joint_delta`` actions: one action, or one
        row per world with ``commanded`` one row per world (a vector environment's worlds at
        once, elementwise: the same numbers as world by world). ``commanded`` is read only by
        ``joint_delta``."""
        a = np.clip(a, self.space.low, self.space.high)
        if self.settings.mode == "joint":
            return np.clip(a, self.lower, self.upper)
        return np.clip(commanded + a, self.lower, self.upper)

    def _ee_targets(self, a: np.ndarray, commanded: np.ndarray) -> np.ndarray:
        bounds = np.array(EE_WORKSPACE_M)
        tip = np.clip(self._tip + a[:3], bounds[:, 0], bounds[:, 1])
        pitch = float(np.clip(self._pitch + a[3], *PITCH_RANGE_DEG))
        roll = float(self._roll + a[4])
        ik = solve_ik(
            tip,
            pitch=pitch,
            roll=roll,
            initial=commanded,
            restarts=0,
            closest=True,
            model=self.model,
        )
        values = np.clip(ik.values, self.lower, self.upper)
        values[GRIPPER_INDEX] = a[5]
        if ik.reachable:
            self._tip, self._pitch, self._roll = tip, pitch, roll
        else:  # keep the target where the arm can be, so deltas do not pile up outside reach
            got = self.kinematics.tip_array(values)
            self._tip, self._pitch, self._roll = got.position.copy(), got.pitch, got.roll
        return values

    def action_for(self, target: np.ndarray, commanded: np.ndarray) -> np.ndarray:
        """The action that moves the targets from ``commanded`` towards ``target`` (arm
        units), as far as one step allows: what a scripted expert sends in any mode."""
        target = np.asarray(target, dtype=float)
        mode = self.settings.mode
        if mode == "joint":
            a = target
        elif mode == "joint_delta":
            a = target - commanded
        else:
            tip = self.kinematics.tip_array(target)
            turn = (np.array([tip.pitch - self._pitch, tip.roll - self._roll]) + 180) % 360 - 180
            a = np.concatenate([tip.position - self._tip, turn, [target[GRIPPER_INDEX]]])
        return np.clip(a, self.space.low, self.space.high).astype(np.float32)
