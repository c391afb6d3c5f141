"""``so101sim dataset``, ``so101sim pretrain-backbone`` and ``so101sim eval``: LeRobot datasets
from the scripted experts, an image ACT's backbone pretrained on one, and policies evaluated
at scale. Their work is in the LeRobot plugins (the only code that imports LeRobot and torch):
``lerobot_robot_so101sim.dataset``, ``lerobot_robot_so101sim.pretrain`` and
``lerobot_env_so101sim.evaluate``,
imported by name only when the command runs; without the plugin installed the command says
what to install (one line, exit status 2). Like the rest of :mod:`so101sim.cli`, this module
only parses and prints.
"""

from __future__ import annotations

import argparse
import importlib
import importlib.util
import os
import sys
from collections.abc import Callable
from typing import Any

from ..errors import MissingDependencyError
from .output import say

SubParsers = Any  # argparse's private _SubParsersAction

PLUGINS = {
    "dataset": ("lerobot_robot_so101sim", "dataset", "./plugins/lerobot_robot_so101sim"),
    "eval": ("lerobot_env_so101sim", "evaluate", "./plugins/lerobot_env_so101sim"),
    "pretrain-backbone": ("lerobot_robot_so101sim", "pretrain", "./plugins/lerobot_robot_so101sim"),
}
"""Each command's plugin: its package, the module with the work, where to install it from."""


def plugin_module(command: str) -> Any:
    """The plugin module that does ``command``'s work.

    Raises:
        MissingDependencyError: its plugin is not installed (the message says what to install).
    """
    package, module, source = PLUGINS[command]
    if importlib.util.find_spec(package) is None:
        raise MissingDependencyError(
            f"so101sim {command} needs the LeRobot plugin {package}: install it with "
            f"`pip install {source}` from so101sim's repository (Python 3.12+, LeRobot 0.6)"
        )
    return importlib.import_module(f"{package}.{module}")


def _size(text: str) -> tuple[int, int]:
    """``WIDTHxHEIGHT`` (as cameras are sized: 640x480) as (height, width)."""
    try:
        w, h = (int(v) for v in text.lower().split("x"))
    except ValueError:
        raise argparse.ArgumentTypeError(
            f"{text!r}: expected WIDTHxHEIGHT in pixels, e.g. 160x120"
        ) from None
    return h, w


def _cameras(text: str) -> tuple[Any, ...]:
    """``--cameras``: presets and camera files, as :func:`so101sim.scenes.parse_cameras`
    (read when the command runs, so that an error is one line)."""
    from ..scenes import parse_cameras  # imported here: it imports MuJoCo (start-up time)

    return parse_cameras(text)


RANDOMIZE_HELP = (
    "none (default), light or full; or a preset with families changed, e.g. "
    "'light,textures=0.5,distractors=2' (docs/tasks.md)"
)


