"""The ``so101sim`` command line. It parses arguments, calls the library and prints results.

so101sim run [MOTION]   a motion file, by default the lab motion (viewer on a desktop)
so101sim pose           pose the arm in the viewer; prints each pose as a dict and as TOML
so101sim check [MOTION] simulate a motion (default: the lab motion) headless; PASS or FAIL
so101sim grade HANDIN   judge a lab hand-in's CSV log (or a folder of them); PASS or FAIL
so101sim hold           hold the starting pose (the lab's first script)
so101sim view           open the model in MuJoCo's interactive viewer
so101sim model-path     print the folder of the shipped model
so101sim teleop         mirror a LeRobot SO-101 leader arm on the sim in real time
so101sim dataset TASK   a LeRobotDataset of a task's scripted expert (LeRobot plugin)
so101sim eval POLICY    a policy's success rate on a task, in parallel (LeRobot plugin)

Nothing here decides anything: the checks, viewer or headless, and running are in the library
(:mod:`so101sim.cli.runplan` runs ``run`` and ``hold``). Each command imports what it needs when
it runs, not at the top, to start fast (``so101sim --help`` imports no MuJoCo) and so that
``--record`` can choose the OpenGL backend before MuJoCo is first imported.

This module holds the parser and :func:`main`; the commands are in :mod:`.run` (run, hold),
:mod:`.commands` (view, model-path, pose, check, teleop), :mod:`.tools` (record, grade,
workspace, cache, examples) and :mod:`.demo`; what is printed, and the signal handling that
finishes the output files first, in :mod:`.output`.
"""

from __future__ import annotations

import argparse
import functools
import logging
import os
import select
import signal
import sys
from collections.abc import Callable, Sequence
from typing import Any

from .. import __version__
from ..errors import So101SimError
from .commands import cmd_check, cmd_model_path, cmd_pose, cmd_teleop, cmd_view
from .output import SIGNALS, EscapingFormatter, _say, _signal_name, add_arm_option
from .run import cmd_hold, cmd_run
from .studio import add_web_options
from .tools import (
    add_camera_options,
    add_commands,
    add_video_options,
    cmd_grade,
    split_script_args,
)

SubParsers = argparse._SubParsersAction  # the object add_subparsers() returns


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
    """Add the subcommand ``name``, run by ``func``, with the options of ``parents``; its
    ``summary`` heads its own ``--help`` too."""
    p = sub.add_parser(name, help=summary, description=f"{summary}.", parents=list(parents))
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
    arm = argparse.ArgumentParser(add_help=False)
    add_arm_option(arm)

    summary = "run a motion file (default: the lab motion)"
    p = _command(sub, "run", cmd_run, summary, model, arm, headless, speed, strict, recording)
    add_web_options(p)
    p.add_argument(
        "motion",
        nargs="?",
        help="a TOML motion file (default: the shipped lab motion, rest -> zeros -> rest)",
    )
    summary = "hold the starting (rest) pose, as the lab's first script"
    p = _command(sub, "hold", cmd_hold, summary, model, arm, headless, speed, recording)
    add_web_options(p)
    p.add_argument("--duration", type=float, default=30.0, help="seconds to hold (default 30)")
    add_web_options(
        _command(sub, "view", cmd_view, "open the model in MuJoCo's viewer (or --web)", model, arm),
        linger=False,
    )
    _command(sub, "model-path", cmd_model_path, "print the folder holding the shipped model")
    summary = (
        "pose the arm in the viewer (or --web); prints each pose as a Python dict and as TOML, "
        "with a warning when the tip or a part of the arm is below the floor or in the table"
    )
    add_web_options(_command(sub, "pose", cmd_pose, summary, model), linger=False)
    summary = "simulate a motion file headless and judge it before hardware: PASS/FAIL"
    _add_check_options(_command(sub, "check", cmd_check, summary, model, arm, strict))
    summary = "mirror a LeRobot SO-101 leader arm on the sim in real time (Ctrl-C stops)"
    _add_teleop_options(_command(sub, "teleop", cmd_teleop, summary, model, arm, headless))
    add_commands(sub, recording=recording, model=model, arm=arm)
    summary = "judge a lab hand-in's CSV log (or a folder of hand-ins) against the lab's spec"
    _add_grade_options(_command(sub, "grade", cmd_grade, summary))
    from .demo import add_demo_command  # so101sim demo

    add_demo_command(sub, arm=arm)
    from .fidelity import add_parsers as add_fidelity_commands  # so101sim compare, fit

    add_fidelity_commands(sub)
    from .learning import add_learning_commands  # so101sim dataset, eval (LeRobot plugins)

    add_learning_commands(sub)
    return parser


