"""``so101sim dataset TASK --episodes N -o DIR``: a LeRobotDataset of a task's scripted expert,
made at simulation speed on all cores.

Each episode is one run of the task's scripted expert (:func:`so101sim.envs.expert_for`) in
the task's Gymnasium environment at the dataset's rate (``fps``, 30 by default: each frame
holds the targets for 16 or 17 physics steps of 2 ms, as the robot plugin's lockstep mode
does), from the start poses drawn from its own seed (``seed + k`` for episode ``k``). Frame
``t`` holds what ``lerobot-record --robot.type=so101_sim`` would store: the observation
before the action (``observation.state``, the six ``"<joint>.pos"`` measured positions, body
joints in degrees and the gripper 0..100; ``observation.images.<camera>`` for the cameras
asked for; ``observation.environment_state``, the objects' poses, when asked) and the action
sent (``action``, the six joint targets, absolute). An episode ends ``after_success_s``
simulated seconds after the task first succeeded; a take that does not succeed within the
task's time limit is left out and counted (:attr:`DatasetReport.failed_seeds`).

Worker processes (``workers``; or Ray tasks with ``use_ray``) simulate the episodes in
parallel and hand their frames back; this process writes them, in seed order, through
LeRobot's own writer (``LeRobotDataset.create``, ``add_frame``, ``save_episode``,
``finalize``), so the dataset is the same for the same seeds whatever the worker count. The
dataset is written to a temporary folder beside ``root`` and moved there when complete
(nothing half-done is left). The settings (task, seeds, randomisation) are recorded in
``meta/so101sim.json``.
"""

from __future__ import annotations

import json
import logging
import os
import shutil
import tempfile
import time
from collections.abc import Callable, Iterator
from concurrent.futures import ProcessPoolExecutor
from dataclasses import asdict, dataclass, field
from multiprocessing import get_context
from pathlib import Path
from typing import Any

import numpy as np

from so101sim.errors import OutputPathError, SettingError
from so101sim.scenes import PRESET_CAMERAS, SCENE_PRESETS, randomization
from so101sim.units import JOINT_NAMES
from so101sim.validation import check_choice, check_count, check_range

from .config_so101sim import ROBOT_TYPE

log = logging.getLogger(__name__)

TASK_TEXT = {"pick_cube": "Pick up the red cube.", "cube_to_bowl": "Put the red cube in the bowl."}
"""The dataset's task text per task (the environments' ``task_description``)."""
MAX_EPISODES = 100_000
MAX_WORKERS = 256
MAX_IMAGE_SIDE = 1024
MOTOR_NAMES = [f"{j}.pos" for j in JOINT_NAMES]
OBJECT_FIELDS = ("x", "y", "z", "qw", "qx", "qy", "qz")


@dataclass(frozen=True)
class DatasetSettings:
    """What to generate (every value checked by :meth:`checked`)."""

    task: str
    episodes: int
    root: str
    repo_id: str = "local/so101sim"
    seed: int = 0
    fps: int = 30
    cameras: tuple[str, ...] = ()
    image_size: tuple[int, int] = (96, 96)
    environment_state: bool = False
    randomize: str = "none"
    after_success_s: float = 1.0
    workers: int = 1
    use_ray: bool = False
    video: bool = True

    def checked(self) -> DatasetSettings:
        """These settings, each checked with its bounds.

        Raises:
            SettingError: a value out of range (the message says what was expected).
        """
        from so101sim.envs.run import TASKS

        check_choice(self.task, "task", TASKS)
        check_count(self.episodes, "episodes", minimum=1, maximum=MAX_EPISODES)
        check_count(self.seed, "seed", maximum=2**62)
        check_count(self.fps, "fps", minimum=1, maximum=500, unit=" Hz")
        check_count(self.workers, "workers", minimum=1, maximum=MAX_WORKERS)
        for cam in self.cameras:
            check_choice(cam, "camera", PRESET_CAMERAS)
        if len(set(self.cameras)) != len(self.cameras):
            raise SettingError(f"cameras {list(self.cameras)} repeat a name; expected each once")
        h, w = self.image_size
        check_count(h, "image height", minimum=2, maximum=MAX_IMAGE_SIDE, even=True)
        check_count(w, "image width", minimum=2, maximum=MAX_IMAGE_SIDE, even=True)
        check_range(self.after_success_s, "after_success_s", low=0.0, high=60.0, unit=" s")
        _randomize_options(self.randomize)  # raises on an unknown preset
        if not self.cameras and not self.environment_state:
            log.info("a dataset with neither cameras nor environment_state: ACT refuses it")
        return self


@dataclass(frozen=True)
class Episode:
    """One simulated episode as a worker hands it back."""

    seed: int
    success: bool
    success_frame: int | None
    states: np.ndarray  # (T, 6) float32
    actions: np.ndarray  # (T, 6) float32
    environment_state: np.ndarray | None = None  # (T, 7 * objects) float32
    images: dict[str, np.ndarray] = field(default_factory=dict)  # camera -> (T, h, w, 3)
    randomization: dict[str, Any] = field(default_factory=dict)
    sim_seconds: float = 0.0
    wall_seconds: float = 0.0


