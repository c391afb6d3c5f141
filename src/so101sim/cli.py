"""The ``so101sim`` command line. It parses arguments, calls the library and prints results.

so101sim run [MOTION]   a motion file, by default the lab motion (viewer on a desktop)
so101sim pose           pose the arm in the viewer; prints each pose as a dict and as TOML
so101sim check [MOTION] simulate a motion (default: the lab motion) headless; PASS or FAIL
so101sim hold           hold the starting pose (the lab's first script)
so101sim view           open the model in MuJoCo's interactive viewer
so101sim model-path     print the folder of the shipped model
so101sim teleop         mirror a LeRobot SO-101 leader arm on the sim in real time

Nothing here decides anything: the checks, viewer or headless, and running are in the library
(:mod:`so101sim.runplan` runs ``run`` and ``hold``). Each command imports what it needs when it
runs, not at the top, to start fast (``so101sim --help`` imports no MuJoCo) and so that
``--record`` can choose the OpenGL backend before MuJoCo is first imported.

Signals: while a command runs, SIGINT, SIGTERM and SIGHUP all raise :class:`Interrupted` (a
KeyboardInterrupt), so each one finishes the output files as Ctrl-C does; one that comes while
they are finished waits until they are (:class:`_Signals`). The exit status is then 128 + the
signal's number (130 for Ctrl-C). The library installs no signal handler.

Why over 400 lines: the signal handling belongs to the command line (the library never
installs handlers), and a module of its own would need a layer of its own in
``tests/test_architecture.py``; it is the block under "signals".
"""

from __future__ import annotations

import argparse
import atexit
import contextlib
import logging
import math
import os
import signal
import sys
import threading
import time
from collections.abc import Callable, Iterator, Sequence
from typing import TYPE_CHECKING, Any

from . import __version__
from .cli_tools import (
    add_camera_options,
    add_commands,
    add_video_options,
    camera_options,
    output_hint,
    split_script_args,
)
from .errors import SettingError, So101SimError
from .validation import check_duration

if TYPE_CHECKING:
    from tqdm import tqdm

    from .motion import RunResult, Segment
    from .recording import Recorder
    from .runplan import Outputs
    from .simulation import SegmentResult
    from .units import Pose

SubParsers = argparse._SubParsersAction  # the object add_subparsers() returns


# ---------------------------------------------------------------------------- printing
def format_segment(seg: SegmentResult) -> str:
    """A phase's report: target, reached pose, largest tracking error."""
    from .units import format_pose, format_value

    joint, err = seg.worst_tracking_error
    status = "" if seg.completed else "  (stopped early)"
    return (
        f"{seg.phase} [{seg.kind}, {seg.start_time:.3f}-{seg.end_time:.3f} s, "
        f"{seg.steps} steps]{status}\n"
        f"  target : {format_pose(seg.target)}\n"
        f"  reached: {format_pose(seg.reached)}\n"
        f"  largest tracking error: {format_value(joint, err, 3)} ({joint})"
    )


def print_run(result: RunResult) -> None:
    for seg in result.segments:
        print(format_segment(seg))
    if not result.completed:
        print(f"run ended early at t = {result.end_time:.3f} s (viewer closed)")


def _progress_bar(frames: int | None) -> tqdm | None:
    """A bar on stderr counting the video's frames (None without a video)."""
    if frames is None:
        return None
    from tqdm import tqdm

    return tqdm(
        total=frames,
        unit="frame",
        desc="recording",
        file=sys.stderr,
        delay=1.0,  # shown only for renders that take more than a second
        disable=None,  # and only on a terminal
        leave=False,
    )


# ---------------------------------------------------------------------------- signals
class Interrupted(KeyboardInterrupt):
    """SIGINT, SIGTERM or SIGHUP, raised as a Ctrl-C is, so that each one finishes the files."""

    def __init__(self, signum: int) -> None:
        super().__init__(signum)
        self.signum = signum


