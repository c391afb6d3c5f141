"""``so101sim eval POLICY_PATH --task TASK --episodes N``: a policy's success rate on a task,
with its 95 % interval, over episodes run in parallel worker processes.

Each worker loads the policy once (``make_policy`` and its saved processors, as
``lerobot-eval`` does) and runs its episodes through LeRobot's own ``rollout()`` on this
plugin's environment, which takes its cameras, image size and state from the policy's input
features (:meth:`~.configs.SO101SimEnvConfig.match_policy`). Episode ``k`` starts from seed
``seed + k`` (the same start poses, and with ``randomize`` the same scene, whatever the worker
count). The report gives the success rate with its Wilson score interval (95 %), the simulated
time to success (mean, median), and a video of each failed episode (up to ``max_videos``: the
``front`` view, and beside it what the policy saw, its own cameras at their size scaled up)
under ``output``; ``eval.json`` there holds all of it.
"""

from __future__ import annotations

import json
import math
import os
import time
from collections.abc import Callable
from concurrent.futures import ProcessPoolExecutor
from dataclasses import asdict, dataclass, replace
from multiprocessing import get_context
from pathlib import Path
from typing import Any

import numpy as np

from so101sim.errors import OutputPathError, SettingError
from so101sim.robot import training_fps
from so101sim.scenes import load_cameras, randomization
from so101sim.validation import check_choice, check_count

TASK_TYPES = {
    "pick_cube": "PickCube-v0",
    "cube_to_bowl": "CubeToBowl-v0",
    "reach": "Reach-v0",
    "lift_cylinder": "LiftCylinder-v0",
    "lift_sphere": "LiftSphere-v0",
    "lift_mesh": "LiftMesh-v0",
    "push": "Push-v0",
    "stack": "Stack-v0",
    "look_at": "LookAt-v0",
}
"""The tasks (``--task``) and their Gymnasium names (``--env.type=so101sim_<task>``)."""
MAX_EPISODES = 100_000
MAX_WORKERS = 256
Z95 = 1.959963984540054
DEFAULT_FPS = 30


@dataclass(frozen=True)
class EvalSettings:
    """What to evaluate (checked by :meth:`checked`)."""

    policy: str
    task: str = "pick_cube"
    episodes: int = 10
    seed: int = 1000
    workers: int = 1
    randomize: str = "none"
    episode_length: int | None = None
    fps: int | None = None
    """Policy steps a simulated second: the training data's (its ``meta/info.json``), else 30."""
    output: str | None = None
    max_videos: int = 10
    device: str = "cpu"
    camera_file: str | None = None
    """Where the policy's cameras of your own are (a TOML camera file, docs/cameras.md)."""

    def checked(self) -> EvalSettings:
        """These settings checked, ``fps`` set (see its text).

        Raises:
            SettingError: a bad setting, or an ``fps`` the policy was not trained at.
        """
        check_choice(self.task, "task", TASK_TYPES)
        check_count(self.episodes, "episodes", minimum=1, maximum=MAX_EPISODES)
        check_count(self.seed, "seed", maximum=2**62)
        check_count(self.workers, "workers", minimum=1, maximum=MAX_WORKERS)
        check_count(self.max_videos, "max_videos", maximum=MAX_EPISODES)
        if self.episode_length is not None:
            check_count(self.episode_length, "episode_length", minimum=1, maximum=1_000_000)
        randomization(self.randomize)  # a preset, or one with families changed: raises
        if not Path(self.policy).joinpath("config.json").is_file():
            raise SettingError(
                f"{self.policy!r} holds no config.json; expected a policy folder as "
                f"lerobot-train saves it (.../checkpoints/last/pretrained_model)"
            )
        trained_at = training_fps(self.policy)
        fps = self.fps if self.fps is not None else trained_at or DEFAULT_FPS
        check_count(fps, "fps", minimum=1, maximum=500, unit=" Hz")
        if trained_at is not None and fps != trained_at:
            raise SettingError(
                f"fps = {fps}: the policy was trained on {trained_at} fps data (its dataset's "
                f"meta/info.json), so it acts {trained_at} times a simulated second; expected "
                f"{trained_at} (leave --fps out)"
            )
        if self.camera_file is not None:
            load_cameras(self.camera_file)  # an unreadable file or a bad camera: said now
        if self.output is not None and Path(self.output, "eval.json").exists():
            raise OutputPathError(
                f"{self.output!r} holds an earlier evaluation (eval.json, its failure videos); "
                "expected a new folder for -o (or remove that one)"
            )
        return replace(self, fps=fps)


