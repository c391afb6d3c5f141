"""The Gymnasium environment the SO-101 tasks share: a table-top scene, the arm driven by
joint targets in its own units, dict observations shaped for LeRobot, seeded resets.

Observations (a ``gymnasium.spaces.Dict``; LeRobot's ``preprocess_observation`` maps the
keys as noted):

* ``agent_pos`` (6,) float32: the measured joint positions, degrees and gripper 0-100
  (``observation.state``);
* ``agent_vel`` (6,) float32: their velocities, per second, if ``joint_velocities`` (the
  default; LeRobot has no key for it, so the LeRobot env plugin turns it off);
* ``environment_state`` (7 per object) float32, if ``object_state``: each object's position
  (metres) and orientation quaternion (w, x, y, z) (``observation.environment_state``);
* ``pixels``: ``{camera: (height, width, 3) uint8}``, if ``cameras`` are named
  (``observation.images.<camera>``).

Every ``1 / control_hz`` s the action sets the six position targets (see
:mod:`so101sim.envs.actions`) and the physics takes that many 2 ms steps (at a rate that is
not a whole number of steps, such as LeRobot's 30 Hz, 16 or 17 steps: step ``k`` ends at the
physics step nearest ``k / control_hz``, with no drift). An episode ends
when the task succeeds (``terminated``, unless ``terminate_on_success`` is off) or after
``episode_seconds`` (``truncated``); ``info["is_success"]`` says whether it succeeded.
"""

from __future__ import annotations

import contextlib
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any, ClassVar, Literal, get_args

import gymnasium as gym
import mujoco
import numpy as np

from ..errors import ClosedError, ViewerError
from ..exitgate import gated
from ..model.arm import ArmLike, load_profile
from ..recording import FREE_CAMERA, QUALITY_CHOICES, FrameRenderer, VideoSettings
from ..recording.settings import check_quality
from ..robot.config import GRIPPER_TORQUE_FRACTION
from ..scenes import (
    PRESET_CAMERAS,
    CameraLike,
    CameraSpec,
    Randomization,
    SceneRandomizer,
    VisualJitter,
    VisualRandomizer,
    build_scene,
    camera,
    place_objects,
    preset_scene,
    randomization,
    resolve_cameras,
    sample_placements,
    scene_additions,
)
from ..sim.simulation import Simulation
from ..sim.stepping import advance_unobserved
from ..units import STARTING_POSE, Pose
from ..validation import check_choice, check_range
from .actions import ActionMap, ControlMode, ControlSettings
from .grasp import limit_gripper
from .observations import Observations, check_size
from .scene_state import SceneState

RewardMode = Literal["dense", "sparse"]
"""The reward: ``dense`` (shaped, 0..1) or ``sparse`` (1.0 on success, else 0.0)."""
REWARD_MODES: tuple[str, ...] = get_args(RewardMode)
_ADVICE = (
    "Expected stable physics: reset the environment, and check the actions and the scene's masses"
)
RenderMode = Literal["human", "rgb_array"]
"""Gymnasium's render modes the tasks offer: a viewer window, or frames as arrays."""
RENDER_MODES: tuple[str, ...] = get_args(RenderMode)


def episode_steps(seconds: float, hz: float) -> int:
    """The steps of an episode of ``seconds`` at ``hz`` steps a simulated second (at least
    one): an environment's ``max_episode_steps``."""
    return max(1, round(seconds * hz))


@dataclass(frozen=True)
class Evaluation:
    """How a task stands after a step: ``success``, the ``dense`` reward (0..1) and the
    figures it came from (they go into ``info``)."""

    success: bool
    dense: float
    details: dict[str, float] = field(default_factory=dict)