class _Signals:
    """While a command runs, SIGINT, SIGTERM and SIGHUP raise :class:`Interrupted`. A signal
    that comes while the output files are finished (:attr:`finishing`), or within a second of
    the last one raised (it is on its way there), waits in :attr:`waiting` instead: the files
    are finished first. A third that waits gives them up (SystemExit)."""

    NAMES = ("SIGINT", "SIGTERM", "SIGHUP")

    def __init__(self) -> None:
        self.finishing = False
        self.waiting: list[int] = []
        self.raised: int | None = None  # the signal last raised as Interrupted
        self._raised_at = -math.inf
        self._previous: dict[int, Any] = {}  # the handlers found by the command now running
        self._originals: dict[int, Any] = {}  # those found before any command (not ours)
        self._ended_at = -math.inf

    def __enter__(self) -> _Signals:
        self.finishing, self.waiting, self._raised_at = False, [], -math.inf
        self.raised = None
        if threading.current_thread() is threading.main_thread():
            for name in self.NAMES:
                if (signum := getattr(signal, name, None)) is not None:
                    previous = self._previous[signum] = signal.signal(signum, self._handle)
                    if previous != self._swallow:
                        self._originals[signum] = previous
        return self

    def __exit__(self, *exc: object) -> None:
        # Interrupted: the command ends with 128 + the signal. One more signal on the way out
        # (a second Ctrl-C within milliseconds, while Python shuts down) must not end the
        # process by the signal instead: from now on they are swallowed (the next command
        # restores the handlers it found first).
        interrupted = self.raised is not None or bool(self.waiting)
        self._ended_at = time.monotonic()
        for signum, previous in self._previous.items():
            signal.signal(signum, self._swallow if interrupted else previous)
        self._previous.clear()

    def _swallow(self, signum: int, frame: object) -> None:
        """After an interrupted command: a signal within a second is swallowed (the process
        is on its way out with 128 + the first); a later one (a program that goes on after
        main()) does what the handler found before the command does."""
        if time.monotonic() - self._ended_at < 1.0:
            self.waiting.append(signum)
            return
        original = self._originals.get(signum, signal.SIG_DFL)
        signal.signal(signum, original)
        if callable(original):
            original(signum, frame)
        elif original == signal.SIG_DFL:
            os.kill(os.getpid(), signum)

    def _handle(self, signum: int, frame: object) -> None:
        now = time.monotonic()
        if not self.finishing and now - self._raised_at > 1.0:
            self._raised_at = now
            self.raised = signum
            raise Interrupted(signum)
        self.waiting.append(signum)
        if len(self.waiting) >= 3:
            _notice("so101sim: output files left unfinished\n")
            raise SystemExit(128 + signum)
        more = "twice more" if len(self.waiting) == 1 else "once more"
        _notice(f"so101sim: finishing the output files first (signal {more} to drop them)\n")


def _notice(text: str) -> None:
    """Write to stderr from a signal handler (print() may be in the middle of a line)."""
    with contextlib.suppress(OSError):
        os.write(2, text.encode())


def _say(text: str, *, err: bool = False) -> None:
    """print(), except that a closed terminal (after SIGHUP) is not an error."""
    with contextlib.suppress(OSError):
        print(text, file=sys.stderr if err else sys.stdout, flush=True)


def _signal_name(signum: int) -> str:
    with contextlib.suppress(ValueError):
        return signal.Signals(signum).name
    return f"signal {signum}"


SIGNALS = _Signals()
"""The handlers :func:`main` installs while a command runs."""


@atexit.register
def _ignore_signals_at_exit() -> None:
    """After an interrupted command, a signal during the interpreter's shutdown (which puts
    back the default handlers) would end the process by the signal instead of 128 + the
    first: ignore them from here on (the process is ending)."""
    if SIGNALS.raised is None and not SIGNALS.waiting:
        return
    for signum in SIGNALS._originals:
        with contextlib.suppress(OSError, ValueError):
            signal.signal(signum, signal.SIG_IGN)