def add_learning_commands(sub: SubParsers) -> None:
    """Add ``dataset`` and ``eval`` to the parser's subcommands."""
    p = sub.add_parser(
        "dataset",
        help="write a LeRobotDataset of a task's scripted expert (needs the LeRobot plugin)",
        description=(
            "Simulates N episodes of TASK's scripted expert (pick_cube, cube_to_bowl, "
            "lift_cylinder, lift_sphere, lift_mesh, push, stack), each from "
            "its own seed, faster than real time on worker processes, and writes them with "
            "LeRobot's dataset writer: the features lerobot-record writes on "
            "--robot.type=so101_sim. Failed takes are left out and counted (replaced by the "
            "next seeds). Needs lerobot_robot_so101sim installed."
        ),
    )
    p.add_argument(
        "task",
        help="pick_cube, cube_to_bowl, lift_cylinder, lift_sphere, lift_mesh, push or stack",
    )
    p.add_argument("--episodes", type=int, required=True, help="episodes to write")
    p.add_argument("-o", "--output", required=True, help="the dataset's folder (must not exist)")
    p.add_argument("--repo-id", default="local/so101sim", help="the dataset's repo_id")
    p.add_argument("--seed", type=int, default=0, help="episode k is drawn from seed + k")
    p.add_argument("--fps", type=int, default=30, help="frames per simulated second (30)")
    p.add_argument(
        "--cameras",
        default="",
        help="comma-separated presets (front, wrist) and TOML files of cameras of your own "
        "(their pose and field of view: docs/cameras.md), e.g. front,wrist or wrist,my_rig.toml; "
        "none by default",
    )
    p.add_argument(
        "--image-size",
        type=_size,
        default=(96, 96),
        help="WIDTHxHEIGHT of the recorded images (default 96x96; a size your camera delivers, "
        "e.g. 160x120 for a 4:3 camera)",
    )
    p.add_argument(
        "--environment-state",
        action="store_true",
        help="also write observation.environment_state (the objects' poses)",
    )
    p.add_argument(
        "--no-video",
        action="store_true",
        help="store the images as PNG frames in the data files, not as videos (larger, and "
        "slower to train ACT on: LeRobot decodes every row of an action chunk's images)",
    )
    p.add_argument(
        "--vcodec",
        default="h264",
        help="the videos' codec: h264 (default: x264's fastest preset, crf 20) or libsvtav1 "
        "(av1: what lerobot-record writes by default; about a third slower to write here)",
    )
    p.add_argument("--randomize", default="none", help=RANDOMIZE_HELP)
    p.add_argument(
        "--after-success", type=float, default=1.0, help="seconds kept after success (1)"
    )
    p.add_argument("--workers", type=int, help="worker processes (default: every core)")
    p.add_argument(
        "--ray",
        nargs="?",
        const="local",
        default=None,
        metavar="ADDRESS",
        help="run the episodes as Ray tasks: --ray (a Ray started here with --workers CPUs), "
        "--ray auto (a cluster started with `ray start --head`) or --ray host:port",
    )
    p.add_argument("--no-progress", action="store_true", help="no progress bar")
    p.set_defaults(func=cmd_dataset)

    p = sub.add_parser(
        "eval",
        help="a policy's success rate on a task, episodes in parallel (needs the LeRobot plugin)",
        description=(
            "Runs N episodes of the policy saved at POLICY_PATH (lerobot-train's "
            ".../pretrained_model) on TASK in worker processes, the environment matching the "
            "policy's inputs, episode k from seed --seed + k; prints the success rate with its "
            "95 % (Wilson) interval and the time to success, writes eval.json and a video of "
            "each failure under --output. Needs lerobot_env_so101sim installed."
        ),
    )
    p.add_argument("policy", metavar="POLICY_PATH", help="the policy's folder (config.json)")
    p.add_argument(
        "--task", default="pick_cube", help="a task of so101sim.envs.TASKS (default pick_cube)"
    )
    p.add_argument("--episodes", type=int, default=10, help="episodes (default 10)")
    p.add_argument("--seed", type=int, default=1000, help="first episode's seed (1000)")
    p.add_argument("--workers", type=int, help="worker processes (default: every core)")
    p.add_argument("--randomize", default="none", help=RANDOMIZE_HELP)
    p.add_argument("--episode-length", type=int, help="steps per episode (default: the task's)")
    p.add_argument(
        "--fps",
        type=int,
        help="policy steps per simulated second (default: its training data's, else 30)",
    )
    p.add_argument("-o", "--output", help="folder for eval.json and the failures' videos")
    p.add_argument("--max-videos", type=int, default=10, help="failure videos at most (10)")
    p.add_argument("--device", default="cpu", help="torch device (cpu)")
    p.add_argument(
        "--cameras",
        default=None,
        metavar="FILE.toml",
        help="where the policy's cameras are when they are not the presets (the camera file "
        "its dataset was recorded with: docs/cameras.md)",
    )
    p.add_argument("--no-progress", action="store_true", help="no progress bar")
    p.set_defaults(func=cmd_eval)

    p = sub.add_parser(
        "pretrain-backbone",
        help="an image ACT whose ResNet-18 has learnt to find the cube, for lerobot-train "
        "--policy.path (needs the LeRobot plugin)",
        description=(
            "Trains the ResNet-18 of an image ACT on DATASET's front and wrist images to tell "
            "where the cube is (on the table; from the gripper), with the cube's pose that "
            "so101sim dataset --environment-state recorded as the label, and writes the ACT "
            "(inputs: joint states and cameras only) to --output, as lerobot-train saves a "
            "checkpoint, for `lerobot-train --policy.path=OUTPUT ...` to train on from it. "
            "Needs lerobot_robot_so101sim installed (docs/learning.md)."
        ),
    )
    p.add_argument(
        "dataset", metavar="DATASET", help="a so101sim dataset folder (--environment-state)"
    )
    p.add_argument("-o", "--output", required=True, help="a new folder for the policy")
    p.add_argument("--steps", type=int, default=500, help="optimiser steps (500)")
    p.add_argument("--batch-size", type=int, default=32, help="frames a step (32)")
    p.add_argument("--lr", type=float, default=3e-4, help="peak learning rate, cosine (3e-4)")
    p.add_argument("--seed", type=int, default=1, help="seed of the weights and batches (1)")
    p.add_argument("--repo-id", default="local/so101sim", help="the dataset's repo id")
    p.add_argument("--dim-model", type=int, default=256, help="ACT's width (256)")
    p.add_argument("--dim-feedforward", type=int, default=1024, help="ACT's MLP width (1024)")
    p.add_argument("--encoder-layers", type=int, default=2, help="ACT's encoder layers (2)")
    p.add_argument("--chunk-size", type=int, default=30, help="ACT's action chunk (30)")
    p.add_argument("--no-progress", action="store_true", help="no progress bar")
    p.set_defaults(func=cmd_pretrain_backbone)

    p = sub.add_parser(
        "policy-check",
        help="will a trained policy run on a real robot's LeRobot config? (one line per mismatch)",
        description=(
            "Reads the inputs of the policy saved at POLICY_PATH (lerobot-train's "
            ".../pretrained_model: config.json, train_config.json and, when it is here, the "
            "training dataset's meta) and a robot config (the JSON or YAML that lerobot-record "
            "--config_path takes, or its robot section alone) and prints one line per "
            "mismatch: a camera the policy reads that the robot lacks, a resolution, the "
            "state's size or names, degrees against range mode, a frame rate. Exit status 0: "
            "none; 1: mismatches; 2: a file could not be read. Needs no LeRobot."
        ),
    )
    p.add_argument("policy", metavar="POLICY_PATH", help="the policy's folder (config.json)")
    p.add_argument(
        "--robot-config", required=True, metavar="FILE", help="the robot's config (JSON/YAML)"
    )
    p.set_defaults(func=cmd_policy_check)