@dataclass(frozen=True)
class EpisodeOutcome:
    seed: int
    success: bool
    steps: int
    success_time_s: float | None
    video: str | None = None
    randomization: dict[str, Any] | None = None
    """What the episode's scene drew (``--randomize``), as the environment recorded it."""


@dataclass(frozen=True)
class EvalReport:
    """The result of :func:`evaluate_policy`."""

    task: str
    randomize: str
    outcomes: tuple[EpisodeOutcome, ...]
    wall_seconds: float
    workers: int
    settings: EvalSettings | None = None
    """What was run (checked: ``fps`` set), written to eval.json beside the results."""

    @property
    def episodes(self) -> int:
        return len(self.outcomes)

    @property
    def successes(self) -> int:
        return sum(o.success for o in self.outcomes)

    @property
    def success_rate(self) -> float:
        return self.successes / self.episodes if self.episodes else 0.0

    @property
    def interval(self) -> tuple[float, float]:
        """The Wilson score interval of the success rate, 95 %."""
        return wilson_interval(self.successes, self.episodes)

    @property
    def success_times(self) -> list[float]:
        return [o.success_time_s for o in self.outcomes if o.success_time_s is not None]

    def as_dict(self) -> dict[str, Any]:
        from so101sim.model import servo_model  # imported here: it imports MuJoCo

        times = self.success_times
        s = self.settings
        run: dict[str, Any] = {}
        if s is not None:
            from so101sim.envs import episode_steps_limit  # imported here: it imports MuJoCo

            fps = s.fps if s.fps is not None else DEFAULT_FPS
            steps = s.episode_length or episode_steps_limit(s.task, fps)
            run = {"policy": str(Path(s.policy).resolve()), "seed": s.seed, "fps": fps,
                   "episode_length": steps, "camera_file": s.camera_file,
                   "device": s.device}  # fmt: skip
        return {
            **run,
            "task": self.task,
            "servo_model": servo_model(),  # the environments' default arm profile
            "randomize": self.randomize,
            "episodes": self.episodes,
            "successes": self.successes,
            "success_rate": self.success_rate,
            "success_interval_95": list(self.interval),
            "time_to_success_s": {
                "mean": float(np.mean(times)) if times else None,
                "median": float(np.median(times)) if times else None,
            },
            "failure_videos": [o.video for o in self.outcomes if o.video],
            "per_episode": [asdict(o) for o in self.outcomes],
            "wall_seconds": self.wall_seconds,
            "workers": self.workers,
        }


def wilson_interval(successes: int, n: int, z: float = Z95) -> tuple[float, float]:
    """The Wilson score interval for ``successes`` of ``n`` (95 % by default)."""
    if n <= 0:
        return (0.0, 1.0)
    p = successes / n
    denom = 1 + z * z / n
    centre = (p + z * z / (2 * n)) / denom
    half = z * math.sqrt(p * (1 - p) / n + z * z / (4 * n * n)) / denom
    return (max(0.0, centre - half), min(1.0, centre + half))


_loaded: dict[str, Any] = {}


