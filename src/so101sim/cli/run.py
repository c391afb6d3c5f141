"""``so101sim run`` and ``so101sim hold``: a motion run through :mod:`.runplan`."""

from __future__ import annotations

import argparse
import contextlib
from collections.abc import Sequence
from typing import TYPE_CHECKING

from ..validation import check_duration
from .output import _progress_bar, _reporting, print_run, say
from .tools import camera_options, output_hint

if TYPE_CHECKING:
    from collections.abc import Mapping

    import mujoco
    import numpy as np

    from ..motion.segments import Segment
    from ..units import Pose
    from .runplan import Outputs


# ---------------------------------------------------------------------------- run and hold
def _prepare_rendering(args: argparse.Namespace) -> None:
    """With --record, choose MuJoCo's OpenGL backend (EGL or OSMesa without a display) before
    MuJoCo is first imported; with --headless and no --record nothing draws: no backend."""
    # before anything imports MuJoCo: the OpenGL backend is chosen first
    from ..gl import prepare_for_rendering, skip_opengl

    if args.record:
        prepare_for_rendering()
    elif args.headless:
        skip_opengl()


def _outputs(args: argparse.Namespace) -> Outputs:
    from ..recording import VideoSettings  # imported here: it imports MuJoCo
    from .runplan import Outputs

    fields = ("width", "height", "fps", "camera", "quality", "caption")
    settings = VideoSettings(
        **{name: getattr(args, name) for name in fields}, **camera_options(args)
    )
    return Outputs(args.record, args.plot, args.log, settings, force=args.force)


def _run(
    args: argparse.Namespace,
    segments: Sequence[Segment],
    start: Pose,
    strict: bool = False,
    *,
    model: mujoco.MjModel | None = None,
    known: Mapping[int, tuple[np.ndarray, np.ndarray]] | None = None,
) -> int:
    from ..model.build import servo_model  # imported here: it imports MuJoCo
    from .runplan import prepare_run
    from .studio import web_run  # --web: the studio in a browser (cli/studio.py)

    with web_run(args) as web:  # None without --web
        run = prepare_run(  # checks every setting before anything opens or moves
            segments,
            start=start,
            model=web.model if web else (model if model is not None else args.model),
            arm=args.arm,
            speed=args.speed,
            headless=args.headless or web is not None,
            strict=strict,
            outputs=_outputs(args),
            known=known,
        )
        if run.viewer.note:
            say(run.viewer.note)
        say(f"servo model: {servo_model(run.sim.model)}")
        bar = _progress_bar(run.video_frames)
        with _reporting(run.recorder, bar) if run.recorder else contextlib.nullcontext():
            result = run.execute(
                progress=bar.update if bar is not None else None,
                observers=web.observers(run) if web else (),
            )
        print_run(result)
        shown_in = "the viewer" if run.viewer.use else "the browser page" if web else None
        if shown_in and run.pacer.lag_events:
            say(
                f"note: {shown_in} fell behind real time {run.pacer.lag_events} times over the "
                f"run ({run.pacer.lag_s:.1f} s in all): this machine could not step and draw it "
                "faster; the simulated time and every figure above are exact anyway (--speed 0.5 "
                "shows it slower and steadier)"
            )
    return 0


def cmd_run(args: argparse.Namespace) -> int:
    _prepare_rendering(args)
    from ..motion.file import lab_motion_path, load_motion  # imported here: they import MuJoCo
    from .runplan import run_model

    # the run's model first: the loader plans the tip moves on it, and the run reuses them
    model = run_model(args.model, headless=args.headless, outputs=_outputs(args), arm=args.arm)
    with output_hint(args.motion):
        motion = load_motion(
            args.motion if args.motion is not None else lab_motion_path(), model=model
        )
    return _run(
        args, motion.steps, motion.start, strict=args.strict, model=model, known=motion.tip_plans
    )


def cmd_hold(args: argparse.Namespace) -> int:
    duration = check_duration(args.duration, "hold duration")
    _prepare_rendering(args)
    from ..motion.segments import Hold  # imported here: it imports MuJoCo
    from ..units import STARTING_POSE, format_pose

    say(f"holding the starting pose: {format_pose(STARTING_POSE)}")
    return _run(args, (Hold(duration, phase="hold"),), STARTING_POSE)
