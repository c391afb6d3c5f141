"""The environments' configurations, registered with LeRobot's ``EnvConfig`` registry on import.

- ``--env.type=so101sim_pick_cube``: :class:`SO101SimPickCubeEnv` (``so101sim/PickCube-v0``);
- ``--env.type=so101sim_cube_to_bowl``: :class:`SO101SimCubeToBowlEnv`
  (``so101sim/CubeToBowl-v0``);
- ``so101sim_reach``, ``so101sim_lift_cylinder``, ``so101sim_lift_sphere``,
  ``so101sim_lift_mesh``, ``so101sim_push``, ``so101sim_stack``, ``so101sim_look_at``: the
  other tasks of ``so101sim.envs.TASKS`` (docs/tasks.md).

What a policy sees is what the robot plugin (``--robot.type=so101_sim``) records: the six joint
positions (``observation.state``: body joints in degrees, gripper 0-100, in the order of the
dataset's ``"<joint>.pos"`` names) and one image per camera (``observation.images.front``,
``observation.images.wrist``); the action is the six joint targets in the same units. So a
policy trained on a dataset recorded on the sim (``lerobot-record --robot.type=so101_sim``)
runs here unchanged: give the cameras the size they were recorded at
(``--env.observation_height``, ``--env.observation_width``) and the dataset's rate
(``--env.fps``, 30 by default as ``--dataset.fps``).

**Matching the policy.** Given a policy (``lerobot-eval --policy.path=...``, read from
LeRobot's command line, or ``--env.policy_path=...``; or :meth:`SO101SimEnvConfig.match_policy`
in code), the environment takes its cameras (``observation.images.<camera>``), their image
size and whether it gives ``observation.environment_state`` from the policy's input features,
so it observes what the policy was trained on. A setting given explicitly that differs from
the policy (``--env.observation_height=480`` for a policy trained on 96x96 images, a camera
list without one the policy needs), or an input the environment cannot give (a camera that is
not a preset, a state that is not the six joints), is refused with a message naming the
setting to change. The observations hold exactly the declared features (``agent_pos``, the
cameras' ``pixels``, ``environment_state`` when asked): the joint velocities the Gymnasium
environment can give (``agent_vel``), which LeRobot has no key for, are turned off.

Every value is checked when the config is made (a bad command line fails before any
environment is built), by so101sim's own checks.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from lerobot.configs import FeatureType, PolicyFeature
from lerobot.envs.configs import EnvConfig
from lerobot.utils.constants import ACTION, OBS_ENV_STATE, OBS_IMAGES, OBS_STATE

from so101sim.errors import SettingError
from so101sim.model import load_profile
from so101sim.recording import QUALITY_CHOICES
from so101sim.scenes import PRESET_CAMERAS, SCENE_PRESETS, load_cameras, randomization
from so101sim.units import JOINT_NAMES
from so101sim.validation import check_choice, check_count, check_range

NAMESPACE = "so101sim"
"""The Gymnasium namespace of so101sim's environments (``so101sim/PickCube-v0``)."""
ENV_MODULE = "so101sim.envs"
"""The module whose import registers them (LeRobot imports ``package_name`` if needed)."""
TASK_SCENES = {
    "PickCube-v0": "pick_cube",
    "CubeToBowl-v0": "cube_to_bowl",
    "Reach-v0": "pick_cube",
    "LiftCylinder-v0": "lift_cylinder",
    "LiftSphere-v0": "lift_sphere",
    "LiftMesh-v0": "lift_mesh",
    "Push-v0": "push",
    "Stack-v0": "stack",
    "LookAt-v0": "pick_cube",
}
"""Each task (``--env.task``) and the scene preset it is played in."""
TASK_EXTRA_STATE = {"Reach-v0": 6, "LookAt-v0": 2}
"""Numbers a task's ``environment_state`` holds after the objects' poses (reach: the target
and the tip, x y z each; look-at: where the wrist camera sees the cube, u v)."""


def state_size(task: str) -> int:
    """The length of ``task``'s ``environment_state``: 7 per object, then the task's own."""
    return 7 * len(SCENE_PRESETS[TASK_SCENES[task]].objects) + TASK_EXTRA_STATE.get(task, 0)


