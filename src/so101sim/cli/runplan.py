"""Running a motion as ``so101sim run`` and ``so101sim hold`` do: check everything, then run.

:func:`prepare_run` checks every setting before anything opens or moves: the playback speed,
the model, each segment's target and duration, with ``strict`` the ``limited`` moves that are
too short for the joint limits (:func:`check_strict`), and the output paths and video settings
(it makes the :class:`~so101sim.recording.Recorder`, which opens no file yet). It also decides
viewer or headless (:func:`so101sim.viewer.choose_viewer`). :meth:`PreparedRun.execute` then
opens the viewer if there is one and runs the motion with the recorder's observers.

Nothing here prints: the caller shows :attr:`PreparedRun.viewer`'s note, a progress bar fed
through ``execute(progress=...)``, and what :meth:`Recorder.close` wrote (the caller closes the
recorder, also after Ctrl-C). This module sits above motion and the outputs (recording, viewer)
and below the command line.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from contextlib import ExitStack
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

import mujoco
import numpy as np

from ..model.arm import ArmLike
from ..model.load import arm_units, load_model
from ..motion.plan import PlannedMotion, plan_segments, run_plan
from ..motion.segments import RunResult, Segment
from ..recording.framing import sweep_frames
from ..recording.settings import VideoSettings
from ..sim.simulation import Observer, Pacer, Simulation, ViewerObserver
from ..units import STARTING_POSE, Pose
from ..viewer import ViewerChoice, choose_viewer, open_viewer

if TYPE_CHECKING:
    from ..recording import Recorder


@dataclass(frozen=True)
class Outputs:
    """What to write while a motion runs: a video, a plot and a CSV log (None: not written)."""

    video: str | Path | None = None
    plot: str | Path | None = None
    log: str | Path | None = None
    settings: VideoSettings = field(default_factory=VideoSettings)
    force: bool = False  # overwrite existing files

    @property
    def wanted(self) -> bool:
        """True when at least one file is asked for."""
        # an empty path is asked for too (and refused by the output check), not "no file"
        return any(p is not None for p in (self.video, self.plot, self.log))


def check_strict(
    model: mujoco.MjModel, segments: Sequence[Segment], start: Pose = STARTING_POSE
) -> None:
    """Refuse, before anything runs, a ``limited`` move shorter than the joint limits allow
    (instead of stretching it): raises :class:`~so101sim.errors.TrajectoryLimitError` naming
    the first such move of ``segments`` run from ``start`` (the motion planner's own check,
    :func:`~so101sim.motion.plan.plan_segments` with ``strict``)."""
    plan_segments(model, segments, arm_units(model).pose_to_array(start), strict=True)


@dataclass
class PreparedRun:
    """A motion checked and ready to run; :meth:`execute` runs it."""

    sim: Simulation
    plan: PlannedMotion  # planned and checked once: the framing and the run use it
    pacer: Pacer
    viewer: ViewerChoice
    recorder: Recorder | None = None

    @property
    def segments(self) -> tuple[Segment, ...]:
        return self.plan.steps

    @property
    def duration(self) -> float:
        """Simulated seconds the motion lasts."""
        return sum(s.duration for s in self.segments)

    @property
    def video_frames(self) -> int | None:
        """Frames the video will hold (None without a video)."""
        if self.recorder is None or self.recorder.video is None:
            return None
        from ..recording import video_frames  # imported here: only a run that records needs it

        return video_frames(self.duration, self.recorder.settings.fps)

    def execute(
        self, progress: Callable[[int], Any] | None = None, observers: Sequence[Observer] = ()
    ) -> RunResult:
        """Run the motion, in the viewer if one was chosen (paced to the wall clock), writing
        to the recorder's outputs; ``progress`` is called with 1 per video frame; ``observers``
        also watch (the web studio). The recorder is left open: close it
        (``recorder.close()``) afterwards, also on an error."""
        if progress is not None and self.recorder is not None and self.recorder.video is not None:
            self.recorder.video.progress = progress
        with ExitStack() as stack:
            watching: list[Observer] = list(self.recorder.observers) if self.recorder else []
            watching.extend(observers)
            if self.viewer.use:
                handle = stack.enter_context(
                    open_viewer(self.sim.model, self.sim.data, mirror=True, quality="auto")
                )
                watching.append(ViewerObserver(handle, self.pacer, warn_lag=False))  # run says it
            return run_plan(self.sim, self.plan, observers=watching)


def run_model(
    model: str | Path | mujoco.MjModel | None = None,
    *,
    headless: bool = False,
    outputs: Outputs | None = None,
    arm: ArmLike = None,
) -> mujoco.MjModel:
    """The model a run uses: ``model`` loaded (the shipped one by default) with the arm profile
    ``arm`` (None: the default, see :func:`~so101sim.model.load_model`), the physics-only
    copy when nothing will draw it (no viewer, no video: the same physics, a fifth of the
    memory). Load it first and pass it to :func:`~so101sim.motion.file.load_motion` and
    :func:`prepare_run`, so the tip moves the loader plans are the run's own."""
    if isinstance(model, mujoco.MjModel):
        return model
    draws = choose_viewer(headless).use or (outputs is not None and outputs.video is not None)
    return load_model(model, physics_only=not draws, arm=arm)


def prepare_run(
    segments: Sequence[Segment],
    *,
    start: Pose = STARTING_POSE,
    model: str | Path | mujoco.MjModel | None = None,
    speed: float = 1.0,
    headless: bool = False,
    strict: bool = False,
    outputs: Outputs | None = None,
    known: Mapping[int, tuple[np.ndarray, np.ndarray]] | None = None,
    arm: ArmLike = None,
) -> PreparedRun:
    """Check a run of ``segments`` from ``start`` and make its recorder, opening nothing. The
    motion is planned here, once (:func:`~so101sim.motion.plan.plan_segments`): the video's
    framing and the run use that plan. ``known``: tip moves the motion-file loader planned on
    the same model (``MotionFile.tip_plans``), not solved again.

    Raises:
        So101SimError: a bad speed, model, segment, output path or video setting, or (with
            ``strict``) a ``limited`` move too short for the joint limits.
    """
    viewer = choose_viewer(headless)
    loaded = run_model(model, headless=headless, outputs=outputs, arm=arm)
    pacer = Pacer(speed)  # checks the speed before anything opens
    sim = Simulation(loaded, initial_pose=start)
    # every target and duration, before anything runs (tip moves planned in full), once; with
    # ``strict``, a limited move too short for the joint limits refused
    plan = plan_segments(sim.model, segments, sim.commanded_array(), known=known, strict=strict)
    recorder = None
    if outputs is not None and outputs.wanted:
        from ..recording import Recorder  # imported here: only a run that writes files needs it

        sweep = None
        if outputs.video is not None:  # the camera frames what the motion will sweep
            sweep = sweep_frames(sim.model, plan.path()[1])
        recorder = Recorder(  # checks every path and setting
            sim,
            video=outputs.video,
            plot=outputs.plot,
            log=outputs.log,
            settings=outputs.settings.validated(),
            force=outputs.force,
            sweep=sweep,
        )
    return PreparedRun(sim, plan, pacer, viewer, recorder)


__all__ = ["Outputs", "PreparedRun", "check_strict", "prepare_run", "run_model"]