def _setup(settings: EvalSettings) -> dict[str, Any]:
    """The env config, the vector env, the policy and the processors (once per process)."""
    key = json.dumps(asdict(settings), sort_keys=True)
    if key in _loaded:
        return _loaded[key]
    import torch
    from lerobot.configs.policies import PreTrainedConfig
    from lerobot.envs.configs import EnvConfig
    from lerobot.envs.factory import make_env, make_env_pre_post_processors
    from lerobot.policies import make_policy, make_pre_post_processors

    import lerobot_env_so101sim  # noqa: F401  (registers the env types)

    torch.set_num_threads(1)
    kind = f"so101sim_{settings.task}"
    cfg = EnvConfig.get_choice_class(kind)(
        policy_path=settings.policy,
        episode_length=settings.episode_length,
        fps=settings.fps,
        randomize=settings.randomize,
        camera_file=settings.camera_file,
    )
    policy_cfg = PreTrainedConfig.from_pretrained(settings.policy)
    policy_cfg.pretrained_path = settings.policy
    policy_cfg.device = settings.device
    policy = make_policy(cfg=policy_cfg, env_cfg=cfg)
    policy.eval()
    pre, post = make_pre_post_processors(
        policy_cfg=policy_cfg,
        pretrained_path=settings.policy,
        preprocessor_overrides={"device_processor": {"device": settings.device}},
    )
    env_pre, env_post = make_env_pre_post_processors(env_cfg=cfg, policy_cfg=policy_cfg)
    vec = make_env(cfg, n_envs=1)[kind][0]
    _loaded.clear()
    _loaded[key] = {"vec": vec, "policy": policy, "pre": pre, "post": post,
                    "env_pre": env_pre, "env_post": env_post, "cfg": cfg}  # fmt: skip
    return _loaded[key]


class _SeenImages:
    """The vector environment, passed through, keeping the camera images of its last
    observation (what the policy is given): the failure videos show them."""

    def __init__(self, vec: Any) -> None:
        self._vec = vec
        self.pixels: dict[str, np.ndarray] = {}

    def __getattr__(self, name: str) -> Any:
        return getattr(self._vec, name)

    def _keep(self, obs: Any) -> None:
        pixels = obs.get("pixels") if isinstance(obs, dict) else None
        self.pixels = {k: np.asarray(v)[0] for k, v in pixels.items()} if pixels else {}

    def reset(self, *args: Any, **kwargs: Any) -> Any:
        out = self._vec.reset(*args, **kwargs)
        self._keep(out[0])
        return out

    def step(self, *args: Any, **kwargs: Any) -> Any:
        out = self._vec.step(*args, **kwargs)
        self._keep(out[0])
        return out


