"""Running the scripted experts: one episode (:func:`run_expert`, optionally recorded to a
video, which is what ``so101sim demo <task> --record <file>`` shows), or many seeds for a
success rate (:func:`evaluate_expert`).
"""

from __future__ import annotations

import atexit
import contextlib
import os
import threading
from collections.abc import Iterator, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium.envs.registration import load_env_creator

from ..errors import SettingError
from ..recording import VideoRecorder, VideoSettings
from ..scenes import CameraLike, camera_name
from ..validation import check_count, check_range
from .base import episode_steps
from .expert import expert_for

TASKS = {
    "pick_cube": "so101sim/PickCube-v0",
    "cube_to_bowl": "so101sim/CubeToBowl-v0",
    "reach": "so101sim/Reach-v0",
    "lift_cylinder": "so101sim/LiftCylinder-v0",
    "lift_sphere": "so101sim/LiftSphere-v0",
    "lift_mesh": "so101sim/LiftMesh-v0",
    "push": "so101sim/Push-v0",
    "stack": "so101sim/Stack-v0",
    "look_at": "so101sim/LookAt-v0",
}
"""Task names (as the scene presets name them) and their Gymnasium ids."""


@dataclass(frozen=True)
class EpisodeResult:
    """One episode: its seed, whether it succeeded, the steps it took, the sum of its rewards,
    the simulated time at its end and when it first succeeded, how many grasps the expert
    tried, the video written (if any) and its frames, the task's figures at the end
    (``info``'s numbers, e.g. ``cube_rise_m``, ``cube_to_bowl_m``) and whether it ran to its
    end (False: the viewer was closed)."""

    seed: int
    success: bool
    steps: int
    total_reward: float
    sim_time: float
    attempts: int
    video: Path | None = None
    figures: dict[str, float] = field(default_factory=dict)
    completed: bool = True
    video_frames: int = 0
    success_time: float | None = None


def env_id(task: str) -> str:
    """The Gymnasium id of ``task`` (a task name such as ``"pick_cube"``, or an id)."""
    if task in TASKS.values():
        return task
    if task in TASKS:
        return TASKS[task]
    raise SettingError(
        f"unknown task {task!r}; valid tasks are {', '.join(TASKS)} "
        f"(or the ids {', '.join(TASKS.values())})"
    )


def episode_steps_limit(task: str, hz: float) -> int:
    """The most steps an episode of ``task`` (a name or an id) takes at ``hz`` steps a
    simulated second with its default time limit, as the environment counts them."""
    hz = check_range(hz, "hz", low=1.0, high=500.0, unit=" Hz")  # as the environments take it
    env_class = load_env_creator(gym.spec(env_id(task)).entry_point)
    return episode_steps(float(env_class.default_episode_seconds), hz)


def make(task: str, **kwargs: Any) -> gym.Env:
    """``gymnasium.make`` of ``task`` (a name or an id), with ``kwargs`` for the env."""
    return gym.make(env_id(task), **kwargs)


def run_episode(
    env: gym.Env, seed: int, *, video: VideoRecorder | None = None, linger: float = 0.0
) -> EpisodeResult:
    """Run ``env``'s scripted expert for one episode from ``reset(seed=seed)``; it ends when
    the environment says so, or ``linger`` simulated seconds after the task first succeeded
    (to show the result in a video of an environment that does not end on success), or when
    the environment's viewer (``render_mode="human"``) is closed."""
    expert = expert_for(env)
    inner = env.unwrapped
    linger_steps = round(check_range(linger, "linger", low=0.0, high=60.0) * inner.control_hz)
    if video is not None:
        inner.sim.observers.append(video)
    try:
        obs, info = env.reset(seed=seed)
        expert.reset()
        total, steps, done, first, completed = 0.0, 0, False, None, True
        while not done:
            if not _viewer_open(inner):
                completed = False
                break
            obs, reward, terminated, truncated, info = env.step(expert.act(obs))
            total += float(reward)
            steps += 1
            if info["is_success"] and first is None:
                first = steps
            done = terminated or truncated or (first is not None and steps - first >= linger_steps)
    finally:
        if video is not None:
            inner.sim.observers.remove(video)
    return EpisodeResult(
        seed=seed,
        success=first is not None,
        steps=steps,
        total_reward=total,
        sim_time=inner.sim.time,
        attempts=expert.attempts + 1,
        figures={k: float(v) for k, v in info.items() if k not in ("is_success", "time")},
        completed=completed,
        success_time=None if first is None else first / inner.control_hz,
    )


