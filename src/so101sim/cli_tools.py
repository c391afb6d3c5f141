"""More ``so101sim`` commands: ``record`` (a student's own script to a video), ``workspace``,
``cache`` and ``examples``. Like :mod:`so101sim.cli`, they only parse and print: each calls
one library function. Heavy modules are imported inside the commands, to keep start-up fast.
"""

from __future__ import annotations

import argparse
import sys
import traceback
from typing import Any

SubParsers = Any  # argparse's private _SubParsersAction


def add_commands(
    sub: SubParsers, *, recording: argparse.ArgumentParser, model: argparse.ArgumentParser
) -> None:
    """Add ``record``, ``workspace``, ``cache`` and ``examples`` to the parser's subcommands."""
    p = sub.add_parser(
        "record",
        parents=[recording],
        help="run your own simulation script headless and record it to a video",
        description=(
            "Runs SCRIPT unchanged: its mujoco.viewer.launch_passive(m, d) records instead of "
            "opening a window, and its clock (time.time, time.sleep, ...) follows simulated "
            "time, so a wall-clock '2 s' move is 2 s of simulated time. Arguments after '--' "
            "go to the script."
        ),
    )
    p.add_argument("script", help="the Python script to run (as you run it with python)")
    p.add_argument("-o", "--output", required=True, help="the video to write (.mp4)")
    p.add_argument("--title", help="a title in the caption and the video's metadata")
    p.add_argument("script_args", nargs="*", help="arguments for the script, after --")
    p.set_defaults(func=cmd_record)

    p = sub.add_parser(
        "workspace",
        parents=[model],
        help="draw the region the gripper's tip can reach (side and top views)",
    )
    p.add_argument("--plot", required=True, metavar="PATH", help="the picture to write (.png)")
    p.add_argument(
        "--pitch", type=float, default=-90.0, help="tool pitch of the second panel (default -90)"
    )
    p.add_argument("--samples", type=int, default=20000, help="random poses sampled")
    p.add_argument("--force", action="store_true", help="overwrite an existing file")
    p.set_defaults(func=cmd_workspace)

    p = sub.add_parser("cache", help="the cache of compiled models: where, how big, clear it")
    p.add_argument("action", choices=("info", "clear"), help="info (default) or clear", nargs="?")
    p.set_defaults(func=cmd_cache)

    p = sub.add_parser("examples", help="copy the example scripts and motion files to a folder")
    p.add_argument("folder", help="where to copy them (made if missing)")
    p.add_argument("--force", action="store_true", help="overwrite files already there")
    p.set_defaults(func=cmd_examples)


def split_script_args(argv: list[str]) -> tuple[list[str], list[str] | None]:
    """For ``so101sim record SCRIPT ... -- ARGS``: (the arguments for so101sim, ARGS for the
    script); None when the command is not ``record`` or there is no ``--``."""
    if "record" not in argv or "--" not in argv or argv.index("--") < argv.index("record"):
        return argv, None
    cut = argv.index("--")
    return argv[:cut], argv[cut + 1 :]


def cmd_record(args: argparse.Namespace) -> int:
    from .handin import run_script  # imported here: it imports MuJoCo

    script_args = list(args.script_args)
    options = {
        "title": args.title,
        "width": args.width,
        "height": args.height,
        "fps": args.fps,
        "camera": args.camera,
        "quality": args.quality,
        "caption": args.caption,
        "plot": args.plot,
        "log": args.log,
        "force": args.force,
    }
    try:
        run = run_script(args.script, script_args, args.output, **options)
    except Exception as exc:
        from .errors import So101SimError

        if isinstance(exc, So101SimError):
            raise
        traceback.print_exc()  # the script's own error, as Python shows it
        print(f"so101sim: {args.script} raised {type(exc).__name__}", file=sys.stderr)
        return 1
    if run.message:
        print(run.message, file=sys.stderr)
    for kind, path in run.outputs.items():
        print(f"wrote the {kind} to {path}")
    print(f"{args.script}: {run.simulated_seconds:.3f} s of simulated time")
    return run.exit_status


def cmd_workspace(args: argparse.Namespace) -> int:
    from .kinematics import plot_workspace, sample_workspace  # imported here: MuJoCo
    from .model import load_model

    model = load_model(args.model)
    path = plot_workspace(
        args.plot, pitch=args.pitch, samples=args.samples, force=args.force, model=model
    )
    reach = sample_workspace(samples=args.samples, model=model).reach_m
    print(f"wrote the workspace to {path}; the tip reaches {reach:.3f} m from the base")
    return 0


def cmd_cache(args: argparse.Namespace) -> int:
    from . import modelcache

    if args.action == "clear":
        gone = modelcache.clear()
        print(
            f"deleted {gone.entries} compiled model(s), {gone.size / 1e6:.1f} MB, in {gone.folder}"
        )
        return 0
    info = modelcache.info()
    state = "on" if modelcache.enabled() else "off (SO101SIM_NO_CACHE)"
    print(
        f"{info.folder}: {info.entries} compiled model(s), {info.size / 1e6:.1f} MB; cache {state}"
    )
    return 0


def cmd_examples(args: argparse.Namespace) -> int:
    from .starter import copy_examples

    copied = copy_examples(args.folder, force=args.force)
    for path in copied:
        print(path)
    print(f"copied {len(copied)} file(s) to {args.folder}")
    return 0