@contextlib.contextmanager
def _reporting(recorder: Recorder, bar: tqdm | None) -> Iterator[None]:
    """Finish the recorder's files on the way out (also on Ctrl-C, SIGTERM, SIGHUP or an
    error) and say what was written; signals that come meanwhile wait until it is done."""
    try:
        yield
    except BaseException as exc:
        SIGNALS.finishing = True  # first, and no call before it: a call may be interrupted
        _finish_outputs(recorder, bar, exc)
        raise
    SIGNALS.finishing = True
    _finish_outputs(recorder, bar, None)


def _say_written(recorder: Recorder, so_far: str) -> None:
    for key, path in recorder.outputs.items():
        extra = f" ({recorder.video.frames} frames)" if key == "video" and recorder.video else ""
        _say(f"wrote the {key} {so_far}to {path}{extra}")


def _finish_outputs(recorder: Recorder, bar: tqdm | None, pending: BaseException | None) -> None:
    """Close the recorder and print what it wrote; raise what failed (a full disk), unless
    ``pending`` (what stopped the run) is on its way out: then print it."""
    if bar is not None:
        with contextlib.suppress(OSError):  # a terminal that hung up
            bar.close()
    # errors are in recorder.errors; an interrupt is already on its way (SIGNALS.waiting)
    with contextlib.suppress(So101SimError, KeyboardInterrupt):
        recorder.close()
    _say_written(recorder, "so far " if pending is not None else "")
    errors = [e for e in recorder.errors.values() if e is not pending]
    first = errors.pop(0) if errors and pending is None else None
    for error in errors:
        _say(f"so101sim: error: {error}", err=True)
    if first is not None:
        raise first


# ---------------------------------------------------------------------------- parser
def _parent(*flags: str, **kwargs: Any) -> argparse.ArgumentParser:
    """A parent parser holding one option, for ``add_parser(..., parents=[...])``."""
    p = argparse.ArgumentParser(add_help=False)
    p.add_argument(*flags, **kwargs)
    return p


def _recording_parent() -> argparse.ArgumentParser:
    """The --record/--plot/--log options of ``run`` and ``hold``."""
    p = argparse.ArgumentParser(add_help=False)
    g = p.add_argument_group("recording (video, plot and log of the run, no screen recorder)")
    g.add_argument("--record", metavar="PATH", help="write an H.264 video of the run (.mp4)")
    g.add_argument("--plot", metavar="PATH", help="plot commanded vs measured angles (.png)")
    g.add_argument("--log", metavar="PATH", help="log every control step to a CSV file")
    add_video_options(
        g, camera="free", camera_help="'free' (the viewer's view) or a camera of the model"
    )
    g.add_argument(
        "--caption",
        action=argparse.BooleanOptionalAction,
        default=True,
        help="draw the time and phase into the video (default: on)",
    )
    add_camera_options(g)
    g.add_argument("--force", action="store_true", help="overwrite existing output files")
    return p