def _workers(value: int | None) -> int:
    return value if value is not None else max(1, len(os.sched_getaffinity(0)))


def _with_bar(total: int, unit: str, disable: bool, run: Callable[[Any], Any]) -> Any:
    """Returns ``run(bar)``, with a progress bar on stderr that is closed however it ends."""
    # start-up: the progress bar's module only when a command that shows one runs
    from tqdm import tqdm

    bar = tqdm(total=total, unit=unit, disable=disable, file=sys.stderr)
    try:
        return run(bar)
    finally:
        bar.close()


def cmd_dataset(args: argparse.Namespace) -> int:
    module = plugin_module("dataset")
    module.quiet_encoder_logs()  # no encoder settings or muxer lines between the progress
    settings = module.DatasetSettings(
        task=args.task,
        episodes=args.episodes,
        root=args.output,
        repo_id=args.repo_id,
        seed=args.seed,
        fps=args.fps,
        cameras=_cameras(args.cameras),
        image_size=args.image_size,
        environment_state=args.environment_state,
        randomize=args.randomize,
        after_success_s=args.after_success,
        workers=_workers(args.workers),
        use_ray=args.ray is not None,
        ray_address=args.ray or "local",
        video=not args.no_video,
        vcodec=args.vcodec,
    ).checked()  # every setting before the bar: an error is its only line

    def run(bar: Any) -> Any:
        def progress(episode: Any) -> None:
            if episode.success:
                bar.update(1)
            else:
                bar.set_postfix_str(f"failed seed {episode.seed}")

        return module.generate_dataset(settings, progress)

    report = _with_bar(args.episodes, "episode", args.no_progress, run)
    say(
        f"wrote {report.episodes} episodes ({report.frames} frames) to {report.root} in "
        f"{report.wall_seconds:.1f} s with {report.workers} worker(s): "
        f"{report.speed:.1f}x real time"
    )
    if report.failed_seeds:
        seeds = ", ".join(str(s) for s in report.failed_seeds)
        say(f"left out {len(report.failed_seeds)} failed take(s): seeds {seeds}")
    return 0


