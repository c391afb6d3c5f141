"""The ``so101sim`` command line. It parses arguments, calls the library and prints results.

so101sim run [MOTION]   a motion file, by default the lab motion (viewer on a desktop)
so101sim pose           pose the arm in the viewer; prints each pose as a dict and as TOML
so101sim check MOTION   simulate a motion headless and judge it: PASS or FAIL
so101sim hold           hold the starting pose (the lab's first script)
so101sim view           open the model in MuJoCo's interactive viewer
so101sim model-path     print the folder of the shipped model
so101sim teleop         mirror a LeRobot SO-101 leader arm on the sim in real time
"""

from __future__ import annotations

import argparse
import contextlib
import logging
import sys
from collections.abc import Iterator, Sequence
from contextlib import ExitStack
from typing import TYPE_CHECKING

from . import __version__
from .errors import So101SimError
from .model import arm_units, load_model, model_dir
from .motion import (
    Hold,
    RunResult,
    Segment,
    SegmentResult,
    run_motion,
    validate_segments,
)
from .motionfile import lab_motion_path, load_motion
from .simulation import Pacer, Simulation, ViewerObserver
from .trajectory import check_limited_moves
from .units import GRIPPER, STARTING_POSE, Pose, format_pose
from .validation import check_duration
from .viewer import has_display, open_viewer, view

if TYPE_CHECKING:
    from tqdm import tqdm

    from .recording import Recorder

SubParsers = argparse._SubParsersAction  # the object add_subparsers() returns

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

    p = sub.add_parser("run", help="run a motion file (default: the lab motion)")
    _add_common(p)
    _add_motion_args(p)
    add_recording_options(p)
    p.set_defaults(func=cmd_run)

    p = sub.add_parser("hold", help="hold the starting (rest) pose, as the lab's first script")
    _add_common(p)
    p.add_argument("--duration", type=float, default=30.0, help="seconds to hold (default 30)")
    add_recording_options(p)
    p.set_defaults(func=cmd_hold)

    p = sub.add_parser("view", help="open the model in MuJoCo's interactive viewer")
    p.add_argument("--model", help="MJCF file to load instead of the shipped scene.xml")
    p.set_defaults(func=cmd_view)

    p = sub.add_parser("model-path", help="print the folder holding the shipped model")
    p.set_defaults(func=cmd_model_path)

    _add_pose_parser(sub)
    _add_check_parser(sub)
    _add_teleop_parser(sub)
    return parser


def _run_steps(
    args: argparse.Namespace, steps: Sequence[Segment], start: Pose = STARTING_POSE
) -> int:
    pacer = Pacer(args.speed)  # checks --speed before anything opens
    sim = Simulation(args.model, initial_pose=start)
    validate_segments(sim.model, steps)  # every target and duration, before anything runs
    recorder, bar = recorder_from_args(args, sim, sum(s.duration for s in steps))  # checks paths
    use_viewer = not args.headless and has_display()
    if not args.headless and not use_viewer:
        print("no display found: running headless (use --headless to say so, xvfb-run to view)")
    with ExitStack() as stack:
        observers = []
        if recorder is not None:
            stack.enter_context(_reporting(recorder, bar))
            observers.extend(recorder.observers)
        if use_viewer:
            handle = stack.enter_context(open_viewer(sim.model, sim.data))
            observers.append(ViewerObserver(handle, pacer))
        result = run_motion(sim.model, sim.data, steps, observers=observers)
    print_run(result)
    return 0


# ---------------------------------------------------------------------------- recording
def add_recording_options(p: argparse.ArgumentParser) -> None:
    """The --record/--plot/--log options of ``run`` and ``hold``."""
    from .recording import QUALITY_CHOICES

    g = p.add_argument_group("recording (video, plot and log of the run, no screen recorder)")
    g.add_argument("--record", metavar="PATH", help="write an H.264 video of the run (.mp4)")
    g.add_argument("--plot", metavar="PATH", help="plot commanded vs measured angles (.png)")
    g.add_argument("--log", metavar="PATH", help="log every control step to a CSV file")
    g.add_argument("--width", type=int, default=640, help="video width in pixels (default 640)")
    g.add_argument("--height", type=int, default=480, help="video height in pixels (default 480)")
    g.add_argument("--fps", type=float, default=30.0, help="video frames per simulated second")
    g.add_argument(
        "--camera", default="free", help="'free' (the viewer's view) or a camera of the model"
    )
    g.add_argument(
        "--quality",
        choices=QUALITY_CHOICES,
        default="auto",
        help="draft: fast on a CPU (simplified meshes, no shadows); full: the model's look; "
        "auto (default): draft when rendering on the CPU, full on a GPU",
    )
    g.add_argument(
        "--caption",
        action=argparse.BooleanOptionalAction,
        default=True,
        help="draw the time and phase into the video (default: on)",
    )
    g.add_argument("--force", action="store_true", help="overwrite existing output files")


def recorder_from_args(
    args: argparse.Namespace, sim: Simulation, duration: float
) -> tuple[Recorder | None, tqdm | None]:
    """``(recorder, progress_bar)`` for the options (``(None, None)`` if no output was asked
    for). Checks every path and setting before anything runs."""
    if not (args.record or args.plot or args.log):
        return None, None
    from tqdm import tqdm

    from .recording import Recorder, VideoSettings, video_frames

    settings = VideoSettings(
        width=args.width,
        height=args.height,
        fps=args.fps,
        camera=args.camera,
        quality=args.quality,
        caption=args.caption,
    ).validated()
    bar = None
    if args.record:
        bar = tqdm(
            total=video_frames(duration, settings.fps),
            unit="frame",
            desc="recording",
            file=sys.stderr,
            delay=1.0,  # shown only for renders that take more than a second
            disable=None,  # and only on a terminal
            leave=False,
        )
    recorder = Recorder(
        sim,
        video=args.record,
        plot=args.plot,
        log=args.log,
        settings=settings,
        force=args.force,
        progress=bar.update if bar is not None else None,
    )
    return recorder, bar


