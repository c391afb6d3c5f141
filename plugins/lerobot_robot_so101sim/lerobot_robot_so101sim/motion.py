"""``SO101SimMotion``: a teleoperator without hardware that plays a TOML motion file
(``--teleop.type=so101_sim_motion [--teleop.motion=FILE]``), so a dataset can be recorded on
the simulation without a leader arm.

The motion is planned as ``so101sim run`` would command it (:func:`so101sim.motion.
commanded_path`, one target per 2 ms physics step), and ``get_action()`` returns the target at
the motion's clock, which moves on by ``1/fps`` per call: the actions follow the loop's frames,
not the wall clock, so a dataset holds the whole motion however slowly the loop runs.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from so101sim import lab_motion_path, load_motion
from so101sim.model import arm_units, load_model
from so101sim.motion import Move, Segment, commanded_path
from so101sim.robot import MOTOR_KEYS
from so101sim.units import JOINT_NAMES

from .config_so101sim import MOTION_TELEOP_TYPE, SO101SimMotionConfig
from .errors import DeviceAlreadyConnectedError, DeviceNotConnectedError
from .leader import SimLeader


class SO101SimMotion(SimLeader):
    """Plays a motion file as a leader arm's positions (see the module's documentation)."""

    config_class = SO101SimMotionConfig
    name = MOTION_TELEOP_TYPE

    def __init__(self, config: SO101SimMotionConfig) -> None:
        super().__init__(config)
        self.config = config
        self._model = load_model(config.model)
        self._units = arm_units(self._model)
        self.motion = load_motion(config.motion or lab_motion_path(), units=self._units)
        self._dt = float(self._model.opt.timestep)
        self._rng = np.random.default_rng(config.seed)
        self._connected = False
        self._calls = 0
        self._take = -1
        self._start = self._units.pose_to_array(self.motion.start)
        self._path = np.zeros((0, len(JOINT_NAMES)))
        self.takes = 0
        """How many takes (passes through the motion) have started."""

    @property
    def duration(self) -> float:
        """The motion's length in seconds (one take)."""
        return len(self._plan(vary=False)) * self._dt

    def connect(self, calibrate: bool = True) -> None:
        """Plan the first take; the motion starts from its beginning."""
        if self._connected:
            raise DeviceAlreadyConnectedError(f"{self} is already connected.")
        self._calls, self._take, self.takes = 0, -1, 0
        self._path = self._plan(vary=True)
        self._connected = True

    def get_action(self) -> dict[str, float]:
        """The motion's target at ``calls / fps`` seconds (degrees; gripper 0..100)."""
        if not self._connected:
            raise DeviceNotConnectedError(f"{self} is not connected. Run `.connect()` first.")
        step = round(self._calls / (self.config.fps * self._dt))
        self._calls += 1
        n = len(self._path)
        take, i = divmod(step, n) if self.config.loop and n else (0, min(step, n))
        if take != self._take:
            if self._take >= 0:  # a new pass through the motion (the first was planned)
                self._path = self._plan(vary=True)
            self._take = take
            self.takes += 1
        row = self._start if i == 0 else self._path[i - 1]
        return dict(zip(MOTOR_KEYS, (float(v) for v in row), strict=True))

    # ------------------------------------------------------------------ internals
    def _plan(self, *, vary: bool) -> np.ndarray:
        """The targets of one take, (n, 6) arm units, one row per physics step."""
        steps: tuple[Segment, ...] = self.motion.steps
        if vary and self.config.variation > 0:
            steps = tuple(self._varied(s) for s in steps)
        _, path = commanded_path(self._model, steps, self.motion.start)
        return path

    def _varied(self, seg: Segment) -> Segment:
        if not isinstance(seg, Move) or seg.target is None:
            return seg
        v = self.config.variation
        goal = self._units.pose_to_array(seg.target) + self._rng.uniform(-v, v, len(JOINT_NAMES))
        lower, upper = self._units.limits
        return replace(seg, target=self._units.array_to_pose(np.clip(goal, lower, upper)))


__all__ = ["SO101SimMotion"]