def cmd_eval(args: argparse.Namespace) -> int:
    module = plugin_module("eval")
    settings = module.EvalSettings(
        policy=args.policy,
        task=args.task,
        episodes=args.episodes,
        seed=args.seed,
        workers=_workers(args.workers),
        randomize=args.randomize,
        episode_length=args.episode_length,
        fps=args.fps,
        output=args.output,
        max_videos=args.max_videos,
        device=args.device,
        camera_file=args.cameras,
    ).checked()  # every setting before the bar: an error is its only line
    report = _with_bar(
        args.episodes,
        "episode",
        args.no_progress,
        lambda bar: module.evaluate_policy(settings, lambda _: bar.update(1)),
    )
    low, high = report.interval
    say(
        f"{report.task} (randomize {report.randomize}): success {report.successes}/"
        f"{report.episodes} = {100 * report.success_rate:.0f} % "
        f"(95 % interval {100 * low:.0f}-{100 * high:.0f} %) in {report.wall_seconds:.1f} s "
        f"with {report.workers} worker(s)"
    )
    times = report.success_times
    if times:
        say(f"time to success: mean {sum(times) / len(times):.2f} s, "
              f"median {sorted(times)[len(times) // 2]:.2f} s (simulated)")  # fmt: skip
    videos = [o.video for o in report.outcomes if o.video]
    if videos:
        say(f"videos of {len(videos)} failure(s) in {videos[0].rsplit('/', 1)[0]}")
    return 0


def cmd_pretrain_backbone(args: argparse.Namespace) -> int:
    module = plugin_module("pretrain-backbone")
    settings = module.PretrainSettings(
        dataset=args.dataset,
        output=args.output,
        repo_id=args.repo_id,
        steps=args.steps,
        batch_size=args.batch_size,
        lr=args.lr,
        seed=args.seed,
        dim_model=args.dim_model,
        dim_feedforward=args.dim_feedforward,
        n_encoder_layers=args.encoder_layers,
        chunk_size=args.chunk_size,
    ).checked()  # every setting before the bar: an error is its only line
    report = _with_bar(
        args.steps,
        "step",
        args.no_progress,
        lambda bar: module.pretrain_backbone(settings, lambda _: bar.update(1)),
    )
    say(
        f"wrote {report.output} after {report.steps} steps on {report.frames} frames in "
        f"{report.wall_seconds:.1f} s; held-out error: the cube on the table "
        f"{report.front_error_mm:.1f} mm (guessing the mean: {report.front_baseline_mm:.1f}), "
        f"from the gripper {report.wrist_error_mm:.1f} mm ({report.wrist_baseline_mm:.1f})"
    )
    say(
        f"next: lerobot-train --policy.path={report.output} --dataset.repo_id={args.repo_id} "
        f"--dataset.root={args.dataset} ..."
    )
    return 0


def cmd_policy_check(args: argparse.Namespace) -> int:
    # this command's modules, loaded when it runs (every other command starts without them)
    from ..robot.policycheck import check_policy

    result = check_policy(args.policy, args.robot_config)
    for finding in result.mismatches:
        say(f"{finding.what}: {finding.message}")
    for note in result.notes:
        say(f"note: {note}")
    if result.ok:
        say(f"OK: {args.policy} reads nothing {args.robot_config} does not deliver")
        return 0
    say(f"{len(result.mismatches)} mismatch(es): the policy would not see what it was trained on")
    return 1


__all__ = ["PLUGINS", "add_learning_commands", "plugin_module"]
