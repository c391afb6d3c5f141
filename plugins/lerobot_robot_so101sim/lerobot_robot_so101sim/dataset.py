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
``finalize``; videos encoded as the frames arrive, on a thread: ``streaming_encoding``), so
the dataset is the same for the same seeds whatever the worker count (:mod:`.episodes`). With
``video=False`` the images are stored as PNG frames in the data files instead of videos:
larger, and slower to train on with action chunks (LeRobot 0.6.1 reads a chunk's rows whole,
decoding each row's images). The
dataset is written to a temporary folder beside ``root`` and moved there when complete
(nothing half-done is left). The settings (task, seeds, randomisation) are recorded in
``meta/so101sim.json``.
"""

from __future__ import annotations

import contextlib
import json
import logging
import os
import shutil
import tempfile
import time
from collections.abc import Callable
from dataclasses import asdict, dataclass, replace
from pathlib import Path
from typing import Any

from so101sim.errors import OutputPathError, SettingError
from so101sim.scenes import (
    PRESET_CAMERAS,
    SCENE_PRESETS,
    CameraLike,
    CameraSpec,
    camera_name,
    randomization,
    resolve_cameras,
)
from so101sim.units import JOINT_NAMES
from so101sim.validation import check_choice, check_count, check_range, checked_path

from .config_so101sim import ROBOT_TYPE
from .episodes import Episode, episodes, jsonable, simulate_episode

log = logging.getLogger(__name__)

TASK_TEXT = {
    "pick_cube": "Pick up the red cube.",
    "cube_to_bowl": "Put the red cube in the bowl.",
    "lift_cylinder": "Pick up the orange cylinder.",
    "lift_sphere": "Pick up the green ball.",
    "lift_mesh": "Pick up the purple nut.",
    "push": "Push the red cube onto the green mark.",
    "stack": "Stack the red cube on the blue block.",
}
"""The dataset's task text per task (the environments' ``task_description``)."""
MAX_EPISODES = 100_000
MAX_WORKERS = 256
MAX_IMAGE_SIDE = 1024
ENCODER_THREADS = 1
"""Threads of the video encoder (streaming: it runs beside the workers on the same cores)."""
VIDEO_CODECS: dict[str, dict[str, Any]] = {
    "h264": {"vcodec": "h264", "preset": "ultrafast", "crf": 20},
    "libsvtav1": {"vcodec": "libsvtav1"},
    "av1": {"vcodec": "libsvtav1"},
}
"""The video codecs (``vcodec``) and the encoder settings each is given, through LeRobot's
``RGBEncoderConfig`` (``--dataset.rgb_encoder.*`` of ``lerobot-record``). ``h264`` (the
default): x264's fastest preset at a quality (``crf`` 20) that keeps the rendered frames at
least as close to the raw images as AV1 at LeRobot's settings does, for about a quarter less
CPU over the whole dataset (342 CPU-s against 459 for 200 episodes, docs/learning.md).
``libsvtav1`` (or ``av1``): what ``lerobot-record`` writes by default (SVT-AV1, preset 12,
``crf`` 30). LeRobot trains on either (docs/learning.md: measured), but merges
only datasets of one codec, and ``lerobot-record --resume`` appends in its own settings: give
the codec of the dataset you will combine this one with."""
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
    cameras: tuple[CameraLike, ...] = ()
    """Preset names (``front``, ``wrist``) and cameras of your own (``CameraSpec``, e.g. from
    ``so101sim.scenes.load_cameras``); images are stored as ``observation.images.<name>``."""
    image_size: tuple[int, int] = (96, 96)
    environment_state: bool = False
    randomize: str = "none"
    after_success_s: float = 1.0
    workers: int = 1
    use_ray: bool = False
    ray_address: str = "local"
    """With ``use_ray``: "local" (start a Ray cluster here with ``workers`` CPUs), "auto" (one
    running on this machine) or a cluster's ``host:port`` / ``ray://host:port``."""
    video: bool = True
    vcodec: str = "h264"
    """The videos' codec: ``h264`` or ``libsvtav1`` (``av1``), see :data:`VIDEO_CODECS`."""

    def checked(self) -> DatasetSettings:
        """These settings, each checked with its bounds.

        Raises:
            SettingError: a value out of range (the message says what was expected);
            OutputPathError: ``root`` exists or is not a path.
        """
        check_choice(self.task, "task", TASK_TEXT)  # the tasks a follower's expert records
        # empty, NUL, a name or path too long: refused before anything touches the disk
        root = checked_path(self.root, "dataset folder", error=OutputPathError)
        if root.exists():
            raise OutputPathError(
                f"{root} exists; expected a new folder (LeRobot does not overwrite a dataset)"
            )
        check_count(self.episodes, "episodes", minimum=1, maximum=MAX_EPISODES)
        check_count(self.seed, "seed", maximum=2**62)
        check_count(self.fps, "fps", minimum=1, maximum=500, unit=" Hz")
        check_count(self.workers, "workers", minimum=1, maximum=MAX_WORKERS)
        check_choice(self.vcodec, "vcodec", VIDEO_CODECS)
        for cam in self.cameras:
            if not isinstance(cam, CameraSpec):
                check_choice(cam, "camera", PRESET_CAMERAS)
        names = [camera_name(c) for c in self.cameras]
        if len(set(names)) != len(names):
            raise SettingError(f"cameras {names} repeat a name; expected each once")
        resolve_cameras(self.cameras)  # each camera of your own valid
        h, w = self.image_size
        check_count(h, "image height", minimum=2, maximum=MAX_IMAGE_SIDE, even=True)
        check_count(w, "image width", minimum=2, maximum=MAX_IMAGE_SIDE, even=True)
        check_range(self.after_success_s, "after_success_s", low=0.0, high=60.0, unit=" s")
        _randomize_options(self.randomize)  # raises on an unknown preset
        if not isinstance(self.ray_address, str) or not self.ray_address.strip():
            raise SettingError(
                f"ray_address = {self.ray_address!r}; expected local, auto or host:port"
            )
        if not self.cameras and not self.environment_state:
            log.info("a dataset with neither cameras nor environment_state: ACT refuses it")
        return self


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
        features[f"observation.images.{camera_name(cam)}"] = {
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


def _say_what_is_rendered(settings: DatasetSettings) -> None:
    """A camera of your own whose file gives another size or frame rate than the dataset's is
    recorded at the dataset's (``image_size``, ``fps``: one frame rate a dataset, the training
    size for the images): logged, so that the file is not taken for what was recorded."""
    h, w = settings.image_size
    for cam in settings.cameras:
        if not isinstance(cam, CameraSpec):
            continue
        size = (cam.width, cam.height)
        if size != (CameraSpec.width, CameraSpec.height) and size != (w, h):
            log.warning(
                "camera %r: its file gives %dx%d; the dataset records it at %dx%d (--image-size)",
                cam.name, cam.width, cam.height, w, h,
            )  # fmt: skip
        if cam.fps != CameraSpec.fps and cam.fps != settings.fps:
            log.warning(
                "camera %r: its file gives %g fps; the dataset records every camera at %d fps "
                "(--fps)", cam.name, cam.fps, settings.fps,
            )  # fmt: skip


def _abandon(dataset: Any) -> None:
    """Stop LeRobot's writer of a dataset left unfinished (an error, Ctrl-C) while its folder
    is still there: its encoder's episode cancelled, its files closed. Left to itself, the
    writer finalizes when it is garbage-collected, which writes the metadata again into a
    folder already removed."""
    with contextlib.suppress(Exception):
        dataset.clear_episode_buffer()  # cancels the streaming encoder's episode
    with contextlib.suppress(Exception):
        dataset.finalize()


def _randomize_options(preset: str) -> dict[str, Any]:
    """The environments' keyword for a randomisation preset (``none``: nothing)."""
    randomization(preset)  # a preset, or one with families changed: raises
    return {} if preset == "none" else {"randomize": preset}


def quiet_encoder_logs() -> None:
    """Warnings and errors only from the video encoders, for a command that shows its own
    progress: SVT-AV1 prints about 15 lines of its settings for every video it starts (two a
    camera and episode) unless ``SVT_LOG`` says otherwise (left as the user set it), libx264
    a dozen lines of statistics for each video it ends, and ffmpeg's muxer a line for each
    video file it finalises. Process-wide: for a command's
    ``main``, not for a library."""
    os.environ.setdefault("SVT_LOG", "1")
    import av.logging

    # ffmpeg's own threshold: LeRobot hands ffmpeg's logging back to its default printer
    # after each video (av.logging.restore_default_callback), so PyAV's set_level is not enough
    av.logging.set_libav_level(av.logging.WARNING)


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
    from lerobot.configs.video import RGBEncoderConfig
    from lerobot.datasets import LeRobotDataset

    from so101sim.envs import episode_steps_limit  # imported here: it imports MuJoCo

    from .writer import fast_writer, size_video_files  # imported here: it imports LeRobot

    datasets.disable_progress_bars()  # the caller shows the progress
    settings = settings.checked()
    root = checked_path(settings.root, "dataset folder", error=OutputPathError)
    _say_what_is_rendered(settings)
    try:
        root.parent.mkdir(parents=True, exist_ok=True)
        # the temporary folder's name stays within NAME_MAX however long root's name is
        tmp = Path(tempfile.mkdtemp(prefix=f".{root.name[:50]}.", dir=root.parent))
    except OSError as exc:
        raise OutputPathError(
            f"cannot write the dataset folder {str(root)!r}: creating a folder in "
            f"{str(root.parent)!r} failed ({exc.strerror}); expected a folder you can write to"
        ) from None
    start = time.perf_counter()
    kept: list[int] = []
    failed: list[int] = []
    randomization: dict[str, Any] = {}
    frames = 0
    sim_seconds = 0.0
    # LeRobot's writer, made to keep up with the workers (.writer)
    dataset = None
    with fast_writer():
        try:
            dataset = LeRobotDataset.create(
                settings.repo_id,
                settings.fps,
                root=tmp / "dataset",
                robot_type=ROBOT_TYPE,
                features=dataset_features(settings),
                use_videos=settings.video,
                image_writer_threads=0,
                # videos are encoded on a thread as frames arrive, not at each save_episode: the
                # writer keeps taking the workers' episodes while the encoder works
                streaming_encoding=settings.video and bool(settings.cameras),
                encoder_threads=ENCODER_THREADS,
                rgb_encoder=RGBEncoderConfig(**VIDEO_CODECS[settings.vcodec]),
                # room for a whole episode's frames: LeRobot drops a frame (a warning, and a video
                # shorter than the episode) when its encoder's queue stays full for 0.1 s, which a
                # busy machine does when the frames come faster than real time, as they do here
                # (at most one more copy of the episode in hand, which is already all in memory;
                # the + 1 is the end-of-video marker LeRobot puts after the last frame)
                encoder_queue_maxsize=episode_steps_limit(settings.task, settings.fps) + 1,
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
                for ep in episodes(settings, seeds):
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
                    if not kept:  # the first episode: the video files sized from its videos
                        size_video_files(dataset, settings.episodes)
                    frames += len(ep.actions)
                    kept.append(ep.seed)
                    if ep.randomization:
                        randomization[str(ep.seed)] = ep.randomization
            dataset.finalize()
            from so101sim.model import servo_model  # imported here: it imports MuJoCo

            recorded = asdict(settings)
            if not (settings.video and settings.cameras):
                recorded["vcodec"] = None  # no video was encoded: no codec, whatever was given
            meta = {
                "generator": "so101sim dataset",
                "task": settings.task,
                "servo_model": servo_model(),  # the environments' default arm profile
                "settings": jsonable(recorded),
                # the cameras as rendered (at --image-size and --fps): the rig to give eval or
                # a real follower
                "cameras": jsonable(
                    [
                        asdict(replace(c, fps=float(settings.fps)))
                        for c in resolve_cameras(settings.cameras, settings.image_size)
                    ]
                ),
                "episode_seeds": kept,
                "failed_seeds": failed,
                "randomize": settings.randomize,
                "randomization": randomization,
            }
            (tmp / "dataset" / "meta" / "so101sim.json").write_text(json.dumps(meta, indent=1))
            os.replace(tmp / "dataset", root)
        except BaseException:
            if dataset is not None:
                _abandon(dataset)
            raise
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
    "VIDEO_CODECS",
    "DatasetReport",
    "DatasetSettings",
    "Episode",
    "dataset_features",
    "generate_dataset",
    "quiet_encoder_logs",
    "simulate_episode",
]
