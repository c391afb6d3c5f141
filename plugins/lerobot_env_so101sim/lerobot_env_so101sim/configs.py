"""The environments' configurations, registered with LeRobot's ``EnvConfig`` registry on import.

- ``--env.type=so101sim_pick_cube``: :class:`SO101SimPickCubeEnv` (``so101sim/PickCube-v0``);
- ``--env.type=so101sim_cube_to_bowl``: :class:`SO101SimCubeToBowlEnv`
  (``so101sim/CubeToBowl-v0``).

What a policy sees is what the robot plugin (``--robot.type=so101_sim``) records: the six joint
positions (``observation.state``: body joints in degrees, gripper 0-100, in the order of the
dataset's ``"<joint>.pos"`` names) and one image per camera (``observation.images.front``,
``observation.images.wrist``); the action is the six joint targets in the same units. So a
policy trained on a dataset recorded on the sim (``lerobot-record --robot.type=so101_sim``)
runs here unchanged: give the cameras the size they were recorded at
(``--env.observation_height``, ``--env.observation_width``) and the dataset's rate
(``--env.fps``, 30 by default as ``--dataset.fps``).

Every value is checked when the config is made (a bad command line fails before any
environment is built), by so101sim's own checks.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

from lerobot.configs import FeatureType, PolicyFeature
from lerobot.envs.configs import EnvConfig
from lerobot.utils.constants import ACTION, OBS_ENV_STATE, OBS_IMAGES, OBS_STATE

from so101sim.errors import SettingError
from so101sim.model.arm import load_profile
from so101sim.recording import QUALITY_CHOICES
from so101sim.scenes import PRESET_CAMERAS, SCENE_PRESETS
from so101sim.units import JOINT_NAMES
from so101sim.validation import check_choice, check_count, check_range

NAMESPACE = "so101sim"
"""The Gymnasium namespace of so101sim's environments (``so101sim/PickCube-v0``)."""
ENV_MODULE = "so101sim.envs"
"""The module whose import registers them (LeRobot imports ``package_name`` if needed)."""
TASK_SCENES = {"PickCube-v0": "pick_cube", "CubeToBowl-v0": "cube_to_bowl"}
"""Each task (``--env.task``) and the scene preset it is played in."""
MAX_IMAGE_SIDE = 4096