MAX_IMAGE_SIDE = 4096
DEFAULT_CAMERAS = ("front", "wrist")
DEFAULT_SIZE = (480, 640)
STATE_SIZE = len(JOINT_NAMES)


@dataclass
class SO101SimEnvConfig(EnvConfig):
    """A so101sim task for ``lerobot-eval`` (the registered subclasses pick the task)."""

    task: str | None = None
    fps: int = 30
    """Environment steps (policy actions) per simulated second: the dataset's fps."""
    episode_length: int | None = None
    """Steps before an episode is truncated (None: the task's time limit, 8 or 12 s)."""
    cameras: list[str] | None = None
    """Preset cameras whose images the policy sees (``observation.images.<camera>``); None:
    the policy's, or ``[front, wrist]`` without a policy."""
    camera_file: str | None = None
    """A TOML file of cameras of your own (docs/cameras.md): their names join the presets'
    as cameras the policy may read, and a preset's name there moves that preset."""
    observation_height: int | None = None
    observation_width: int | None = None
    """The cameras' image size; None: the policy's, or 480 x 640 without a policy."""
    quality: str = "auto"
    """Meshes the cameras draw: ``auto`` (draft on a CPU, full on a GPU, as the robot
    plugin's cameras), ``draft`` or ``full``."""
    object_state: bool | None = None
    """Also give the objects' poses (``observation.environment_state``, 7 numbers each);
    None: if the policy takes them (off without a policy)."""
    policy_path: str | None = None
    """The policy whose input features the environment matches (a folder with its
    ``config.json``, or a Hub id); None: ``--policy.path`` of LeRobot's command line, if any."""
    reward: str = "dense"
    """``dense`` (0..1) or ``sparse`` (1 on success)."""
    randomize: str = "none"
    """Domain randomisation per episode: ``none``, ``light`` or ``full`` (so101sim's presets,
    ``gym.make(..., randomize=...)``), or one with families changed (``light,textures=0.5``)."""
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
        self._given = {
            n for n in ("cameras", "observation_height", "observation_width", "object_state")
            if getattr(self, n) is not None
        }  # fmt: skip
        self._own = {c.name: c for c in load_cameras(self.camera_file)} if self.camera_file else {}
        if self.cameras is not None:
            if not isinstance(self.cameras, list | tuple):
                raise SettingError(f"cameras = {self.cameras!r}; expected a list such as [front]")
            for cam in self.cameras:
                check_choice(cam, "camera", [*PRESET_CAMERAS, *self._own])
            self.cameras = list(self.cameras)
        for name in ("observation_height", "observation_width"):
            if getattr(self, name) is not None:
                check_count(getattr(self, name), name, minimum=2, maximum=MAX_IMAGE_SIDE, even=True)
        if self.object_state is not None and not isinstance(self.object_state, bool):
            raise SettingError(f"object_state = {self.object_state!r}; expected true or false")
        for name in ("visualization_height", "visualization_width"):
            check_count(getattr(self, name), name, minimum=2, maximum=MAX_IMAGE_SIDE, even=True)
        check_choice(self.quality, "quality", QUALITY_CHOICES)
        check_choice(self.reward, "reward", ("dense", "sparse"))
        randomization(self.randomize)  # a preset, or one with families changed: raises
        check_choice(self.render_mode, "render_mode", ("rgb_array",))
        if self.arm is not None:
            load_profile(self.arm)  # an unknown profile fails now, naming the known ones
        self._fill_defaults()
        path = self.policy_path if self.policy_path is not None else _policy_path_argument()
        if path:
            self.match_policy(_policy_inputs(path), source=f"the policy at {path}")
        self.features, self.features_map = self._features()

    def _fill_defaults(self) -> None:
        if "cameras" not in self._given:
            self.cameras = list(DEFAULT_CAMERAS)
        if "observation_height" not in self._given:
            self.observation_height = DEFAULT_SIZE[0]
        if "observation_width" not in self._given:
            self.observation_width = DEFAULT_SIZE[1]
        if "object_state" not in self._given:
            self.object_state = False

    def match_policy(self, inputs: Any, *, source: str = "the policy") -> None:
        """Take the cameras, image size and environment state from a policy's input
        features (a ``PreTrainedConfig``, or its ``input_features`` dict): settings left
        unset follow the policy; settings given that differ are refused.

        Raises:
            SettingError: the policy needs what this environment cannot give, or a setting
                given explicitly differs from the policy (the message names it).
        """
        features = getattr(inputs, "input_features", inputs)
        if not isinstance(features, dict):
            raise SettingError(f"{source}: input features {features!r}; expected a dict")
        cams: dict[str, tuple[int, ...]] = {}
        env_state: tuple[int, ...] | None = None
        for key, ft in features.items():
            shape = tuple(int(v) for v in getattr(ft, "shape", ()))
            if key.startswith(f"{OBS_IMAGES}."):
                cams[key.removeprefix(f"{OBS_IMAGES}.")] = shape
            elif key == OBS_STATE:
                if shape != (STATE_SIZE,):
                    raise SettingError(
                        f"{source} takes {OBS_STATE} of shape {shape}; so101sim's environment "
                        f"gives the six joint positions ({STATE_SIZE},): train on a dataset "
                        f"recorded with --robot.type=so101_sim"
                    )
            elif key == OBS_ENV_STATE:
                env_state = shape
            else:
                raise SettingError(
                    f"{source} takes {key!r}, which so101sim's environment does not give; "
                    f"expected {OBS_STATE}, {OBS_ENV_STATE} and {OBS_IMAGES}.<camera> "
                    f"(map other names with lerobot-eval's --rename_map)"
                )
        for cam in cams:
            if cam not in PRESET_CAMERAS and cam not in self._own:
                raise SettingError(
                    f"{source} takes {OBS_IMAGES}.{cam}; so101sim's environment has the cameras "
                    f"{', '.join([*PRESET_CAMERAS, *self._own])}: give where {cam!r} is in a "
                    f"camera file (--env.camera_file, docs/cameras.md), or map the name with "
                    f"lerobot-eval's --rename_map "
                    f'(e.g. --rename_map=\'{{"{OBS_IMAGES}.{next(iter(PRESET_CAMERAS))}": '
                    f'"{OBS_IMAGES}.{cam}"}}\')'
                )
        sizes = {(s[-2], s[-1]) if len(s) == 3 and s[0] in (1, 3) else s[:2] for s in cams.values()}
        if len(sizes) > 1:
            raise SettingError(
                f"{source} takes images of several sizes {sorted(sizes)}; so101sim's environment "
                f"renders every camera at one size (--env.observation_height/_width)"
            )
        want_cams = list(cams)
        if "cameras" in self._given and sorted(self.cameras or []) != sorted(want_cams):
            raise SettingError(
                f"--env.cameras={self.cameras} but {source} takes the cameras {want_cams}; "
                f"give --env.cameras={want_cams!r} or leave --env.cameras out"
            )
        self.cameras = want_cams
        if sizes:
            h, w = sizes.pop()
            for name, value in (("observation_height", h), ("observation_width", w)):
                if name in self._given and getattr(self, name) != value:
                    raise SettingError(
                        f"--env.{name}={getattr(self, name)} but {source} was trained on "
                        f"{h}x{w} images (height x width); give --env.{name}={value} or leave "
                        f"it out"
                    )
            self.observation_height, self.observation_width = h, w
        size = state_size(str(self.task))
        if env_state is not None and env_state != (size,):
            raise SettingError(
                f"{source} takes {OBS_ENV_STATE} of shape {env_state}; {self.task} gives "
                f"({size},) (7 per object, then the task's own): it was trained on another task"
            )
        wants = env_state is not None
        if "object_state" in self._given and self.object_state != wants:
            raise SettingError(
                f"--env.object_state={str(self.object_state).lower()} but {source} "
                f"{'takes' if wants else 'does not take'} {OBS_ENV_STATE}; give "
                f"--env.object_state={str(wants).lower()} or leave it out"
            )
        self.object_state = wants
        self.features, self.features_map = self._features()

    def _features(self) -> tuple[dict[str, PolicyFeature], dict[str, str]]:
        n = len(JOINT_NAMES)
        features = {
            ACTION: PolicyFeature(type=FeatureType.ACTION, shape=(n,)),
            "agent_pos": PolicyFeature(type=FeatureType.STATE, shape=(n,)),
        }
        names = {ACTION: ACTION, "agent_pos": OBS_STATE}
        if self.object_state:
            state = PolicyFeature(type=FeatureType.ENV, shape=(state_size(str(self.task)),))
            features["environment_state"] = state
            names["environment_state"] = OBS_ENV_STATE
        shape = (int(self.observation_height or 0), int(self.observation_width or 0), 3)
        for cam in self.cameras or []:
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
            "cameras": [self._own.get(c, c) for c in self.cameras or []],
            "image_size": (self.observation_height, self.observation_width),
            "quality": self.quality,
            "object_state": bool(self.object_state),
            "joint_velocities": False,  # LeRobot has no key for them: not a declared feature
            "reward": self.reward,
            "render_mode": self.render_mode,
            "render_size": (self.visualization_height, self.visualization_width),
            "terminate_on_success": True,
        }
        if self.randomize != "none":
            kwargs["randomize"] = self.randomize
        if self.arm is not None:
            kwargs["arm"] = self.arm
        if self.episode_length is not None:
            kwargs["episode_seconds"] = check_range(
                self.episode_length / self.fps, "episode_length / fps", low=0.0, high=3600.0
            )
        return kwargs


