"""``SO101Sim``: LeRobot's ``Robot`` for the simulated SO-101 follower (``--robot.type=so101_sim``).

It delegates to :class:`so101sim.robot.SO101SimFollower` (``self.follower``) and behaves as
LeRobot's ``SO101Follower`` does where LeRobot's code depends on it:

- the same observation and action keys (six ``"<joint>.pos"``, body joints in degrees, the
  gripper 0..100; one ``(h, w, 3)`` uint8 frame per camera), so datasets and policies move
  between the real arm and the sim;
- action values may be 0-d torch tensors or NumPy scalars (``lerobot-replay`` sends tensors);
  keys that do not end in ``.pos`` are ignored, as the real follower ignores them;
- LeRobot's ``DeviceNotConnectedError``/``DeviceAlreadyConnectedError`` (:mod:`.errors`);
- ``robot.cameras``: LeRobot ``Camera`` objects (``len(robot.cameras)`` sizes the image writer).

``name`` (stored as each dataset's ``robot_type``, compared by ``lerobot-record --resume``) is
``"so101_sim"``, on purpose not the real follower's ``"so_follower"``: a dataset says whether
it was recorded on the simulation. The features are the same, so a policy trained on either
runs on the other.

Time: see :class:`~.config_so101sim.SO101SimConfig` ``mode``. In lockstep mode every
``send_action`` advances simulated time to ``t0 + n/fps`` (``n`` actions since ``connect``),
so a loop at ``--fps N`` advances exactly ``1/N`` s per step, with no drift from rounding to
whole 2 ms physics steps.

Exit: a connected robot is disconnected when it is garbage-collected and at interpreter exit
(``weakref.finalize``), so the physics and render threads never outlive the program.
"""

from __future__ import annotations

import logging
import weakref
from typing import Any

from lerobot.robots import Robot

from so101sim.robot import SO101SimFollower, robot_scene, scene_resets

from .camera import SO101SimCamera
from .config_so101sim import ROBOT_TYPE, SO101SimConfig
from .errors import lerobot_errors, raises_lerobot_errors

log = logging.getLogger(__name__)

SUFFIX = ".pos"
ENVIRONMENT_STATE = "environment_state"
"""The observation's key for the objects' state (``--robot.environment_state=true``)."""


def _scalar(value: Any) -> Any:
    """A 0-d tensor or array (or NumPy scalar) as a Python number; anything else unchanged
    (so101sim then says what is wrong with it)."""
    if getattr(value, "ndim", None) == 0 and hasattr(value, "item"):
        return value.item()
    return value


def _disconnect(follower: SO101SimFollower) -> None:
    """The finalizer: disconnect ``follower`` if it is still connected."""
    try:
        if follower.is_connected:
            follower.disconnect()
    except Exception as exc:  # at exit or in GC: say it, never raise
        log.warning("so101_sim: disconnecting at exit failed: %s", exc)


class SO101Sim(Robot):
    """The simulated SO-101 follower as a LeRobot robot (see the module's documentation)."""

    config_class = SO101SimConfig
    name = ROBOT_TYPE

    def __init__(self, config: SO101SimConfig) -> None:
        super().__init__(config)
        self.config = config
        with lerobot_errors():
            self.follower = SO101SimFollower(config.follower_config())
        sources = self.follower.cameras
        self.cameras: dict[str, SO101SimCamera] = {
            name: SO101SimCamera(cam, source=sources[name])  # type: ignore[arg-type]
            for name, cam in config.cameras.items()
        }
        self._actions = 0
        self._t0 = 0.0
        self._resets = 0
        self._finalizer = weakref.finalize(self, _disconnect, self.follower)

    # ------------------------------------------------------------------ features
    @property
    def _motors_ft(self) -> dict[str, type]:
        return dict(self.follower.action_features)

    @property
    def _cameras_ft(self) -> dict[str, tuple[int, int, int]]:
        return {n: (c.height, c.width, 3) for n, c in self.cameras.items()}  # type: ignore[misc]

    @property
    def observation_features(self) -> dict[str, type | tuple[int, int, int]]:
        return {**self._motors_ft, **self._cameras_ft}

    @property
    def action_features(self) -> dict[str, type]:
        return self._motors_ft

    # ------------------------------------------------------------------ connection
    @property
    def is_connected(self) -> bool:
        return self.follower.is_connected

    @property
    def is_calibrated(self) -> bool:
        return True

    @raises_lerobot_errors
    def connect(self, calibrate: bool = True) -> None:
        self.follower.connect(calibrate=calibrate)
        self._actions = 0
        self._t0 = self.follower.time
        self._resets = scene_resets(self.follower)

    def calibrate(self) -> None:
        """Nothing to do: the simulated joints are calibrated by construction."""
        self.follower.calibrate()

    def configure(self) -> None:
        self.follower.configure()

    @raises_lerobot_errors
    def disconnect(self) -> None:
        self.follower.disconnect()

    # ------------------------------------------------------------------ data
    @raises_lerobot_errors
    def get_observation(self) -> dict[str, Any]:
        obs = self.follower.get_observation()
        resets = scene_resets(self.follower)
        if resets != self._resets:  # a new take on the scene: its frames count from here,
            self._resets, self._actions, self._t0 = resets, 0, self.follower.time  # as in envs
        if self.config.environment_state:
            obs[ENVIRONMENT_STATE] = robot_scene(self.follower).environment_state()
        return obs

    @property
    def environment_state_size(self) -> int:
        """The length of ``observation["environment_state"]`` (7 per object; 0 when
        ``environment_state`` is off)."""
        if not self.config.environment_state:
            return 0
        return robot_scene(self.follower).state_size

    @raises_lerobot_errors
    def send_action(self, action: dict[str, Any]) -> dict[str, Any]:
        """Send the ``"<joint>.pos"`` goals of ``action`` (other keys are ignored); in lockstep
        mode, then advance simulated time to ``t0 + n / fps``. Returns the goals sent (after
        ``max_relative_target`` and the joint limits)."""
        goals = {k: _scalar(v) for k, v in action.items() if str(k).endswith(SUFFIX)}
        sent = self.follower.send_action(goals)
        if self.config.mode == "lockstep":
            self._actions += 1
            due = self._t0 + self._actions / self.config.fps
            self.follower.step(max(0.0, due - self.follower.time))
        return sent

    # ------------------------------------------------------------------ sim extras
    @property
    def time(self) -> float:
        """Simulated time in seconds."""
        return self.follower.time


__all__ = ["SO101Sim"]
