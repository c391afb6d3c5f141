"""A motion planned once: every segment's targets, computed and checked before anything moves.

:func:`plan_segments` plans a sequence of :data:`~so101sim.motion.segments.Segment` s from a
commanded pose, the way a run commands them (each segment from where the one before it leaves
the targets): joint moves by their shape, tip moves by inverse kinematics (a straight line
solved at every step), holds as the target held. Every target, shape and duration is checked
on the way, so a plan that exists can run. :func:`run_plan` then steps the plan on a
:class:`~so101sim.sim.simulation.Simulation`, and :meth:`PlannedMotion.path` gives what it
commands step by step (the video's framing): a run plans each motion once, and whatever looks
at the motion before it runs (the framing, the checks) uses the same plan.
"""

from __future__ import annotations

import logging
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import mujoco
import numpy as np

from ..errors import DurationError, SettingError
from ..exitgate import mujoco_call
from ..model.load import arm_units
from ..sim.limited import LimitedProfile, ShortMove, short_move, too_short
from ..sim.moveplan import plan_joint_move, plan_tip_move
from ..sim.profiles import MAX_MOVE_DURATION_S, SHAPES, get_profile, plan, steps_for
from ..sim.simulation import TRACE_AUTO_STEPS, Observer, Simulation
from ..units import Pose
from ..validation import MAX_DURATION_S
from .moves import Hold, Move, RunResult, Segment

log = logging.getLogger(__name__)

_KEEP_ROWS = TRACE_AUTO_STEPS
"""A joint move longer than this many steps keeps its recipe (start, goal, steps, shape),
not its rows: they are computed again when needed (planning a joint move is arithmetic), so a
motion of long moves does not hold all their targets at once."""


@dataclass(frozen=True)
class PlannedSegment:
    """One segment planned: the commanded target before it and its per-step targets (arm
    units, one row per physics step; a hold's rows are a read-only view of one row)."""

    segment: Segment
    start: np.ndarray  # (6,)
    rows: np.ndarray | None  # (n, 6); None: a long joint move (see ``_KEEP_ROWS``)
    steps: int
    recipe: tuple | None = None  # (goal, shape profile, timestep) of a long joint move

    @property
    def kind(self) -> str:
        return "hold" if isinstance(self.segment, Hold) else "move"

    @property
    def phase(self) -> str:
        return self.segment.phase

    @property
    def targets(self) -> np.ndarray:
        """The per-step targets, ``(steps, 6)`` arm units."""
        if self.rows is not None:
            return self.rows
        goal, profile, dt = self.recipe  # type: ignore[misc]
        return plan(self.start, goal, self.steps, dt, profile)  # a long joint move's rows

    @property
    def end(self) -> np.ndarray:
        """The target the segment leaves commanded."""
        if self.recipe is not None:
            return self.recipe[0]
        return self.rows[-1] if self.steps else self.start  # type: ignore[index]


@dataclass(frozen=True)
class PlannedMotion:
    """A motion planned once on ``model`` from the commanded pose ``start`` (arm units)."""

    model: mujoco.MjModel
    start: np.ndarray
    segments: tuple[PlannedSegment, ...]
    # the ``limited`` moves too short for the joint limits (stretched), from their planned start
    stretched: tuple[ShortMove, ...] = ()

    @property
    def steps(self) -> tuple[Segment, ...]:
        return tuple(p.segment for p in self.segments)

    @property
    def duration(self) -> float:
        """Simulated seconds the motion lasts."""
        return sum(p.steps for p in self.segments) * float(self.model.opt.timestep)

    def path(self) -> tuple[np.ndarray, np.ndarray]:
        """What the motion commands, step by step: ``(times, targets)``, ``targets`` (n, 6)
        arm units (the target applied during the step that ends at ``times[i]``)."""
        rows = [np.asarray(p.targets) for p in self.segments]
        path = np.vstack(rows) if rows else np.zeros((0, 6))
        return self.model.opt.timestep * np.arange(1, len(path) + 1), path