class So101TaskEnv(Observations, SceneState, gym.Env):
    """A table-top task for the SO-101 (see the module's text). Subclasses name the scene
    preset and say how the task is judged (:meth:`evaluate`)."""

    metadata: ClassVar[dict[str, Any]] = {"render_modes": list(RENDER_MODES), "render_fps": 25}
    scene_name = "pick_cube"
    default_episode_seconds = 8.0

    def __init__(
        self,
        render_mode: RenderMode | None = None,
        *,
        control: ControlMode = "joint",
        reward: RewardMode = "dense",
        cameras: Sequence[CameraLike] = (),
        image_size: tuple[int, int] = (224, 224),
        object_state: bool = True,
        joint_velocities: bool = True,
        control_hz: float = 25.0,
        episode_seconds: float | None = None,
        max_delta: float = 10.0,
        ee_step: float = 0.02,
        ee_turn: float = 10.0,
        render_camera: str = "front",
        render_size: tuple[int, int] = (480, 640),
        quality: str = "draft",
        visual_jitter: VisualJitter | None = None,
        gripper_torque_fraction: float = GRIPPER_TORQUE_FRACTION,
        terminate_on_success: bool = True,
        initial_pose: Pose | None = None,
        randomize: str | Randomization | dict[str, Any] | None = None,
        arm: ArmLike = None,
        shared_model: mujoco.MjModel | None = None,
    ) -> None:
        if render_mode is not None:
            check_choice(render_mode, "render mode", RENDER_MODES)
        self.render_mode = render_mode
        self.reward_mode = check_choice(reward, "reward mode", REWARD_MODES)
        self.image_size = check_size(image_size, "image_size")
        for cam in cameras:  # a name must be a preset's (a camera of your own: a CameraSpec)
            if not isinstance(cam, CameraSpec):
                check_choice(cam, "camera", PRESET_CAMERAS)
        self._camera_list = resolve_cameras(cameras, self.image_size)
        self.cameras = tuple(c.name for c in self._camera_list)
        self.render_size = check_size(render_size, "render_size")
        self.render_camera = check_choice(
            render_camera, "render camera", [*PRESET_CAMERAS, FREE_CAMERA]
        )
        self.quality = check_quality(quality, QUALITY_CHOICES)
        self.object_state = bool(object_state)
        self.joint_velocities = bool(joint_velocities)
        self.terminate_on_success = bool(terminate_on_success)
        hz = check_range(control_hz, "control_hz", low=1.0, high=500.0, unit=" Hz")
        seconds = check_range(
            self.default_episode_seconds if episode_seconds is None else episode_seconds,
            "episode_seconds",
            low=0.0,
            high=3600.0,
            low_open=True,
            unit=" s",
        )
        fraction = check_range(
            gripper_torque_fraction, "gripper_torque_fraction", low=0.0, high=1.0, low_open=True
        )
        self.arm = load_profile(arm)  # the servos' model: name, TOML file or None (default)
        self.scene = preset_scene(self.scene_name, cameras=self._camera_specs())
        self.randomize = randomization(randomize)
        if shared_model is None:
            extra = scene_additions(self.randomize)
            self.model = build_scene(self.scene, arm=self.arm, extra=extra)
            limit_gripper(self.model, fraction, self.arm)
        else:  # make_vec's worlds: one compiled model (built with these settings) for all
            self.model = shared_model
        self.sim = Simulation(self.model, initial_pose=initial_pose or STARTING_POSE)
        self._period_steps = 1.0 / (hz * self.sim.timestep)  # physics steps per env step
        self.substeps = max(1, round(self._period_steps))  # nominal (exact at 25 Hz)
        self.control_hz = hz
        self.max_episode_steps = episode_steps(seconds, hz)
        self._max_episode_steps = self.max_episode_steps  # where LeRobot's eval looks for it
        # a whole rate as an int: LeRobot's video writer (PyAV) refuses a float frame rate
        fps = int(hz) if float(hz).is_integer() else hz
        self.metadata = {**self.metadata, "render_fps": fps}
        self.actions = ActionMap(
            self.model, self.sim.units, ControlSettings(control, max_delta, ee_step, ee_turn)
        )
        self.action_space = self.actions.space
        self.observation_space = self._observation_space()
        self.jitter = (visual_jitter or VisualJitter()).validated()
        self._renderers: dict[str, FrameRenderer] = {}
        self._randomizer: VisualRandomizer | None = None
        self._scene_randomizer: SceneRandomizer | None = None
        self.randomization: dict[str, Any] = {}
        """What the last reset's randomisation drew (empty without ``randomize``)."""
        self._viewer_stack: contextlib.ExitStack | None = None
        self._viewer: Any = None
        self._steps = 0
        self._closed = False
        SceneState.__init__(self, self.model, self.sim, self.scene)  # objects, pads, tip
        self._scale = self.sim.units.scale  # radians per arm unit

    # -- set-up
    def _camera_specs(self) -> list:
        specs = list(self._camera_list)
        if self.render_camera in PRESET_CAMERAS and self.render_camera not in self.cameras:
            specs.append(camera(self.render_camera))
        return specs

    def _renderer(self, name: str, size: tuple[int, int]) -> FrameRenderer:
        key = f"{name}@{size[0]}x{size[1]}"
        r = self._renderers.get(key)
        if r is None:
            settings = VideoSettings(
                width=size[1], height=size[0], camera=name, caption=False, quality=self.quality
            )
            r = self._renderers[key] = FrameRenderer(self.model, settings)
            self._randomizer = None  # a new render model: jitter it too from now on
        return r

    def _randomize(self) -> None:
        """The episode's domain randomisation, drawn after the start poses (which stay those
        drawn without it) from the same generator."""
        if not self.randomize.active:
            return
        for name in self.cameras:
            self._renderer(name, self.image_size)
        if self.render_mode == "rgb_array":
            self._renderer(self.render_camera, self.render_size)
        renders = [r.render_model for r in self._renderers.values()]
        if self._scene_randomizer is None:
            objects = [o.name for o in self.scene.objects]
            self._scene_randomizer = SceneRandomizer(
                self.model, objects, self.randomize, renders, profile=self.arm
            )
        for m in renders:
            self._scene_randomizer.add_render_model(m)
        self.randomization = self._scene_randomizer.apply(self.np_random, self.sim.data)

    def _jitter(self) -> None:
        if not self.jitter.active:
            return
        for name in self.cameras:
            self._renderer(name, self.image_size)
        if self.render_mode == "rgb_array":
            self._renderer(self.render_camera, self.render_size)
        if self._randomizer is None:
            models = [self.model, *(r.render_model for r in self._renderers.values())]
            self._randomizer = VisualRandomizer(models, self.scene, self.jitter)
        self._randomizer.apply(self.np_random)

    # -- the Gymnasium API
    @gated  # no MuJoCo call left running at exit (exitgate); later ones refused
    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[dict[str, Any], dict[str, Any]]:
        """Back to the start pose with the objects at poses drawn from the episode's random
        generator (``options={"placements": {name: (x, y, yaw)}}`` sets them instead).

        Raises:
            ClosedError: the environment was closed.
        """
        self._check_open("reset")
        super().reset(seed=seed)
        self.sim.reset()
        placements = (options or {}).get("placements")
        poses = sample_placements(self.scene.objects, self.np_random, self.scene.keep_out)
        if placements is not None:
            poses.update({k: tuple(map(float, v)) for k, v in dict(placements).items()})
        place_objects(self.model, self.sim.data, poses)
        self._randomize()
        self.actions.reset(self.sim.commanded_array())
        self._jitter()
        self._steps = 0
        self.remember_start()
        ev = self.evaluate()
        if self.render_mode == "human":
            self.render()
        return self._observation(), self._info(ev)

    @gated  # no MuJoCo call left running at exit (exitgate); later ones refused
    def step(self, action: np.ndarray) -> tuple[dict[str, Any], float, bool, bool, dict[str, Any]]:
        """One control period with ``action``.

        Raises:
            SettingError: the action is not valid (not numbers, NaN, the wrong shape).
            ClosedError: the environment was closed.
            SimulationDivergedError: the physics became unstable.
        """
        self._check_open("step")
        targets = self.actions.targets(action, self.sim.commanded_array())
        self._advance(targets)
        return self._finish_step()

    def _physics_steps(self) -> int:
        """The physics steps of the next control period (16 or 17 at 30 Hz: no drift)."""
        k = self._steps
        return max(1, round((k + 1) * self._period_steps) - round(k * self._period_steps))

    def _finish_step(self) -> tuple[dict[str, Any], float, bool, bool, dict[str, Any]]:
        """After a control period's physics (here or in a batch, :mod:`.worlds`): count the
        step, judge the task, and answer as :meth:`step` does."""
        reward, terminated, truncated, info = self._judge_step()
        return self._observation(), reward, terminated, truncated, info

    def _judge_step(self) -> tuple[float, bool, bool, dict[str, Any]]:
        """:meth:`_finish_step` but the observation (a vector env takes its worlds' at once)."""
        self._steps += 1
        ev = self.evaluate()
        reward = ev.dense if self.reward_mode == "dense" else float(ev.success)
        terminated = bool(ev.success and self.terminate_on_success)
        truncated = self._steps >= self.max_episode_steps and not terminated
        return float(reward), terminated, truncated, self._info(ev)

    def _advance(self, targets: np.ndarray) -> None:
        """Hold ``targets`` for one control period. With observers (a video) or a viewer, the
        simulation's own stepping serves them; without, the stepping kernel takes them in MuJoCo's
        own loop (the same physics, without the per-step bookkeeping)."""
        sim = self.sim
        n = self._physics_steps()
        if sim.observers or self._viewer is not None:
            rows = np.broadcast_to(targets, (n, len(targets)))
            sim.advance(rows, viewer=self._viewer, phase=self.spec_name, keep_trace=False)
            return
        sim.command_array(targets, check=False)
        advance_unobserved(self.model, sim.data, None, n, advice=_ADVICE)  # the stepping kernel

    @property
    def spec_name(self) -> str:
        """The environment's Gymnasium id, or its class name."""
        return self.spec.id if self.spec is not None else type(self).__name__

    def render(self) -> np.ndarray | None:
        """``rgb_array``: the frame of ``render_camera`` (``render_size``); ``human``: shows
        the simulation in MuJoCo's viewer (a display is needed).

        Raises:
            ClosedError: the environment was closed.
        """
        self._check_open("render")
        if self.render_mode == "rgb_array":
            return self._renderer(self.render_camera, self.render_size).render(self.sim.data).copy()
        if self.render_mode == "human":
            if self._viewer is None:
                from ..viewer import open_viewer  # imported here only to keep start-up fast

                stack = contextlib.ExitStack()
                try:
                    self._viewer = stack.enter_context(open_viewer(self.model, self.sim.data))
                except ViewerError as exc:  # the same reason, with an environment's way out
                    raise ViewerError(
                        f"render_mode='human' needs MuJoCo's viewer: {exc}. For an "
                        "environment: render_mode='rgb_array' or None (and "
                        "check_env(env, skip_render_check=True) on a machine without a "
                        "display), or run under xvfb-run"
                    ) from None
                self._viewer_stack = stack
            self._viewer.sync()
        return None

    def _check_open(self, what: str) -> None:
        if self._closed:
            raise ClosedError(
                f"{what}() on a closed {self.spec_name} environment; expected an open one "
                "(make a new environment after close())"
            )

    def close(self) -> None:
        """Free the renderers and the viewer; later reset(), step() and render() are refused
        (closing again is harmless)."""
        self._closed = True
        for r in self._renderers.values():
            r.close()
        self._renderers.clear()
        if self._viewer_stack is not None:
            self._viewer_stack.close()
            self._viewer_stack, self._viewer = None, None

    # -- the task (object poses, contacts: SceneState)
    def evaluate(self) -> Evaluation:
        """How the task stands (subclasses)."""
        raise NotImplementedError

    @property
    def elapsed_steps(self) -> int:
        return self._steps

    def _info(self, ev: Evaluation) -> dict[str, Any]:
        return {"is_success": bool(ev.success), "time": self.sim.time, **ev.details}