def _policy_path_argument() -> str | None:
    """``--policy.path`` of LeRobot's command line (lerobot-eval), if any."""
    from lerobot.configs import parser

    try:
        return parser.get_path_arg("policy")
    except Exception:  # not LeRobot's command line: no policy given there
        return None


def _policy_inputs(path: str) -> dict[str, PolicyFeature]:
    """The input features of the policy saved at ``path``."""
    from lerobot.configs.policies import PreTrainedConfig

    try:
        return dict(PreTrainedConfig.from_pretrained(path).input_features)
    except Exception as exc:
        raise SettingError(
            f"cannot read the policy's config at {path!r} ({exc}); expected a folder with a "
            f"LeRobot policy's config.json (--policy.path or --env.policy_path)"
        ) from exc


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


@EnvConfig.register_subclass("so101sim_reach")
@dataclass
class SO101SimReachEnv(SO101SimEnvConfig):
    """Bring the tip to a target point (``so101sim/Reach-v0``, 4 s)."""

    task: str | None = "Reach-v0"


@EnvConfig.register_subclass("so101sim_lift_cylinder")
@dataclass
class SO101SimLiftCylinderEnv(SO101SimEnvConfig):
    """Lift the cylinder (``so101sim/LiftCylinder-v0``, 8 s)."""

    task: str | None = "LiftCylinder-v0"