def plan_segments(
    model: mujoco.MjModel,
    segments: Sequence[Segment],
    start: Pose | np.ndarray,
    *,
    clip: bool = False,
    known: Mapping[int, tuple[np.ndarray, np.ndarray]] | None = None,
    strict: bool = False,
) -> PlannedMotion:
    """Plan ``segments`` from the commanded pose ``start`` (a pose, or an array in arm units),
    checking every target, shape and duration: THE motion planner and checker (a run, the
    preflight, the robust preflight and the framing all use it). ``known``: tip moves already
    planned (segment index -> ``(start, targets)``, as the motion-file loader planned them),
    used when they start where this plan has them start, so a tip line is solved once per run.

    Each ``limited`` move is checked against the joint limits from the start this plan gives
    it (after tip moves too): one too short is stretched (listed in
    :attr:`PlannedMotion.stretched`, with a logged warning) or, with ``strict``, refused.

    Raises:
        DurationError, JointNameError, JointValueError, JointLimitError, SettingError,
        UnreachableError: a segment that cannot run, before anything moves.
        TrajectoryLimitError: with ``strict``, a ``limited`` move too short for the limits
            (the first named, after the whole motion was checked).
    """
    units = arm_units(model)
    dt = float(model.opt.timestep)
    counts = [_steps(seg, dt) for seg in segments]  # each duration checked here, once
    total = sum(float(seg.duration) for seg in segments)
    if total > MAX_DURATION_S:
        raise DurationError(
            f"the motion lasts {total:g} s in all; expected at most {MAX_DURATION_S:g} s "
            "(one day of simulated time)"
        )
    sim = Simulation(model, initial_pose=None)  # a scratch one: planning only, never stepped
    first = start if isinstance(start, np.ndarray) else units.pose_to_array(start)
    sim.command_array(np.asarray(first, dtype=float), check=False)
    begin = sim.commanded_array()
    known = known or {}
    planned: list[PlannedSegment] = []
    stretched: list[ShortMove] = []
    for i, (seg, n) in enumerate(zip(segments, counts, strict=True)):
        current = sim.commanded_array()
        if isinstance(seg, Hold):
            rows = np.broadcast_to(current, (n, len(current)))
            planned.append(PlannedSegment(seg, current, rows, n))
            continue
        if not isinstance(seg, Move):
            raise SettingError(f"segment {i + 1} is {seg!r}; expected a Move or a Hold")
        if seg.tip is not None:
            done = known.get(i)
            if done is not None and np.array_equal(done[0], current):
                targets = done[1]
            else:
                with mujoco_call():  # as Simulation.plan_tip_move, which would check n again
                    _, targets = plan_tip_move(
                        sim, seg.tip, seg.duration, pitch=seg.pitch, roll=seg.roll,
                        path=seg.path, shape=seg.shape, steps=n,
                    )  # fmt: skip
            entry = PlannedSegment(seg, current, targets, len(targets))
            prof = get_profile(seg.shape, units)
            if seg.path == "joint" and isinstance(prof, LimitedProfile):  # to the IK's goal
                short = short_move(prof, i, seg.phase, current, targets[-1], n, dt)
                stretched += [short] if short is not None else []
        else:
            prof = get_profile(seg.shape, units)
            if isinstance(prof, LimitedProfile):
                goal = units.pose_to_array(seg.target, clip=clip)  # type: ignore[arg-type]
                short = short_move(prof, i, seg.phase, current, goal, n, dt)
                if short is not None:
                    stretched.append(short)
                    if strict:  # refused once the whole motion is checked: go on from its goal
                        sim.command_array(goal, check=False)
                        continue
            # n: the duration checked above, once (Simulation.plan_move would check it again)
            _, targets = plan_joint_move(sim, seg.target, seg.duration, seg.shape, clip, steps=n)
            if len(targets) > _KEEP_ROWS and isinstance(seg.shape, str) and seg.shape in SHAPES:
                recipe = (targets[-1].copy(), get_profile(seg.shape), dt)
                entry = PlannedSegment(seg, current, None, len(targets), recipe)
            else:
                entry = PlannedSegment(seg, current, targets, len(targets))
        sim.command_array(entry.end, check=False)
        planned.append(entry)
    if strict and stretched:
        raise too_short(stretched, dt)
    return PlannedMotion(model, begin, tuple(planned), tuple(stretched))


def _steps(seg: Segment, dt: float) -> int:
    """The physics steps of ``seg``: its duration checked (once, for the whole planner)."""
    maximum = MAX_MOVE_DURATION_S if isinstance(seg, Move) else MAX_DURATION_S
    return steps_for(seg.duration, dt, maximum=maximum, what=f"{seg.phase} duration")


def run_plan(
    sim: Simulation,
    plan: PlannedMotion,
    *,
    viewer: object = None,
    observers: Sequence[Observer] = (),
    trace: bool | None = None,
) -> RunResult:
    """Step ``plan`` on ``sim`` (which must hold the plan's model, commanded to the plan's
    start); stops early if an observer (a closed viewer) says so. ``trace``: keep each
    segment's per-step arrays (None: for segments up to two minutes).

    Raises:
        SettingError: the plan was made for another model or another start.
        SimulationDivergedError: the physics became unstable.
    """
    if sim.model is not plan.model:
        raise SettingError(
            "the plan was made for another model; expected plan_segments(sim.model, ...)"
        )
    if plan.segments and not np.allclose(sim.commanded_array(), plan.start, rtol=0, atol=1e-9):
        raise SettingError(
            "the plan starts from another commanded pose than the simulation's; expected "
            "plan_segments(sim.model, segments, sim.commanded_array())"
        )
    results = []
    for p in plan.segments:
        r = sim.run_targets(
            p.kind, p.phase, p.start, p.targets, viewer=viewer, observers=observers, trace=trace
        )
        results.append(r)
        if not r.completed:
            log.info("run stopped during %s at t = %.3f s", r.phase, r.end_time)
            break
    return RunResult(results)


__all__ = ["PlannedMotion", "PlannedSegment", "plan_segments", "run_plan"]
