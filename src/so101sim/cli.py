"""The ``so101sim`` command line. It parses arguments, calls the library and prints results.

so101sim run            the lab motion (viewer on a desktop, headless otherwise)
so101sim hold           hold the starting pose (the lab's first script)
so101sim view           open the model in MuJoCo's interactive viewer
so101sim model-path     print the folder of the shipped model
so101sim teleop         mirror a LeRobot SO-101 leader arm on the sim in real time
"""

from __future__ import annotations

import argparse
import logging
import sys
from collections.abc import Sequence
from contextlib import ExitStack

from . import __version__
from .errors import So101SimError
from .model import model_dir
from .motion import LAB_MOTION, Hold, RunResult, SegmentResult, run_motion
from .simulation import Pacer, Simulation, ViewerObserver
from .units import GRIPPER, STARTING_POSE, format_pose
from .viewer import has_display, open_viewer, view

log = logging.getLogger("so101sim")


def _unit(name: str) -> str:
    return "" if name == GRIPPER else "°"


def format_segment(seg: SegmentResult) -> str:
    """A phase's report: target, reached pose, largest tracking error."""
    joint, err = seg.worst_tracking_error
    status = "" if seg.completed else "  (stopped early)"
    return (
        f"{seg.phase} [{seg.kind}, {seg.start_time:.3f}-{seg.end_time:.3f} s, "
        f"{seg.steps} steps]{status}\n"
        f"  target : {format_pose(seg.target)}\n"
        f"  reached: {format_pose(seg.reached)}\n"
        f"  largest tracking error: {err:.3f}{_unit(joint)} ({joint})"
    )


def print_run(result: RunResult) -> None:
    for seg in result.segments:
        print(format_segment(seg))
    if not result.completed:
        print(f"run ended early at t = {result.end_time:.3f} s (viewer closed)")


def _add_common(p: argparse.ArgumentParser) -> None:
    p.add_argument("--model", help="MJCF file to load instead of the shipped scene.xml")
    p.add_argument(
        "--headless", action="store_true", help="run without the viewer, even with a display"
    )
    p.add_argument(
        "--speed",
        type=float,
        default=1.0,
        help="viewer playback speed as a multiple of real time (default 1.0)",
    )


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="so101sim", description="A MuJoCo digital twin of the SO-101 arm."
    )
    parser.add_argument("--version", action="version", version=f"so101sim {__version__}")
    parser.add_argument("-v", "--verbose", action="store_true", help="log debug messages")
    sub = parser.add_subparsers(dest="command", required=True)

    p = sub.add_parser("run", help="run the lab motion: rest -> zeros (2 s), hold 2 s, back (2 s)")
    _add_common(p)
    p.set_defaults(func=cmd_run)

    p = sub.add_parser("hold", help="hold the starting (rest) pose, as the lab's first script")
    _add_common(p)
    p.add_argument("--duration", type=float, default=30.0, help="seconds to hold (default 30)")
    p.set_defaults(func=cmd_hold)

    p = sub.add_parser("view", help="open the model in MuJoCo's interactive viewer")
    p.add_argument("--model", help="MJCF file to load instead of the shipped scene.xml")
    p.set_defaults(func=cmd_view)

    p = sub.add_parser("model-path", help="print the folder holding the shipped model")
    p.set_defaults(func=cmd_model_path)

    _add_teleop_parser(sub)
    return parser


def _run_steps(args: argparse.Namespace, steps) -> int:
    sim = Simulation(args.model)
    use_viewer = not args.headless and has_display()
    if not args.headless and not use_viewer:
        print("no display found: running headless (use --headless to say so, xvfb-run to view)")
    with ExitStack() as stack:
        observers = []
        if use_viewer:
            handle = stack.enter_context(open_viewer(sim.model, sim.data))
            observers.append(ViewerObserver(handle, Pacer(args.speed)))
        result = run_motion(sim.model, sim.data, steps, observers=observers)
    print_run(result)
    return 0


def cmd_run(args: argparse.Namespace) -> int:
    return _run_steps(args, LAB_MOTION)


def cmd_hold(args: argparse.Namespace) -> int:
    print(f"holding the starting pose: {format_pose(STARTING_POSE)}")
    return _run_steps(args, (Hold(args.duration, phase="hold"),))


def cmd_view(args: argparse.Namespace) -> int:
    sim = Simulation(args.model)
    view(sim.model, sim.data)
    return 0


def cmd_model_path(args: argparse.Namespace) -> int:
    print(model_dir())
    return 0


def _add_teleop_parser(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "teleop", help="mirror a LeRobot SO-101 leader arm on the sim in real time (Ctrl-C stops)"
    )
    p.add_argument("--port", required=True, help="leader arm's serial port, e.g. /dev/ttyACM0")
    p.add_argument(
        "--calibration",
        help="LeRobot calibration JSON of the leader (default: LeRobot's file for --id if any)",
    )
    p.add_argument("--id", help="leader id whose LeRobot calibration file to use")
    p.add_argument("--fps", type=float, default=60.0, help="ticks per second (default 60)")
    p.add_argument("--duration", type=float, help="stop after this many seconds (default: never)")
    p.add_argument("--model", help="MJCF file to load instead of the shipped scene.xml")
    p.add_argument(
        "--headless", action="store_true", help="run without the viewer, even with a display"
    )
    p.set_defaults(func=cmd_teleop)


def cmd_teleop(args: argparse.Namespace) -> int:
    from . import teleop
    from .robot import SO101SimFollower, SO101SimFollowerConfig

    if args.calibration:
        calibration = teleop.load_calibration(args.calibration)
        print(f"calibration: {args.calibration}")
    elif args.id and teleop.lerobot_calibration_path(args.id).is_file():
        path = teleop.lerobot_calibration_path(args.id)
        calibration = teleop.load_calibration(path)
        print(f"calibration: {path}")
    else:
        calibration = teleop.default_calibration()
        print(
            "no calibration file: assuming LeRobot's calibration (middle = 2047 ticks) and "
            "guessing the gripper's range; pass --calibration for exact values"
        )
    use_viewer = not args.headless and has_display()
    if not args.headless and not use_viewer:
        print("no display found: running headless (use --headless to say so, xvfb-run to view)")
    robot = SO101SimFollower(
        SO101SimFollowerConfig(id="teleop", model=args.model, viewer=use_viewer)
    )
    bus = teleop.FeetechLeaderBus(args.port, calibration=calibration)
    result = None
    try:
        with robot:
            print(f"mirroring the leader on {args.port} at {args.fps:g} Hz; Ctrl-C to stop")
            result = teleop.teleoperate(
                robot,
                bus,
                calibration,
                fps=args.fps,
                duration=args.duration,
                should_stop=(lambda: not robot.viewer_open) if use_viewer else None,
            )
    except KeyboardInterrupt:
        print("stopped")
    finally:
        bus.close()
    if result is not None:
        print(
            f"{result.ticks} ticks in {result.duration:.2f} s "
            f"({result.late_ticks} slower than {args.fps:g} Hz)"
        )
    return 0


def main(argv: Sequence[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    logging.basicConfig(
        level=logging.DEBUG if args.verbose else logging.WARNING,
        format="%(levelname)s %(name)s: %(message)s",
    )
    try:
        return int(args.func(args) or 0)
    except So101SimError as exc:
        print(f"so101sim: error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("so101sim: interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":
    raise SystemExit(main())