_THRESHOLD_OPTIONS = (  # check's thresholds: (flag, default, help)
    ("--max-effort", 0.9, "effort (fraction of the actuator's force limit) counted as saturated"),
    ("--max-saturation", 0.03, "seconds the effort may stay above --max-effort"),
    (
        "--max-tracking-error",
        15.0,
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


def _add_grade_options(p: argparse.ArgumentParser) -> None:
    p.description = (
        "Judges a lab hand-in against the lab's spec: from rest to all zeros in 2 s, hold 2 s, "
        "back to the start in 2 s. The phases are found from the log's commanded angles; each "
        "is judged on its duration, the pose reached and (the hold) how still the arm held. "
        "Exit status: 0 every hand-in passed, 1 one failed, 2 not a so101sim log (or a bad "
        "option)."
    )
    p.add_argument(
        "handin",
        metavar="LOG|FOLDER",
        help="a CSV log (so101sim run --log, so101sim record ... --log), or a folder of hand-ins: "
        "one CSV per student (named by the file) or one sub-folder per student (named by it)",
    )
    p.add_argument(
        "--video", metavar="FILE", help="the hand-in's video: readable, as long as the log"
    )
    p.add_argument("--summary", metavar="CSV", help="with a folder: one row per student, per phase")
    p.add_argument("--force", action="store_true", help="overwrite an existing --summary file")
    p.add_argument("--json", action="store_true", help="print the grades as JSON")
    p.add_argument(
        "--tolerance-deg",
        type=float,
        metavar="DEG",
        default=10.0,
        help="largest joint error of a reached pose, and most a joint may move in the hold, "
        "degrees (body joints, the gripper is not judged; default 10: the fitted STS3215 "
        "servos end the lab's moves up to 7.8° short)",
    )
    p.add_argument(
        "--time-tolerance-s",
        type=float,
        metavar="S",
        default=0.25,
        help="most a phase's duration may differ from the spec's 2 s (default 0.25)",
    )


def _add_teleop_options(p: argparse.ArgumentParser) -> None:
    p.add_argument("--port", required=True, help="leader arm's serial port, e.g. /dev/ttyACM0")
    p.add_argument(
        "--calibration",
        help="LeRobot calibration JSON of the leader (default: LeRobot's file for --id if any)",
    )
    p.add_argument("--id", help="leader id whose LeRobot calibration file to use")
    p.add_argument("--fps", type=float, default=60.0, help="ticks per second (default 60)")
    p.add_argument("--duration", type=float, help="stop after this many seconds (default: never)")


def _stdout_closed() -> bool:
    """Whether the standard output's reader has gone (a pipe closed, as by ``| head``); if so
    the output goes to the null device from now on, so Python's flush at exit stays quiet."""
    try:
        fd = sys.stdout.fileno()
        poll = select.poll()  # a pipe with no reader left polls as an error (Linux, macOS: hangup)
        poll.register(fd, select.POLLOUT)
        gone = any(ev & (select.POLLERR | select.POLLHUP) for _, ev in poll.poll(0))
    except (AttributeError, OSError, ValueError):  # no poll (Windows), or no real stdout
        return False
    if gone:
        null = os.open(os.devnull, os.O_WRONLY)
        os.dup2(null, fd)
        os.close(null)
    return gone


@functools.cache
def _parser() -> argparse.ArgumentParser:
    """:func:`build_parser`'s parser, built once per process: it takes about 8 ms (argparse
    looks up a translation for every help text), which a caller of :func:`main` in a loop
    (a test, a script) would otherwise pay on every call. Parsing does not change it."""
    return build_parser()


def main(argv: Sequence[str] | None = None) -> int:
    parser = _parser()
    argv, script_args = split_script_args(list(sys.argv[1:] if argv is None else argv))
    args = parser.parse_args(argv)
    if script_args is not None:
        args.script_args = [*args.script_args, *script_args]
    handler = logging.StreamHandler()  # stderr; control characters escaped as all output
    handler.setFormatter(EscapingFormatter("%(levelname)s %(name)s: %(message)s"))
    logging.basicConfig(
        level=logging.DEBUG if args.verbose else logging.WARNING, handlers=[handler]
    )
    with SIGNALS:
        try:
            code = int(args.func(args) or 0)
        except So101SimError as exc:
            _say(f"so101sim: error: {exc}", err=True)
            code = 2
        except BrokenPipeError:
            if not _stdout_closed():
                raise
            return 128 + signal.SIGPIPE  # `so101sim check | head`: the reader has what it wanted
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