def _command(
    sub: SubParsers,
    name: str,
    func: Callable[[argparse.Namespace], int],
    summary: str,
    *parents: argparse.ArgumentParser,
) -> argparse.ArgumentParser:
    """Add the subcommand ``name``, run by ``func``, with the options of ``parents``."""
    p = sub.add_parser(name, help=summary, parents=list(parents))
    p.set_defaults(func=func)
    return p


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="so101sim", description="A MuJoCo digital twin of the SO-101 arm."
    )
    parser.add_argument("--version", action="version", version=f"so101sim {__version__}")
    parser.add_argument("-v", "--verbose", action="store_true", help="log debug messages")
    sub = parser.add_subparsers(dest="command", required=True)
    # Options several commands share, each declared once.
    model = _parent("--model", help="MJCF file to load instead of the shipped scene.xml")
    headless = _parent(
        "--headless", action="store_true", help="run without the viewer, even with a display"
    )
    speed = _parent(
        "--speed",
        type=float,
        default=1.0,
        help="viewer playback speed as a multiple of real time (default 1.0)",
    )
    strict = _parent(
        "--strict",
        action="store_true",
        help="refuse 'limited' moves shorter than the joint limits allow (default: stretch them)",
    )
    recording = _recording_parent()

    summary = "run a motion file (default: the lab motion)"
    p = _command(sub, "run", cmd_run, summary, model, headless, speed, strict, recording)
    p.add_argument(
        "motion",
        nargs="?",
        help="a TOML motion file (default: the shipped lab motion, rest -> zeros -> rest)",
    )
    summary = "hold the starting (rest) pose, as the lab's first script"
    p = _command(sub, "hold", cmd_hold, summary, model, headless, speed, recording)
    p.add_argument("--duration", type=float, default=30.0, help="seconds to hold (default 30)")
    _command(sub, "view", cmd_view, "open the model in MuJoCo's interactive viewer", model)
    _command(sub, "model-path", cmd_model_path, "print the folder holding the shipped model")
    summary = "pose the arm in the viewer; prints each pose as a Python dict and as TOML"
    _command(sub, "pose", cmd_pose, summary, model)
    summary = "simulate a motion file headless and judge it before hardware: PASS/FAIL"
    _add_check_options(_command(sub, "check", cmd_check, summary, model, strict))
    summary = "mirror a LeRobot SO-101 leader arm on the sim in real time (Ctrl-C stops)"
    _add_teleop_options(_command(sub, "teleop", cmd_teleop, summary, model, headless))
    add_commands(sub, recording=recording, model=model)
    from .cli_demo import add_demo_command  # so101sim demo (cli_demo.py)

    add_demo_command(sub)
    return parser


_THRESHOLD_OPTIONS = (  # check's thresholds: (flag, default, help)
    ("--max-effort", 0.9, "effort (fraction of the actuator's force limit) counted as saturated"),
    ("--max-saturation", 0.03, "seconds the effort may stay above --max-effort"),
    (
        "--max-tracking-error",
        5.0,
        "largest allowed |commanded - measured|, degrees (gripper: 0-100 units)",
    ),
    ("--limit-margin", 1.0, "closest a body joint may come to a limit, degrees"),
)


def _add_check_options(p: argparse.ArgumentParser) -> None:
    p.add_argument(
        "motion", nargs="?", help="the TOML motion file to check (default: the lab motion)"
    )
    p.add_argument("--json", action="store_true", help="print the report as JSON")
    for flag, default, text in _THRESHOLD_OPTIONS:
        p.add_argument(flag, type=float, default=default, help=f"{text} (default {default:g})")
    v = p.add_argument_group("robust preflight (perturbed arms; ranges: the file's [variants])")
    v.add_argument("--variants", type=int, metavar="N", help="run on N perturbed arms (1-100000)")
    v.add_argument("--seed", type=int, help="seed of the variants (default 0)")
    v.add_argument("--threads", type=int, help="threads (default: every core)")
    v.add_argument("--plot", metavar="PNG", help="histograms of the variants' figures")
    v.add_argument("--force", action="store_true", help="overwrite an existing --plot file")
    v.add_argument("--ray", metavar="ADDRESS", help="run on Ray: auto, local or an address")


def _add_teleop_options(p: argparse.ArgumentParser) -> None:
    p.add_argument("--port", required=True, help="leader arm's serial port, e.g. /dev/ttyACM0")
    p.add_argument(
        "--calibration",
        help="LeRobot calibration JSON of the leader (default: LeRobot's file for --id if any)",
    )
    p.add_argument("--id", help="leader id whose LeRobot calibration file to use")
    p.add_argument("--fps", type=float, default=60.0, help="ticks per second (default 60)")
    p.add_argument("--duration", type=float, help="stop after this many seconds (default: never)")


# ---------------------------------------------------------------------------- run and hold
def _prepare_rendering(args: argparse.Namespace) -> None:
    """With --record, choose MuJoCo's OpenGL backend (EGL or OSMesa without a display) before
    MuJoCo is first imported; with --headless and no --record nothing draws: no backend."""
    from .gl import prepare_for_rendering, skip_opengl

    if args.record:
        prepare_for_rendering()
    elif args.headless:
        skip_opengl()


