"""The commands that run no motion file: view, model-path, pose, check and teleop."""

from __future__ import annotations

import argparse
from typing import Any

from ..errors import SettingError
from ..validation import check_duration
from .output import say, signals_end_the_window
from .tools import output_hint


# ---------------------------------------------------------------------------- other commands
def cmd_view(args: argparse.Namespace) -> int:
    if args.web:  # the studio in a browser (cli/studio.py)
        from .studio import view_web

        return view_web(args)
    from ..sim.simulation import Simulation  # imported here: they import MuJoCo
    from ..viewer import view

    sim = Simulation(args.model, arm=args.arm)
    with signals_end_the_window():
        view(sim.model, sim.data)
    return 0


def cmd_model_path(args: argparse.Namespace) -> int:
    from ..model.load import model_dir  # imported here: it imports MuJoCo

    say(model_dir())
    return 0


def cmd_pose(args: argparse.Namespace) -> int:
    if args.web:  # the pose finder in a browser (cli/studio.py)
        from .studio import pose_web

        return pose_web(args)
    from ..viewer.posefinder import (  # imported here: they import MuJoCo
        INSTRUCTIONS,
        check_display,
        find_poses,
        pose_scene,
    )
    from .studio import format_pose

    check_display()  # without a display its error is all the user sees
    m, d = pose_scene(args.model)
    say(INSTRUCTIONS, flush=True)

    def show(change: Any) -> None:
        say(format_pose(change, with_time=True), flush=True)

    with signals_end_the_window():
        find_poses(m, d, show)  # MuJoCo's viewer until its window is closed
    return 0


def cmd_check(args: argparse.Namespace) -> int:
    import json

    from ..model.build import servo_model  # imported here: they import MuJoCo
    from ..motion.file import lab_motion_path
    from ..preflight.check import Thresholds, check_motion_file, format_report

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
            motion, model=args.model, thresholds=thresholds, strict=args.strict, arm=args.arm
        )
    # the report names the motion it judged (the file, or the lab motion) and the servo
    # model it ran: the efforts and tracking errors are that model's
    servos = servo_model(arm=args.arm)
    if args.json:
        named = {"motion": str(motion), "servo_model": servos}
        say(json.dumps({**named, **report.to_dict()}, indent=2))
    else:
        name = f"the lab motion ({motion})" if args.motion is None else str(motion)
        say(f"checked {name}\nservo model: {servos}\n{format_report(report)}")
    return 0 if report.passed else 1


def _check_variants(args: argparse.Namespace, motion: Any, thresholds: Any) -> int:
    import json

    from ..model.build import servo_model  # imported here: they import MuJoCo
    from ..preflight import robust as pv

    settings = {"model": args.model, "thresholds": thresholds, "strict": args.strict}
    settings["arm"] = args.arm
    seed = 0 if args.seed is None else args.seed
    if args.plot is not None:
        pv.check_plot_path(args.plot, force=args.force)  # before anything runs
    if args.ray is None:
        report = pv.check_variants(
            motion, count=args.variants, seed=seed, threads=args.threads, **settings
        )
    else:
        # Ray (an optional extra) only when --ray is given
        from ..preflight.distributed import run_on_ray

        job = pv.make_job(motion, count=args.variants, seed=seed, **settings)
        report = pv.summarize(job, run_on_ray(job, args.ray))
    if args.plot is not None:
        pv.plot_variants(report, args.plot, force=args.force)  # checked above; claimed now
    servos = servo_model(arm=args.arm)  # the variants perturb this servo model
    if args.json:
        say(json.dumps({"servo_model": servos, **report.to_dict()}, indent=2))
    else:
        first, _, rest = pv.format_variants(report).partition("\n")
        say(f"{first}\nservo model: {servos} (perturbed per variant)\n{rest}")
    if args.plot is not None and not args.json:
        say(f"wrote {args.plot}")
    return 0 if report.passed == len(report.outcomes) else 1


def cmd_teleop(args: argparse.Namespace) -> int:
    from .. import robot  # imported here: they import MuJoCo
    from ..model.arm import load_profile
    from ..robot import teleop
    from ..robot.helpers import check_fps
    from ..viewer import choose_viewer

    # Check the numbers and the arm before opening anything (port, robot, viewer).
    load_profile(args.arm)
    fps = check_fps(args.fps)
    duration = check_duration(args.duration) if args.duration is not None else None
    calibration = teleop.find_calibration(args.calibration, args.id)
    say(calibration.note)
    viewer = choose_viewer(args.headless)
    if viewer.note:
        say(viewer.note)
    config = robot.SO101SimFollowerConfig(
        id="teleop", model=args.model, viewer=viewer.use, arm=args.arm
    )
    follower = robot.SO101SimFollower(config)
    bus = teleop.FeetechLeaderBus(args.port, calibration=calibration.motors)
    try:
        with follower:
            say(f"mirroring the leader on {args.port} at {args.fps:g} Hz; Ctrl-C to stop")
            stop = (lambda: not follower.viewer_open) if viewer.use else None
            result = teleop.teleoperate(
                follower, bus, calibration.motors, fps=fps, duration=duration, should_stop=stop
            )
    except KeyboardInterrupt:
        say("stopped")
        return 0
    finally:
        bus.close()
    say(
        f"{result.ticks} ticks in {result.duration:.2f} s "
        f"({result.late_ticks} slower than {args.fps:g} Hz)"
    )
    return 0
