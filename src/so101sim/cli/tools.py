"""More ``so101sim`` commands: ``record`` (a student's own script to a video), ``grade`` (an
instructor's check of hand-ins), ``workspace``, ``cache`` and ``examples``, and the camera
options every recording command shares (:func:`add_camera_options`, :func:`camera_options`).
Like :mod:`so101sim.cli`, they only parse and print: each calls one library function. Heavy
modules are imported inside the commands, to keep start-up fast.
"""

from __future__ import annotations

import argparse
import contextlib
import sys
from collections.abc import Iterator
from pathlib import Path
from typing import Any

from ..errors import MotionFileError, RecordingError, SettingError, So101SimError
from .output import _say, say
from .studio import add_web_options

SubParsers = Any  # argparse's private _SubParsersAction

# framing.NAMED_VIEWS (a test checks they agree), repeated: the parser imports no MuJoCo
VIEW_CHOICES = ("default", "front", "side", "top")
CAMERA_NUMBERS = ("azimuth", "elevation", "distance")


# the option that writes a file of this kind, for a motion file named like one
OUTPUT_OPTIONS = {
    **dict.fromkeys((".mp4", ".mkv", ".mov", ".avi", ".webm", ".gif"), ("--record", "a video")),
    **dict.fromkeys((".png", ".jpg", ".svg", ".pdf"), ("--plot", "a plot")),
    ".csv": ("--log", "a log"),
}


@contextlib.contextmanager
def output_hint(motion: str | None, command: str = "") -> Iterator[None]:
    """Add to a motion file that cannot be read, named like an output (``run lab.mp4``, the
    user forgot ``--record``), which option (of ``command``, if not this one) writes it; to a
    Python script given as one (``check my_lab.py``), which commands take a script."""
    try:
        yield
    except MotionFileError as exc:
        if Path(motion or "").suffix.lower() == ".py" and Path(motion or "").is_file():
            raise MotionFileError(
                exc.path,
                exc.line,
                f"{exc.reason}; a Python script is not a motion file (TOML: "
                "docs/motions.md): `so101sim record SCRIPT --log LOG.csv` runs your own script "
                "headless and `so101sim grade LOG.csv` judges the run against the lab's spec",
            ) from None
        option = OUTPUT_OPTIONS.get(Path(motion or "").suffix.lower())
        if option is None or exc.line != 0:
            raise
        flag, kind = option
        raise MotionFileError(
            exc.path, 0, f"{exc.reason}; to write {kind} use {command}{flag} {motion}"
        ) from None


# recording.QUALITY_CHOICES (a test checks they agree), repeated: the parser imports no MuJoCo
QUALITY_CHOICES = ("auto", "draft", "full")


def add_video_options(g: argparse._ArgumentGroup, *, camera: str, camera_help: str) -> None:
    """A recording command's video options: --width, --height, --fps, --camera, --quality."""
    g.add_argument("--width", type=int, default=640, help="video width in pixels (default 640)")
    g.add_argument("--height", type=int, default=480, help="video height in pixels (default 480)")
    g.add_argument("--fps", type=float, default=30.0, help="video frames per simulated second")
    g.add_argument("--camera", default=camera, help=camera_help)
    g.add_argument(
        "--quality",
        choices=QUALITY_CHOICES,
        default="auto",
        help="draft: fast on a CPU (simplified meshes, no shadows); full: the model's look; "
        "auto (default): draft when rendering on the CPU, full on a GPU",
    )


# ---------------------------------------------------------------------------- camera options
def add_camera_options(g: argparse._ArgumentGroup) -> None:
    """The free camera's options of a recording command: --view, --azimuth, --elevation,
    --distance, --lookat. Numbers are read as text and checked by :func:`camera_options`, so a
    bad one is a one-line error (and a negative one may be written ``--azimuth=-45``)."""
    g.add_argument(
        "--view",
        choices=VIEW_CHOICES,
        default="default",
        help="direction of the free camera, fitted to the arm's motion (default: default)",
    )
    g.add_argument("--azimuth", metavar="DEG", help="camera direction around the vertical, degrees")
    g.add_argument(
        "--elevation", metavar="DEG", help="camera elevation, degrees (-90 looks straight down)"
    )
    g.add_argument("--distance", metavar="M", help="camera distance from --lookat, metres")
    g.add_argument(
        "--lookat", metavar="X,Y,Z", help="point the camera looks at, metres (e.g. 0.2,0,0.1)"
    )


def _number(text: str, option: str, expected: str) -> float:
    try:
        return float(text)
    except ValueError:
        raise RecordingError(f"--{option} {text!r} is not a number; expected {expected}") from None