@dataclass(frozen=True)
class DatasetReport:
    """What :func:`generate_dataset` wrote."""

    root: Path
    episodes: int
    frames: int
    failed_seeds: tuple[int, ...]
    seeds: tuple[int, ...]
    sim_seconds: float
    wall_seconds: float
    workers: int

    @property
    def speed(self) -> float:
        """Simulated seconds of the kept and failed episodes per wall-clock second."""
        return self.sim_seconds / self.wall_seconds if self.wall_seconds > 0 else 0.0


def dataset_features(settings: DatasetSettings) -> dict[str, dict[str, Any]]:
    """The LeRobotDataset features: those ``lerobot-record --robot.type=so101_sim`` writes
    (``action``, ``observation.state``, ``observation.images.<camera>``), and
    ``observation.environment_state`` when asked."""
    features: dict[str, dict[str, Any]] = {
        "action": {"dtype": "float32", "shape": (6,), "names": list(MOTOR_NAMES)},
        "observation.state": {"dtype": "float32", "shape": (6,), "names": list(MOTOR_NAMES)},
    }
    h, w = settings.image_size
    for cam in settings.cameras:
        features[f"observation.images.{cam}"] = {
            "dtype": "video" if settings.video else "image",
            "shape": (h, w, 3),
            "names": ["height", "width", "channels"],
        }
    if settings.environment_state:
        objects = [o.name for o in SCENE_PRESETS[settings.task].objects]
        names = [f"{o}.{f}" for o in objects for f in OBJECT_FIELDS]
        features["observation.environment_state"] = {
            "dtype": "float32",
            "shape": (len(names),),
            "names": names,
        }
    return features


def _randomize_options(preset: str) -> dict[str, Any]:
    """The environments' keyword for a randomisation preset (``none``: nothing)."""
    randomization(preset)  # a preset, or one with families changed: raises
    return {} if preset == "none" else {"randomize": preset}


def _simulate(settings: DatasetSettings, seed: int) -> tuple[Any, float]:
    """In a worker: one episode (so101sim's, no LeRobot import) and its wall time."""
    from so101sim.envs.run import expert_frames

    start = time.perf_counter()
    frames = expert_frames(
        settings.task,
        seed,
        fps=settings.fps,
        cameras=tuple(settings.cameras),
        image_size=tuple(settings.image_size),
        randomize=settings.randomize,
        after_success_s=settings.after_success_s,
    )
    return frames, time.perf_counter() - start


def simulate_episode(settings: DatasetSettings, seed: int) -> Episode:
    """One episode of the task's expert from ``seed``."""
    return _episode(settings, *_simulate(settings, seed))


def _episode(settings: DatasetSettings, frames: Any, wall: float) -> Episode:
    return Episode(
        seed=frames.seed,
        success=frames.success,
        success_frame=frames.success_frame,
        states=frames.states,
        actions=frames.actions,
        environment_state=frames.environment_state if settings.environment_state else None,
        images=frames.images,
        randomization=_jsonable(frames.randomization),
        sim_seconds=len(frames.actions) / settings.fps,
        wall_seconds=wall,
    )