def _viewer_open(env: Any) -> bool:
    """False once the environment's viewer window (if it has one) has been closed."""
    viewer = getattr(env, "_viewer", None)
    return viewer is None or bool(viewer.is_running())


def run_expert(
    task: str,
    seed: int = 0,
    *,
    record: str | os.PathLike[str] | None = None,
    video: VideoSettings | None = None,
    force: bool = False,
    viewer: bool = False,
    **env_kwargs: Any,
) -> EpisodeResult:
    """One episode of ``task``'s scripted expert; with ``record``, an MP4 of it (by default
    the ``front`` camera, 30 frames per simulated second; ``video`` sets size, rate, camera
    and quality; going on for a second after the task succeeds) written and verified before
    this returns. With ``viewer``, the episode is shown in MuJoCo's viewer at real-time speed
    (a display is needed); closing the window ends it (``completed`` False).

    Raises:
        SettingError: an unknown task; OutputPathError, RecordingError: a bad video path or
            settings.
    """
    seed = check_count(seed, "seed", maximum=2**63 - 1)
    settings = video or VideoSettings(camera="front", caption=True)
    if record is not None or viewer:
        env_kwargs.setdefault("terminate_on_success", False)
    if viewer:
        env_kwargs["render_mode"] = "human"
    if record is not None and settings.camera != "free":
        env_kwargs.setdefault("render_camera", settings.camera)  # its scene holds that camera
    env = make(task, **env_kwargs)
    recorder = None
    try:
        if record is not None:
            recorder = VideoRecorder(record, env.unwrapped.model, settings, force=force)
        result = run_episode(env, seed, video=recorder, linger=1.0 if record or viewer else 0.0)
    finally:
        written = recorder.close() if recorder is not None else None
        env.close()
    if record is not None and written is None:
        raise SettingError(f"the video {str(record)!r} was not written (no frame was drawn)")
    frames = recorder.frames if recorder is not None else 0
    return EpisodeResult(**{**result.__dict__, "video": written, "video_frames": frames})


@dataclass(frozen=True)
class ExpertScore:
    """A scripted expert's record over many seeds."""

    task: str
    episodes: tuple[EpisodeResult, ...]

    @property
    def success_rate(self) -> float:
        return float(np.mean([e.success for e in self.episodes])) if self.episodes else 0.0

    @property
    def failed_seeds(self) -> list[int]:
        return [e.seed for e in self.episodes if not e.success]

    @property
    def mean_steps(self) -> float:
        return float(np.mean([e.steps for e in self.episodes])) if self.episodes else 0.0


def evaluate_expert(
    task: str, seeds: range | list[int] = range(100), **env_kwargs: Any
) -> ExpertScore:
    """Run ``task``'s scripted expert once per seed (one environment, reset each time)."""
    seeds = list(seeds)
    check_count(len(seeds), "number of seeds", minimum=1, maximum=100_000)
    env = make(task, **env_kwargs)
    try:
        episodes = tuple(run_episode(env, int(s)) for s in seeds)
    finally:
        env.close()
    return ExpertScore(task=env_id(task), episodes=episodes)


@dataclass(frozen=True)
class ExpertFrames:
    """One episode of a scripted expert as a dataset holds it: frame ``t`` is the observation
    before action ``t`` and that action (what ``lerobot-record`` stores per frame)."""

    seed: int
    success: bool
    success_frame: int | None
    """The first frame whose observation shows the task done (None: it failed)."""
    states: np.ndarray
    """(T, 6) float32: measured joint positions (degrees, gripper 0..100)."""
    actions: np.ndarray
    """(T, 6) float32: the joint targets sent (absolute, the same units)."""
    environment_state: np.ndarray
    """(T, 7 * objects) float32: each object's position and quaternion."""
    images: dict[str, np.ndarray] = field(default_factory=dict)
    """camera -> (T, h, w, 3) uint8."""
    randomization: dict[str, Any] = field(default_factory=dict)
    """What the domain randomisation drew for the episode (empty without it)."""