def camera_options(args: argparse.Namespace) -> dict[str, Any]:
    """The camera fields of :class:`~so101sim.recording.VideoSettings` from the options of
    :func:`add_camera_options` (their ranges are checked by ``VideoSettings.validated``).

    Raises:
        RecordingError: a number that is not one, or --lookat that is not three numbers.
    """
    units = {"azimuth": "degrees", "elevation": "degrees from -90 to 90", "distance": "metres"}
    options: dict[str, Any] = {"view": args.view}
    for name in CAMERA_NUMBERS:
        if (text := getattr(args, name)) is not None:
            options[name] = _number(text, name, f"a number of {units[name]}")
    if args.lookat is not None:
        parts = args.lookat.split(",")
        expected = "three numbers X,Y,Z in metres, e.g. --lookat 0.2,0,0.1"
        if len(parts) != 3:
            raise RecordingError(f"--lookat {args.lookat!r} is invalid; expected {expected}")
        options["lookat"] = tuple(_number(p.strip(), "lookat", expected) for p in parts)
    return options


RECORD_ARM_HELP = (
    "the servo model for the script's own model. Default: the script's models as it makes "
    "them (a scene.xml it compiles itself, as the lab handout does, has the file's ideal "
    "actuators: official; so101sim's load_model/Simulation: sts3215). --arm sts3215, "
    "official, sts3215-12v or a TOML file runs the script's model with that profile "
    "(said once on stderr)"
)


def add_commands(
    sub: SubParsers,
    *,
    recording: argparse.ArgumentParser,
    model: argparse.ArgumentParser,
    arm: argparse.ArgumentParser,
) -> None:
    """Add ``record``, ``workspace``, ``cache`` and ``examples`` to the parser's subcommands."""
    p = sub.add_parser(
        "record",
        parents=[recording],  # not `arm`: record's --arm says what it means for a script
        help="run your own simulation script headless and record it to a video",
        description=(
            "Runs SCRIPT unchanged: its mujoco.viewer.launch_passive(m, d) records instead of "
            "opening a window, and its clock (time.time, time.sleep, ...) follows simulated "
            "time, so a wall-clock '2 s' move is 2 s of simulated time. The video is drawn "
            "when the script ends, the camera fitted to the whole motion. With --web the "
            "script runs on the wall clock instead, shown live in a web browser (and recorded "
            "with -o). Arguments after '--' go to the script."
        ),
    )
    p.add_argument("script", help="the Python script to run (as you run it with python)")
    p.add_argument("-o", "--output", help="the video to write (.mp4); --record PATH says the same")
    p.add_argument("--title", help="a title in the caption and the video's metadata")
    p.add_argument("--arm", metavar="NAME|FILE", default=None, help=RECORD_ARM_HELP)
    p.add_argument("script_args", nargs="*", help="arguments for the script, after --")
    add_web_options(p)
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
    from ..lab.handin import (
        run_script,
        script_line,
        script_traceback,
        written_before,
    )  # imported here: it imports MuJoCo
    from ..recording import VideoSettings

    args.output = record_output(args)
    script_args = list(args.script_args)
    video = {name: getattr(args, name) for name in ("width", "height", "fps", "camera")}
    video |= {"quality": args.quality, "caption": args.caption, "title": args.title}
    video |= camera_options(args)
    VideoSettings(**video).validated()  # a bad setting stops before the script runs
    options = {**video, "plot": args.plot, "log": args.log, "force": args.force}
    options["arm"] = args.arm
    options["say"] = lambda text: _say(f"so101sim record: {text}", err=True)
    if args.web:  # the script live in a browser (cli/studio.py)
        from .studio import record_web

        return record_web(args, options)
    try:
        run = run_script(args.script, script_args, args.output, **options)
    except Exception as exc:
        where = script_line(exc, args.script)  # the script's file:line, if it came from there
        if isinstance(exc, So101SimError) and not where:
            raise
        if isinstance(exc, So101SimError):
            _say(f"so101sim: error: {where}: {exc}", err=True)
        else:  # the script's own error, as `python SCRIPT` shows it (not so101sim's frames)
            say(script_traceback(exc, args.script), end="", file=sys.stderr)
            say(f"so101sim: {where or args.script} raised {type(exc).__name__}", file=sys.stderr)
        for kind, path in written_before(exc).items():  # finished: what ran before the error
            _say(f"so101sim: the {kind} holds what ran before the error: {path}", err=True)
        return 2 if isinstance(exc, So101SimError) else 1
    if run.message:
        say(run.message, file=sys.stderr)
    for kind, path in run.outputs.items():
        say(f"wrote the {kind} to {path}")
    say(f"{args.script}: {run.simulated_seconds:.3f} s of simulated time")
    say(f"servo model: {run.servo_model}")
    return run.exit_status