def _jsonable(value: Any) -> Any:
    if isinstance(value, dict):
        return {str(k): _jsonable(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [_jsonable(v) for v in value]
    if isinstance(value, np.ndarray):
        return value.tolist()
    if isinstance(value, np.generic):
        return value.item()
    return value


def _frames_kwargs(settings: DatasetSettings) -> dict[str, Any]:
    return {
        "fps": settings.fps,
        "cameras": tuple(settings.cameras),
        "image_size": tuple(settings.image_size),
        "randomize": settings.randomize,
        "after_success_s": settings.after_success_s,
    }


def _episodes(settings: DatasetSettings, seeds: list[int]) -> Iterator[Episode]:
    """The episodes of ``seeds``, in that order, simulated by ``settings.workers`` workers.
    The workers run so101sim's :func:`~so101sim.envs.run.expert_frames` (plain arguments, so
    they import nothing of LeRobot or of this plugin); this process turns each into an
    :class:`Episode`."""
    from so101sim.envs.run import expert_frames

    kwargs = _frames_kwargs(settings)
    if settings.use_ray:
        try:
            import ray
        except ImportError as exc:
            raise SettingError(
                "--ray needs Ray in this Python; expected `pip install ray` (or leave --ray out)"
            ) from exc
        started = not ray.is_initialized()
        if started:
            ray.init(num_cpus=settings.workers, include_dashboard=False, log_to_driver=False)
        try:
            remote = ray.remote(num_cpus=1)(expert_frames)
            refs = [remote.remote(settings.task, s, **kwargs) for s in seeds]
            for ref in refs:
                start = time.perf_counter()
                yield _episode(settings, ray.get(ref), time.perf_counter() - start)
        finally:
            if started:
                ray.shutdown()
        return
    if settings.workers == 1:
        for s in seeds:
            yield simulate_episode(settings, s)
        return
    ahead = 2 * settings.workers  # episodes in flight: bounds the frames held in memory
    ctx = get_context("spawn")  # MuJoCo's GL contexts and torch do not survive a fork
    with ProcessPoolExecutor(settings.workers, mp_context=ctx) as pool:
        pending: list[Any] = []
        todo = iter(seeds)
        try:
            while True:
                for s in todo:
                    pending.append(pool.submit(expert_frames, settings.task, s, **kwargs))
                    if len(pending) >= ahead:
                        break
                if not pending:
                    return
                start = time.perf_counter()
                yield _episode(settings, pending.pop(0).result(), time.perf_counter() - start)
        finally:
            for fut in pending:
                fut.cancel()


def generate_dataset(
    settings: DatasetSettings, progress: Callable[[Episode], None] | None = None
) -> DatasetReport:
    """Simulate ``settings.episodes`` successful episodes and write them as a LeRobotDataset
    at ``settings.root`` (see the module's text); ``progress`` is called after each episode
    (kept or left out).

    Raises:
        SettingError: a bad setting; OutputPathError: ``root`` exists or cannot be written.
    """
    import datasets
    from lerobot.datasets import LeRobotDataset

    datasets.disable_progress_bars()  # the caller shows the progress
    settings = settings.checked()
    root = Path(settings.root)
    if root.exists():
        raise OutputPathError(
            f"{root} exists; expected a new folder (LeRobot does not overwrite a dataset)"
        )
    try:
        root.parent.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise OutputPathError(
            f"cannot make {root.parent} ({exc}); expected a writable folder"
        ) from exc
    tmp = Path(tempfile.mkdtemp(prefix=f".{root.name}.", dir=root.parent))
    start = time.perf_counter()
    kept: list[int] = []
    failed: list[int] = []
    randomization: dict[str, Any] = {}
    frames = 0
    sim_seconds = 0.0
    try:
        dataset = LeRobotDataset.create(
            settings.repo_id,
            settings.fps,
            root=tmp / "dataset",
            robot_type=ROBOT_TYPE,
            features=dataset_features(settings),
            use_videos=settings.video,
            image_writer_threads=0,
        )
        text = TASK_TEXT[settings.task]
        next_seed = settings.seed
        # simulate in batches (a batch is what the workers have in flight): a failed take is
        # replaced by the next seed until the episodes asked for are kept
        limit = settings.seed + 10 * settings.episodes + 10
        while len(kept) < settings.episodes:
            want = settings.episodes - len(kept)
            if next_seed >= limit:
                raise SettingError(
                    f"the expert failed {len(failed)} of {len(failed) + len(kept)} takes "
                    f"(seeds {failed[:10]}...); expected most to succeed: check the settings"
                )
            seeds = list(range(next_seed, min(next_seed + want, limit)))
            next_seed = seeds[-1] + 1
            for ep in _episodes(settings, seeds):
                sim_seconds += ep.sim_seconds
                if progress is not None:
                    progress(ep)
                if not ep.success:
                    failed.append(ep.seed)
                    log.info("seed %d: the expert failed; episode left out", ep.seed)
                    continue
                for t in range(len(ep.actions)):
                    frame: dict[str, Any] = {
                        "observation.state": ep.states[t],
                        "action": ep.actions[t],
                        "task": text,
                    }
                    for cam, imgs in ep.images.items():
                        frame[f"observation.images.{cam}"] = imgs[t]
                    if ep.environment_state is not None:
                        frame["observation.environment_state"] = ep.environment_state[t]
                    dataset.add_frame(frame)
                dataset.save_episode()
                frames += len(ep.actions)
                kept.append(ep.seed)
                if ep.randomization:
                    randomization[str(ep.seed)] = ep.randomization
        dataset.finalize()
        from so101sim.model import servo_model  # imported here: it imports MuJoCo

        meta = {
            "generator": "so101sim dataset",
            "task": settings.task,
            "servo_model": servo_model(),  # the environments' default arm profile
            "settings": _jsonable(asdict(settings)),
            "episode_seeds": kept,
            "failed_seeds": failed,
            "randomize": settings.randomize,
            "randomization": randomization,
        }
        (tmp / "dataset" / "meta" / "so101sim.json").write_text(json.dumps(meta, indent=1))
        os.replace(tmp / "dataset", root)
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    return DatasetReport(
        root=root,
        episodes=len(kept),
        frames=frames,
        failed_seeds=tuple(failed),
        seeds=tuple(kept),
        sim_seconds=sim_seconds,
        wall_seconds=time.perf_counter() - start,
        workers=settings.workers,
    )


__all__ = [
    "DatasetReport",
    "DatasetSettings",
    "Episode",
    "dataset_features",
    "generate_dataset",
    "simulate_episode",
]