def _outputs(args: argparse.Namespace) -> Outputs:
    from .recording import VideoSettings  # imported here: it imports MuJoCo
    from .runplan import Outputs

    fields = ("width", "height", "fps", "camera", "quality", "caption")
    settings = VideoSettings(
        **{name: getattr(args, name) for name in fields}, **camera_options(args)
    )
    return Outputs(args.record, args.plot, args.log, settings, force=args.force)


def _run(
    args: argparse.Namespace, segments: Sequence[Segment], start: Pose, strict: bool = False
) -> int:
    from .runplan import prepare_run  # imported here: it imports MuJoCo

    run = prepare_run(  # checks every setting before anything opens or moves
        segments,
        start=start,
        model=args.model,
        speed=args.speed,
        headless=args.headless,
        strict=strict,
        outputs=_outputs(args),
    )
    if run.viewer.note:
        print(run.viewer.note)
    bar = _progress_bar(run.video_frames)
    with _reporting(run.recorder, bar) if run.recorder else contextlib.nullcontext():
        result = run.execute(progress=bar.update if bar is not None else None)
    print_run(result)
    return 0


def cmd_run(args: argparse.Namespace) -> int:
    _prepare_rendering(args)
    from .motionfile import lab_motion_path, load_motion  # imported here: they import MuJoCo

    with output_hint(args.motion):
        motion = load_motion(args.motion if args.motion is not None else lab_motion_path())
    return _run(args, motion.steps, motion.start, strict=args.strict)


def cmd_hold(args: argparse.Namespace) -> int:
    duration = check_duration(args.duration, "hold duration")
    _prepare_rendering(args)
    from .motion import Hold  # imported here: it imports MuJoCo
    from .units import STARTING_POSE, format_pose

    print(f"holding the starting pose: {format_pose(STARTING_POSE)}")
    return _run(args, (Hold(duration, phase="hold"),), STARTING_POSE)


# ---------------------------------------------------------------------------- other commands
def cmd_view(args: argparse.Namespace) -> int:
    from .simulation import Simulation  # imported here: they import MuJoCo
    from .viewer import view

    sim = Simulation(args.model)
    view(sim.model, sim.data)
    return 0


def cmd_model_path(args: argparse.Namespace) -> int:
    from .model import model_dir  # imported here: it imports MuJoCo

    print(model_dir())
    return 0


def cmd_pose(args: argparse.Namespace) -> int:
    from .posefinder import (  # imported here: they import MuJoCo
        format_python,
        format_toml,
        open_pose_viewer,
        pose_scene,
        watch_poses,
    )

    m, d = pose_scene(args.model)
    # Open the viewer first: without a display its error is all the user sees.
    with open_pose_viewer(m, d) as handle:
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
                f"toml:   {format_toml(f'pose_{change.number}', change.pose)}"
                + (f"\ntip:    {change.tip.format()}" if change.tip is not None else ""),
                flush=True,
            )
    return 0


def cmd_check(args: argparse.Namespace) -> int:
    import json

    from .motionfile import lab_motion_path  # imported here: they import MuJoCo
    from .preflight import Thresholds, check_motion_file, format_report

    names = ("max_effort", "max_saturation", "max_tracking_error", "limit_margin")
    # a bad threshold is a SettingError: main() reports it
    thresholds = Thresholds(**{name: getattr(args, name) for name in names})
    motion = args.motion if args.motion is not None else lab_motion_path()
    if args.variants is not None:
        return _check_variants(args, motion, thresholds)
    if any(getattr(args, o) is not None for o in ("seed", "threads", "plot", "ray")) or args.force:
        raise SettingError(
            "--seed, --threads, --plot, --force and --ray go with --variants N; expected --variants"
        )
    with output_hint(args.motion, "so101sim run "):
        report = check_motion_file(
            motion, model=args.model, thresholds=thresholds, strict=args.strict
        )
    print(json.dumps(report.to_dict(), indent=2) if args.json else format_report(report))
    return 0 if report.passed else 1