@contextlib.contextmanager
def _reporting(recorder: Recorder, bar: tqdm | None) -> Iterator[Recorder]:
    """Close the recorder's files on the way out (also on Ctrl-C) and say what was written."""
    interrupted = False
    try:
        yield recorder
    except KeyboardInterrupt:
        interrupted = True
        raise
    finally:
        if bar is not None:
            bar.close()
        written = recorder.close()
        what = "so far " if interrupted else ""
        for key, path in written.items():
            extra = f" ({recorder.video.frames} frames)" if key == "video" else ""
            print(f"wrote the {key} {what}to {path}{extra}")


def cmd_run(args: argparse.Namespace) -> int:
    motion = load_motion(args.motion if args.motion else lab_motion_path())
    if args.strict:
        m = load_model(args.model)
        units = arm_units(m)
        start = units.pose_to_array(motion.start)
        check_limited_moves(start, motion.steps, m.opt.timestep, units=units, strict=True)
    return _run_steps(args, motion.steps, motion.start)


def cmd_hold(args: argparse.Namespace) -> int:
    duration = check_duration(args.duration, "hold duration")
    print(f"holding the starting pose: {format_pose(STARTING_POSE)}")
    return _run_steps(args, (Hold(duration, phase="hold"),))


def cmd_view(args: argparse.Namespace) -> int:
    sim = Simulation(args.model)
    view(sim.model, sim.data)
    return 0


def cmd_model_path(args: argparse.Namespace) -> int:
    print(model_dir())
    return 0


# ---------------------------------------------------------------------------- motion files
def _add_motion_args(p: argparse.ArgumentParser) -> None:
    p.add_argument(
        "motion",
        nargs="?",
        help="a TOML motion file (default: the shipped lab motion, rest -> zeros -> rest)",
    )
    p.add_argument(
        "--strict",
        action="store_true",
        help="refuse 'limited' moves shorter than the joint limits allow (default: stretch them)",
    )


# ---------------------------------------------------------------------------- pose finder
def _add_pose_parser(sub: SubParsers) -> None:
    p = sub.add_parser(
        "pose", help="pose the arm in the viewer; prints each pose as a Python dict and as TOML"
    )
    p.add_argument("--model", help="MJCF file to load instead of the shipped scene.xml")
    p.set_defaults(func=cmd_pose)


def cmd_pose(args: argparse.Namespace) -> int:
    from .posefinder import format_python, format_toml, pose_scene, watch_poses

    m, d = pose_scene(args.model)
    # Open the viewer first: without a display its error is all the user sees.
    with open_viewer(m, d, show_ui=True) as handle:
        print(
            "Move the joint sliders (right panel, 'Joint'), or double-click a part and "
            "Ctrl+right-drag it. Each pose the arm is left in is printed below; close the "
            "window to finish.",
            flush=True,
        )
        for change in watch_poses(handle, m, d):
            print(
                f"\n# pose {change.number} (t = {change.time:.1f} s)\n"
                f"python: {format_python(change.pose)}\n"
                f"toml:   {format_toml(f'pose_{change.number}', change.pose)}",
                flush=True,
            )
    return 0


# ---------------------------------------------------------------------------- preflight
def _add_check_parser(sub: SubParsers) -> None:
    p = sub.add_parser(
        "check", help="simulate a motion file headless and judge it before hardware: PASS/FAIL"
    )
    p.add_argument("motion", help="the TOML motion file to check")
    p.add_argument("--model", help="MJCF file to load instead of the shipped scene.xml")
    p.add_argument("--json", action="store_true", help="print the report as JSON")
    p.add_argument(
        "--max-effort",
        type=float,
        default=0.9,
        help="effort (fraction of the actuator's force limit) counted as saturated (default 0.9)",
    )
    p.add_argument(
        "--max-saturation",
        type=float,
        default=0.03,
        help="seconds the effort may stay above --max-effort (default 0.03)",
    )
    p.add_argument(
        "--max-tracking-error",
        type=float,
        default=5.0,
        help="largest allowed |commanded - measured|, degrees (gripper: 0-100 units) (default 5)",
    )
    p.add_argument(
        "--limit-margin",
        type=float,
        default=1.0,
        help="closest a body joint may come to a limit, degrees (default 1)",
    )
    p.add_argument(
        "--strict",
        action="store_true",
        help="refuse 'limited' moves shorter than the joint limits allow (default: stretch them)",
    )
    p.set_defaults(func=cmd_check)


def cmd_check(args: argparse.Namespace) -> int:
    import json

    from .preflight import Thresholds, check_motion_file, format_report

    thresholds = Thresholds(  # a bad threshold is a SettingError: main() reports it
        max_effort=args.max_effort,
        max_saturation=args.max_saturation,
        max_tracking_error=args.max_tracking_error,
        limit_margin=args.limit_margin,
    )
    report = check_motion_file(
        args.motion, model=args.model, thresholds=thresholds, strict=args.strict
    )
    print(json.dumps(report.to_dict(), indent=2) if args.json else format_report(report))
    return 0 if report.passed else 1


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
    from .robot_helpers import check_fps
    from .validation import check_duration

    # Check the numbers before opening anything (port, robot, viewer).
    fps = check_fps(args.fps)
    duration = check_duration(args.duration) if args.duration is not None else None
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
                fps=fps,
                duration=duration,
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