def _scaled(img: np.ndarray, height: int) -> np.ndarray:
    """``img`` scaled to ``height`` rows (nearest pixel: the policy's pixels stay visible)."""
    h, w = img.shape[:2]
    width = max(2, round(w * height / h) // 2 * 2)
    return img[(np.arange(height) * h) // height][:, (np.arange(width) * w) // width]


def side_by_side(front: np.ndarray, seen: dict[str, np.ndarray]) -> np.ndarray:
    """The front view with the policy's camera images, scaled to its height, on its right."""
    height = front.shape[0]
    parts = [np.asarray(front, dtype=np.uint8)]
    parts += [_scaled(np.asarray(img, dtype=np.uint8), height) for img in seen.values()]
    return np.concatenate(parts, axis=1)


def run_episode(settings: EvalSettings, index: int) -> EpisodeOutcome:
    """Episode ``index`` (seed ``settings.seed + index``), in this process."""
    from unittest import mock

    from lerobot.scripts import lerobot_eval

    s = _setup(settings)
    seed = settings.seed + index
    frames: list[np.ndarray] = []
    drawn: list[Any] = []

    seen = _SeenImages(s["vec"])

    def render(env: Any) -> None:
        if not frames:  # the first call follows the episode's reset: its scene's draws
            drawn.append(getattr(env.envs[0].unwrapped, "randomization", None))
        frames.append(side_by_side(env.envs[0].render(), seen.pixels))

    # one bar for the whole evaluation (ours): rollout()'s per-step bar is off, as LeRobot
    # turns it off under Slurm
    with mock.patch.object(lerobot_eval, "inside_slurm", lambda: True):
        out = lerobot_eval.rollout(seen, s["policy"], s["env_pre"], s["env_post"], s["pre"],
                                   s["post"], seeds=[seed], render_callback=render)  # fmt: skip
    success = out["success"][0].numpy()
    done = out["done"][0].numpy()
    steps = int(np.argmax(done)) + 1 if done.any() else len(done)
    hits = np.flatnonzero(success[:steps])
    ok = bool(len(hits))
    video = None
    if not ok and settings.output is not None:
        # frame 0 is the reset, frame k the scene after step k; the one after the last step
        # may already be the vector env's automatic reset (the next episode's scene)
        video = _write_video(settings, seed, frames[:steps])
    return EpisodeOutcome(
        seed=seed,
        success=ok,
        steps=steps,
        success_time_s=float((hits[0] + 1) / settings.fps) if ok else None,
        video=video,
        randomization=json.loads(json.dumps(drawn[0], default=float)) if drawn[0] else None,
    )


def _write_video(settings: EvalSettings, seed: int, frames: list[np.ndarray]) -> str | None:
    if not frames or settings.output is None:
        return None
    import imageio.v2 as imageio

    folder = Path(settings.output) / "videos"
    folder.mkdir(parents=True, exist_ok=True)
    path = folder / f"failure_seed{seed}.mp4"
    with imageio.get_writer(str(path), fps=settings.fps, macro_block_size=1) as writer:
        for f in frames:
            writer.append_data(np.asarray(f, dtype=np.uint8))
    return str(path)


def _worker_init() -> None:
    os.environ.setdefault("OMP_NUM_THREADS", "1")
    from so101sim.gl import one_rasterizer_thread  # Mesa draws in the worker's own thread

    one_rasterizer_thread()


def evaluate_policy(
    settings: EvalSettings, progress: Callable[[EpisodeOutcome], None] | None = None
) -> EvalReport:
    """Run the episodes (see the module's text); ``progress`` is called after each.

    Raises:
        SettingError: a bad setting or a policy this environment cannot match;
            OutputPathError: ``output`` cannot be written.
    """
    settings = settings.checked()
    start = time.perf_counter()
    if settings.output is not None:
        try:
            Path(settings.output).mkdir(parents=True, exist_ok=True)
        except OSError as exc:
            raise OutputPathError(f"cannot make {settings.output} ({exc})") from exc
    # each failed episode writes its video in its worker; those past max_videos are removed
    outcomes: list[EpisodeOutcome] = []
    indices = list(range(settings.episodes))
    if settings.workers == 1:
        for i in indices:
            o = run_episode(settings, i)
            outcomes.append(o)
            if progress is not None:
                progress(o)
    else:
        ctx = get_context("spawn")
        with ProcessPoolExecutor(
            settings.workers, mp_context=ctx, initializer=_worker_init
        ) as pool:
            for o in pool.map(run_episode, [settings] * len(indices), indices):
                outcomes.append(o)
                if progress is not None:
                    progress(o)
    kept = 0
    final = []
    for o in outcomes:
        if o.video is not None:
            if kept >= settings.max_videos:
                Path(o.video).unlink(missing_ok=True)
                o = replace(o, video=None)  # its draws and the rest kept
            else:
                kept += 1
        final.append(o)
    report = EvalReport(
        task=settings.task,
        randomize=settings.randomize,
        outcomes=tuple(final),
        wall_seconds=time.perf_counter() - start,
        workers=settings.workers,
        settings=settings,
    )
    if settings.output is not None:
        Path(settings.output, "eval.json").write_text(json.dumps(report.as_dict(), indent=1))
    return report


__all__ = ["EpisodeOutcome", "EvalReport", "EvalSettings", "evaluate_policy", "wilson_interval"]