def _check_variants(args: argparse.Namespace, motion: Any, thresholds: Any) -> int:
    import json

    from . import preflight_variants as pv  # imports MuJoCo

    settings = {"model": args.model, "thresholds": thresholds, "strict": args.strict}
    seed = 0 if args.seed is None else args.seed
    if args.plot is not None:
        pv.check_plot_path(args.plot, force=args.force)  # before anything runs
    if args.ray is None:
        report = pv.check_variants(
            motion, count=args.variants, seed=seed, threads=args.threads, **settings
        )
    else:
        from .distributed import run_on_ray

        job = pv.make_job(motion, count=args.variants, seed=seed, **settings)
        report = pv.summarize(job, run_on_ray(job, args.ray))
    if args.plot is not None:
        pv.plot_variants(report, args.plot, force=True)
    print(json.dumps(report.to_dict(), indent=2) if args.json else pv.format_variants(report))
    if args.plot is not None and not args.json:
        print(f"wrote {args.plot}")
    return 0 if report.passed == len(report.outcomes) else 1


def cmd_teleop(args: argparse.Namespace) -> int:
    from . import robot, teleop  # imported here: they import MuJoCo
    from .robot_helpers import check_fps
    from .viewer import choose_viewer

    # Check the numbers before opening anything (port, robot, viewer).
    fps = check_fps(args.fps)
    duration = check_duration(args.duration) if args.duration is not None else None
    calibration = teleop.find_calibration(args.calibration, args.id)
    print(calibration.note)
    viewer = choose_viewer(args.headless)
    if viewer.note:
        print(viewer.note)
    config = robot.SO101SimFollowerConfig(id="teleop", model=args.model, viewer=viewer.use)
    follower = robot.SO101SimFollower(config)
    bus = teleop.FeetechLeaderBus(args.port, calibration=calibration.motors)
    try:
        with follower:
            print(f"mirroring the leader on {args.port} at {args.fps:g} Hz; Ctrl-C to stop")
            stop = (lambda: not follower.viewer_open) if viewer.use else None
            result = teleop.teleoperate(
                follower, bus, calibration.motors, fps=fps, duration=duration, should_stop=stop
            )
    except KeyboardInterrupt:
        print("stopped")
        return 0
    finally:
        bus.close()
    print(
        f"{result.ticks} ticks in {result.duration:.2f} s "
        f"({result.late_ticks} slower than {args.fps:g} Hz)"
    )
    return 0


def main(argv: Sequence[str] | None = None) -> int:
    parser = build_parser()
    argv, script_args = split_script_args(list(sys.argv[1:] if argv is None else argv))
    args = parser.parse_args(argv)
    if script_args is not None:
        args.script_args = [*args.script_args, *script_args]
    logging.basicConfig(
        level=logging.DEBUG if args.verbose else logging.WARNING,
        format="%(levelname)s %(name)s: %(message)s",
    )
    with SIGNALS:
        try:
            code = int(args.func(args) or 0)
        except So101SimError as exc:
            _say(f"so101sim: error: {exc}", err=True)
            code = 2
        except KeyboardInterrupt as exc:
            signum = getattr(exc, "signum", signal.SIGINT)
            _say(f"so101sim: interrupted ({_signal_name(signum)})", err=True)
            return 128 + signum
        except Exception:
            # A signal's Interrupted raised inside a C call's argument conversion comes out as
            # that library's error (ctypes.ArgumentError "argument 1: Interrupted: 15" from
            # PyOpenGL's EGL calls); the files were finished as for any error: it was the signal.
            if SIGNALS.raised is None:
                raise
            _say(f"so101sim: interrupted ({_signal_name(SIGNALS.raised)})", err=True)
            return 128 + SIGNALS.raised
        if SIGNALS.waiting:  # came while the files were finished
            signum = SIGNALS.waiting[0]
            _say(f"so101sim: interrupted ({_signal_name(signum)})", err=True)
            return 128 + signum
        return code


if __name__ == "__main__":
    raise SystemExit(main())