@dataclass
class SO101SimEnvConfig(EnvConfig):
    """A so101sim task for ``lerobot-eval`` (the registered subclasses pick the task)."""

    task: str | None = None
    fps: int = 30
    """Environment steps (policy actions) per simulated second: the dataset's fps."""
    episode_length: int | None = None
    """Steps before an episode is truncated (None: the task's time limit, 8 or 12 s)."""
    cameras: list[str] = field(default_factory=lambda: ["front", "wrist"])
    """Preset cameras whose images the policy sees (``observation.images.<camera>``)."""
    observation_height: int = 480
    observation_width: int = 640
    quality: str = "auto"
    """Meshes the cameras draw: ``auto`` (draft on a CPU, full on a GPU, as the robot
    plugin's cameras), ``draft`` or ``full``."""
    object_state: bool = False
    """Also give the objects' poses (``observation.environment_state``, 7 numbers each)."""
    reward: str = "dense"
    """``dense`` (0..1) or ``sparse`` (1 on success)."""
    render_mode: str = "rgb_array"
    arm: str | None = None
    """The arm profile (``--env.arm=``): ``sts3215`` (None: the default), ``official``,
    ``sts3215-12v`` or a TOML file; use the one the policy's dataset was recorded with
    (``--robot.arm``)."""
    visualization_height: int = 480
    visualization_width: int = 640
    """Size of the frames of lerobot-eval's videos (the ``front`` camera)."""

    def __post_init__(self) -> None:
        check_choice(self.task, "task", TASK_SCENES)
        self.fps = int(check_count(self.fps, "fps", minimum=1, maximum=500, unit=" Hz"))
        if self.episode_length is not None:
            check_count(self.episode_length, "episode_length", minimum=1, maximum=1_000_000)
        if not isinstance(self.cameras, list | tuple):
            raise SettingError(f"cameras = {self.cameras!r}; expected a list such as [front]")
        for cam in self.cameras:
            check_choice(cam, "camera", PRESET_CAMERAS)
        for name in ("observation_height", "observation_width"):
            check_count(getattr(self, name), name, minimum=2, maximum=MAX_IMAGE_SIDE, even=True)
        for name in ("visualization_height", "visualization_width"):
            check_count(getattr(self, name), name, minimum=2, maximum=MAX_IMAGE_SIDE, even=True)
        check_choice(self.quality, "quality", QUALITY_CHOICES)
        check_choice(self.reward, "reward", ("dense", "sparse"))
        check_choice(self.render_mode, "render_mode", ("rgb_array",))
        if self.arm is not None:
            load_profile(self.arm)  # an unknown profile fails now, naming the known ones
        self.features, self.features_map = self._features()

    def _features(self) -> tuple[dict[str, PolicyFeature], dict[str, str]]:
        n = len(JOINT_NAMES)
        features = {
            ACTION: PolicyFeature(type=FeatureType.ACTION, shape=(n,)),
            "agent_pos": PolicyFeature(type=FeatureType.STATE, shape=(n,)),
        }
        names = {ACTION: ACTION, "agent_pos": OBS_STATE}
        if self.object_state:
            objects = len(SCENE_PRESETS[TASK_SCENES[str(self.task)]].objects)
            state = PolicyFeature(type=FeatureType.ENV, shape=(7 * objects,))
            features["environment_state"] = state
            names["environment_state"] = OBS_ENV_STATE
        shape = (self.observation_height, self.observation_width, 3)
        for cam in self.cameras:
            features[f"pixels/{cam}"] = PolicyFeature(type=FeatureType.VISUAL, shape=shape)
            names[f"pixels/{cam}"] = f"{OBS_IMAGES}.{cam}"
        return features, names

    @property
    def package_name(self) -> str:
        return ENV_MODULE

    @property
    def gym_id(self) -> str:
        return f"{NAMESPACE}/{self.task}"

    @property
    def gym_kwargs(self) -> dict[str, Any]:
        kwargs: dict[str, Any] = {
            "control": "joint",
            "control_hz": float(self.fps),
            "cameras": list(self.cameras),
            "image_size": (self.observation_height, self.observation_width),
            "quality": self.quality,
            "object_state": self.object_state,
            "reward": self.reward,
            "render_mode": self.render_mode,
            "render_size": (self.visualization_height, self.visualization_width),
            "terminate_on_success": True,
        }
        if self.arm is not None:
            kwargs["arm"] = self.arm
        if self.episode_length is not None:
            kwargs["episode_seconds"] = check_range(
                self.episode_length / self.fps, "episode_length / fps", low=0.0, high=3600.0
            )
        return kwargs


@EnvConfig.register_subclass("so101sim_pick_cube")
@dataclass
class SO101SimPickCubeEnv(SO101SimEnvConfig):
    """Pick up the 2.5 cm cube (``so101sim/PickCube-v0``, 8 s)."""

    task: str | None = "PickCube-v0"


@EnvConfig.register_subclass("so101sim_cube_to_bowl")
@dataclass
class SO101SimCubeToBowlEnv(SO101SimEnvConfig):
    """Put the cube in the bowl (``so101sim/CubeToBowl-v0``, 12 s)."""

    task: str | None = "CubeToBowl-v0"


__all__ = [
    "ENV_MODULE",
    "NAMESPACE",
    "TASK_SCENES",
    "SO101SimCubeToBowlEnv",
    "SO101SimEnvConfig",
    "SO101SimPickCubeEnv",
]