@EnvConfig.register_subclass("so101sim_lift_sphere")
@dataclass
class SO101SimLiftSphereEnv(SO101SimEnvConfig):
    """Lift the ball (``so101sim/LiftSphere-v0``, 8 s)."""

    task: str | None = "LiftSphere-v0"


@EnvConfig.register_subclass("so101sim_lift_mesh")
@dataclass
class SO101SimLiftMeshEnv(SO101SimEnvConfig):
    """Lift the octagonal mesh (``so101sim/LiftMesh-v0``, 8 s)."""

    task: str | None = "LiftMesh-v0"


@EnvConfig.register_subclass("so101sim_push")
@dataclass
class SO101SimPushEnv(SO101SimEnvConfig):
    """Push the cube onto the mark (``so101sim/Push-v0``, 10 s)."""

    task: str | None = "Push-v0"


@EnvConfig.register_subclass("so101sim_stack")
@dataclass
class SO101SimStackEnv(SO101SimEnvConfig):
    """Put the cube on the block (``so101sim/Stack-v0``, 12 s)."""

    task: str | None = "Stack-v0"


@EnvConfig.register_subclass("so101sim_look_at")
@dataclass
class SO101SimLookAtEnv(SO101SimEnvConfig):
    """Centre the cube in the wrist camera (``so101sim/LookAt-v0``, 4 s)."""

    task: str | None = "LookAt-v0"


__all__ = [
    "ENV_MODULE",
    "NAMESPACE",
    "TASK_EXTRA_STATE",
    "TASK_SCENES",
    "SO101SimCubeToBowlEnv",
    "SO101SimEnvConfig",
    "SO101SimLiftCylinderEnv",
    "SO101SimLiftMeshEnv",
    "SO101SimLiftSphereEnv",
    "SO101SimLookAtEnv",
    "SO101SimPickCubeEnv",
    "SO101SimPushEnv",
    "SO101SimReachEnv",
    "SO101SimStackEnv",
    "state_size",
]