_KEPT: dict[str, Any] = {}
"""This process's last expert environment (``key``, ``env``): a dataset's worker makes its
environment (compiled scene, renderers) once for all its episodes, not once per episode."""
_KEPT_LOCK = threading.Lock()


@contextlib.contextmanager
def _kept_env(task: str, options: dict[str, Any]) -> Iterator[gym.Env]:
    """The kept environment of ``task`` made with ``options`` (made, and the one kept before
    closed, when they differ). A thread that finds it in use by another gets a new one, closed
    after its episode. Every episode starts from ``reset(seed)``, which sets everything an
    episode depends on, so an episode is the same on a kept or a new environment (tested)."""
    key = repr((task, sorted(options.items())))
    if not _KEPT_LOCK.acquire(blocking=False):
        env = make(task, **options)
        try:
            yield env
        finally:
            env.close()
        return
    try:
        if _KEPT.get("key") != key:
            _close_kept()
            env = make(task, **options)
            _KEPT.update(key=key, env=env)
        yield _KEPT["env"]
    except BaseException:
        _close_kept()  # an episode that failed half-way: nothing of it is kept
        raise
    finally:
        _KEPT_LOCK.release()


def _close_kept() -> None:
    env = _KEPT.pop("env", None)
    _KEPT.pop("key", None)
    if env is not None:
        env.close()


atexit.register(_close_kept)


def expert_frames(
    task: str,
    seed: int,
    *,
    fps: int = 30,
    cameras: Sequence[CameraLike] = (),
    image_size: tuple[int, int] = (96, 96),
    randomize: Any = None,
    after_success_s: float = 1.0,
) -> ExpertFrames:
    """One episode of ``task``'s scripted expert from ``reset(seed=seed)``, at ``fps``
    environment steps per simulated second (absolute joint targets, the draft meshes for
    images), ending ``after_success_s`` after the task first succeeded or at its time limit.
    A plain function of plain arguments, so that worker processes can run it (``so101sim
    dataset``) without importing anything of LeRobot.

    Raises:
        SettingError: an unknown task or a bad setting.
    """
    options = {
        "control": "joint",
        "control_hz": float(fps),
        "cameras": list(cameras),
        "image_size": tuple(image_size),
        "object_state": True,
        "joint_velocities": False,
        "quality": "draft",
        "terminate_on_success": False,
        "randomize": randomize,
    }
    # randomised or not, the environment is kept: reset(seed) sets everything an episode
    # depends on, the randomisation's draws included (tests/envs/test_reset_history.py)
    with _kept_env(task, options) as env:
        return _expert_episode(env, seed, cameras, fps, after_success_s)


def _expert_episode(
    env: gym.Env, seed: int, cameras: Sequence[CameraLike], fps: int, after_success_s: float
) -> ExpertFrames:
    """One episode of the expert on ``env`` from ``reset(seed=seed)`` (:func:`expert_frames`)."""
    expert = expert_for(env)
    obs, info = env.reset(seed=seed)
    expert.reset()
    after = round(check_range(after_success_s, "after_success_s", low=0.0, high=60.0) * fps)
    states, actions, env_states = [], [], []
    images: dict[str, list[np.ndarray]] = {camera_name(c): [] for c in cameras}
    first: int | None = None
    done = False
    while not done:
        action = np.asarray(expert.act(obs), dtype=np.float32)
        states.append(np.asarray(obs["agent_pos"], dtype=np.float32))
        actions.append(action)
        env_states.append(np.asarray(obs["environment_state"], dtype=np.float32))
        for cam, frames in images.items():
            frames.append(obs["pixels"][cam])
        obs, _, terminated, truncated, info = env.step(action)
        if info["is_success"] and first is None:
            first = len(actions)
        done = terminated or truncated or (first is not None and len(actions) - first >= after)
    return ExpertFrames(
        seed=seed,
        success=first is not None,
        success_frame=first,
        states=np.stack(states),
        actions=np.stack(actions),
        environment_state=np.stack(env_states),
        images={c: np.stack(v) for c, v in images.items()},
        randomization=dict(env.unwrapped.randomization),
    )