def record_output(args: argparse.Namespace) -> str | None:
    """``record``'s video: ``-o PATH`` or ``--record PATH`` (the same option under the name
    ``run`` and ``hold`` use); None (no video) when only a log or a plot is asked for
    (``--log``, ``--plot``) or ``--web`` shows the script."""
    # start-up: validation (NumPy) only when record runs
    from ..validation import check_path_text

    for name in ("output", "record"):  # an empty name is no path (not "no video")
        if getattr(args, name) is not None:
            check_path_text(getattr(args, name), "video", error=RecordingError)
    if args.output and args.record and Path(args.output) != Path(args.record):
        raise RecordingError(
            f"-o {args.output} and --record {args.record} name two videos; expected one "
            "(they are the same option of record)"
        )
    output = args.output or args.record
    if output is None and not (args.web or args.log or args.plot):
        raise RecordingError(
            "record needs something to write; expected -o VIDEO.mp4, --log LOG.csv or --plot "
            "PLOT.png (or --web to show the script in a browser)"
        )
    return output


def cmd_workspace(args: argparse.Namespace) -> int:
    from ..kinematics import plot_workspace, sample_workspace  # imported here: MuJoCo
    from ..model.load import load_model

    model = load_model(args.model)
    path = plot_workspace(
        args.plot, pitch=args.pitch, samples=args.samples, force=args.force, model=model
    )
    reach = sample_workspace(samples=args.samples, model=model).reach_m
    say(f"wrote the workspace to {path}; the tip reaches {reach:.3f} m from the base")
    return 0


def cmd_cache(args: argparse.Namespace) -> int:
    # this command's modules, loaded when it runs (every other command starts without them)
    from ..model import cache as modelcache

    if args.action == "clear":
        gone = modelcache.clear()
        say(f"deleted {gone.entries} compiled model(s), {gone.size / 1e6:.1f} MB, in {gone.folder}")
        return 0
    info = modelcache.info()
    state = "on" if modelcache.enabled() else "off (SO101SIM_NO_CACHE)"
    say(f"{info.folder}: {info.entries} compiled model(s), {info.size / 1e6:.1f} MB; cache {state}")
    return 0


def cmd_examples(args: argparse.Namespace) -> int:
    # this command's modules, loaded when it runs (every other command starts without them)
    from ..lab.starter import copy_examples

    copied = copy_examples(args.folder, force=args.force)
    for path in copied:
        say(path)
    say(f"copied {len(copied)} file(s) to {args.folder}")
    return 0


def cmd_grade(args: argparse.Namespace) -> int:
    """``so101sim grade LOG|FOLDER``: the lab hand-in(s) judged against the lab's spec."""
    # before the log reader's module imports MuJoCo: nothing is drawn, no OpenGL is set up
    from ..gl import skip_opengl

    skip_opengl()  # nothing is drawn (the log reader's module imports MuJoCo)
    import json

    from ..lab.grade import Tolerances, grade_log
    from ..lab.gradefolder import grade_folder
    from ..lab.gradereport import (
        check_summary_path,
        folder_dict,
        format_folder,
        format_grade,
        grade_dict,
        write_summary,
    )
    from ..validation import checked_path

    tolerances = Tolerances(args.tolerance_deg, args.time_tolerance_s)
    handin = checked_path(args.handin, "hand-in")  # empty, too long: one line before anything
    if args.video is not None:
        checked_path(args.video, "video")
    if not handin.is_dir():
        if args.summary is not None:
            raise SettingError(
                "--summary writes one row per student of a folder of hand-ins; expected a "
                f"folder, not {args.handin!r} (or no --summary)"
            )
        try:
            result = grade_log(args.handin, video=args.video, tolerances=tolerances)
        except So101SimError as exc:  # not a log (or unreadable): an autograder still gets JSON
            if args.json:
                say(json.dumps({"log": str(args.handin), "passed": None, "error": str(exc)}))
            raise
        say(json.dumps(grade_dict(result), indent=2) if args.json else format_grade(result))
        return 0 if result.passed else 1
    if args.video is not None:
        raise SettingError(
            "--video goes with one log; in a folder each log's video is found beside it "
            "(the same name, .mp4)"
        )
    if args.summary is not None:
        check_summary_path(args.summary, force=args.force)  # before anything is graded
    folder = grade_folder(args.handin, tolerances=tolerances)
    say(json.dumps(folder_dict(folder), indent=2) if args.json else format_folder(folder))
    if args.summary is not None:
        written = write_summary(folder, args.summary, force=args.force)
        if not args.json:  # the JSON alone on stdout
            say(f"wrote the summary to {written}")
    return 0 if folder.passed else 1
