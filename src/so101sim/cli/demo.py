"""``so101sim demo <task>``: one episode of a task's scripted expert, in the viewer when there
is a display (else headless), optionally recorded to a video. Like :mod:`so101sim.cli`, it only
parses and prints: :func:`so101sim.envs.run_expert` runs the episode. MuJoCo is imported inside
the command, after ``--record`` has chosen the OpenGL backend.
"""

from __future__ import annotations

import argparse
from typing import Any

from .output import say
from .studio import add_web_options
from .tools import add_video_options

SubParsers = Any  # argparse's private _SubParsersAction


ATTEMPT_NOUN = {"push": "push"}
"""What a task's expert tries again when it falls short (others: a grasp)."""
NO_ATTEMPTS = ("look_at", "reach")
"""Tasks whose expert tries nothing again (it aims the camera or the tip)."""


def add_demo_command(sub: SubParsers, *, arm: argparse.ArgumentParser) -> None:
    """Add ``demo`` to the parser's subcommands."""
    p = sub.add_parser(
        "demo",
        parents=[arm],
        help="run a task's scripted expert once (see so101sim.envs.TASKS) or record it",
        description=(
            "Runs the scripted expert of TASK for one episode from the start poses drawn from "
            "--seed: in MuJoCo's viewer when there is a display (unless --headless), and with "
            "--record to an MP4. Prints whether it succeeded, the simulated time and the task's "
            "figure (how high the cube rose, how far it is from the bowl's centre). Exit "
            "status 0 on success, 1 when the task failed, 2 on a bad setting."
        ),
    )
    p.add_argument(
        "task",
        help="the task: pick_cube, cube_to_bowl, reach, lift_cylinder, lift_sphere, lift_mesh, "
        "push, stack or look_at",
    )
    p.add_argument("--seed", type=int, default=0, help="episode seed (default 0)")
    p.add_argument(
        "--headless", action="store_true", help="run without the viewer, even with a display"
    )
    g = p.add_argument_group("recording")
    g.add_argument("--record", metavar="PATH", help="write an H.264 video of the episode (.mp4)")
    add_video_options(
        g, camera="front", camera_help="'front' (default), 'wrist', or 'free' (fitted view)"
    )
    g.add_argument(
        "--caption",
        action=argparse.BooleanOptionalAction,
        default=True,
        help="draw the time into the video (default: on)",
    )
    g.add_argument("--force", action="store_true", help="overwrite an existing video")
    add_web_options(p)
    p.set_defaults(func=cmd_demo)


def format_figures(figures: dict[str, float]) -> str:
    """The task's figure in words: the cube's rise, or its distance from the bowl."""
    parts = []
    if "cube_rise_m" in figures:
        parts.append(f"cube lifted {figures['cube_rise_m'] * 1000:.1f} mm")
    if "object_rise_m" in figures:
        parts.append(f"object lifted {figures['object_rise_m'] * 1000:.1f} mm")
    if "cube_to_bowl_m" in figures:
        where = "in the bowl" if figures.get("in_bowl") else "not in the bowl"
        parts.append(
            f"cube {figures['cube_to_bowl_m'] * 1000:.1f} mm from the bowl's centre ({where})"
        )
    if "cube_to_mark_m" in figures:
        parts.append(f"cube {figures['cube_to_mark_m'] * 1000:.1f} mm from the mark's centre")
    if "cube_to_block_m" in figures:
        where = "on the block" if figures.get("on_block") else "not on the block"
        parts.append(
            f"cube {figures['cube_to_block_m'] * 1000:.1f} mm from the block's centre ({where})"
        )
    if "image_offset" in figures:
        parts.append(
            f"cube seen {figures['image_offset']:.3f} half-heights from the wrist image's centre"
        )
    if "goal_distance_m" in figures:
        parts.append(f"tip {figures['goal_distance_m'] * 1000:.1f} mm from the target")
    if "grasped" in figures:
        parts.append("held in the gripper" if figures["grasped"] else "not held")
    return ", ".join(parts)


def cmd_demo(args: argparse.Namespace) -> int:
    if args.web:  # the episode in a browser (cli/studio.py)
        from .studio import demo_web

        return demo_web(args, format_figures)
    if args.record:
        from ..gl import prepare_for_rendering  # imported here: only rendering needs it

        prepare_for_rendering()
    from ..envs import env_id, run_expert  # imported here: they import MuJoCo
    from ..recording import VideoSettings
    from ..viewer import choose_viewer

    env_id(args.task)  # an unknown task: SettingError listing the tasks (exit status 2)
    viewer = choose_viewer(args.headless)
    if viewer.note:
        say(viewer.note)
    fields = ("width", "height", "fps", "camera", "quality", "caption")
    settings = VideoSettings(**{name: getattr(args, name) for name in fields}).validated()
    result = run_expert(
        args.task,
        args.seed,
        record=args.record,
        video=settings,
        force=args.force,
        viewer=viewer.use,
        arm=args.arm,
    )
    if result.success_time is not None:
        status = f"success at t = {result.success_time:.2f} s"
    else:
        status = "FAILED" if result.completed else "stopped (viewer closed)"
    what = ATTEMPT_NOUN.get(args.task, "grasp")  # what the expert's attempts are
    tries = what if result.attempts == 1 else f"{what}es" if what.endswith("sh") else f"{what}s"
    grasps = (
        ""
        if "goal_distance_m" in result.figures or args.task in NO_ATTEMPTS
        else f", {result.attempts} {tries} tried"
    )
    say(
        f"{args.task}, seed {result.seed}: {status} "
        f"({result.sim_time:.2f} s of simulated time in all, {result.steps} steps{grasps})"
    )
    say(format_figures(result.figures))
    if result.video is not None:
        say(f"wrote the video to {result.video} ({result.video_frames} frames)")
    return 0 if result.success or not result.completed else 1
