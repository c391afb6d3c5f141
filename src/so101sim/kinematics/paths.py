"""Straight-line moves of the tip, planned before anything moves, and how far a run's tip
strayed from its line.

:func:`plan_line` solves IK at every point of a straight line from the tip's start position
to a target, each solve warm-started from the previous one so the arm moves continuously,
and raises :class:`~so101sim.errors.UnreachableError` before any step is taken if some point
of the line cannot be reached. It is pure planning (no stepping): a simulation then commands
its targets one per physics step. :func:`line_deviation` measures a sequence of poses (the
commanded targets, or the joint angles a run reached) against the line.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import mujoco
import numpy as np

from ..errors import SettingError, UnreachableError
from ..exitgate import mujoco_call
from ..units import GRIPPER_INDEX, JOINT_NAMES, Pose
from ..validation import check_count
from .core import N_BODY, Frame, Kinematics, for_model
from .goal import DEFAULT_ITERATIONS, DEFAULT_RESTARTS, Goal, Settings, make_goal, point
from .ik import Attempt, Descent, shortfall, solve

MAX_LINE_STEPS = 2_000_000
"""The most targets one line may be planned into (over an hour at 2 ms a step: the longest
move, :data:`~so101sim.profiles.MAX_MOVE_DURATION_S`, at the shipped model's timestep)."""
EXACT_ROWS = 1_000
"""Up to this many targets, every target is solved by IK on its own (2 s at 2 ms a step).
A line of more targets is solved at knots along it (:data:`KNOTS_PER_SOLVE_STEP` per
stretch of :data:`MAX_SOLVE_STEP_M` or :data:`MAX_SOLVE_STEP_RAD`, at least
:data:`MIN_KNOTS`), and its targets are the joints interpolated between the knots (well under
a micrometre off the line between two knots half a millimetre apart): the planning costs what
the line's length and turn ask for, not what its duration does (a 3600 s line is 1.8 million
targets)."""
MIN_KNOTS = 256
KNOTS_PER_SOLVE_STEP = 4
MAX_LINE_SOLVES = 200_000
"""The most IK solves one line is planned with (a bound on planning work: about ten
seconds); a line asking for more is refused at once, saying so."""
MAX_SOLVE_STEP_M = 0.002
"""The longest stretch of line between two IK solves: finer targets are solved as asked,
coarser ones get solves in between, so that each warm start is close to its answer."""
MAX_SOLVE_STEP_RAD = math.radians(2.0)
"""The largest turn of the asked orientation between two IK solves."""


@dataclass(frozen=True, eq=False)
class LinePlan:
    """A straight-line move of the tip, planned: one target pose per asked fraction."""

    targets: np.ndarray  # (n, 6) arm units, JOINT_NAMES order; every row within the limits
    fractions: np.ndarray  # (n,) how far along the line each row is, 0 (start) .. 1 (end)
    # (n, 3) where each row puts the tip, metres, base frame (for more than EXACT_ROWS rows:
    # exact at EXACT_ROWS rows spread evenly, interpolated between them)
    tips: np.ndarray
    start: np.ndarray  # (3,) the tip at the start pose
    end: np.ndarray  # (3,) the target
    deviation_mm: float  # the largest distance of ``tips`` from the line
    between_mm: float  # the same, halfway between consecutive rows (joints interpolated)

    def poses(self) -> list[dict[str, float]]:
        """The targets as pose dicts (arm units)."""
        return [
            {n: float(v) for n, v in zip(JOINT_NAMES, row, strict=True)} for row in self.targets
        ]


@dataclass(frozen=True, eq=False)
class LineDeviation:
    """How far a sequence of tip positions strays from a straight line (the segment)."""

    distances_mm: np.ndarray  # (n,) each row's distance from the segment
    max_mm: float
    index: int  # the row of the largest distance


def _fractions(steps: int | Sequence[float] | np.ndarray) -> np.ndarray:
    if isinstance(steps, int | np.integer) and not isinstance(steps, bool):
        n = check_count(steps, "steps", minimum=1, maximum=MAX_LINE_STEPS)
        return np.arange(1, n + 1) / n
    s = np.asarray(steps, dtype=float) if not isinstance(steps, str | bool) else np.array([])
    expected = (
        f"a number of steps (1..{MAX_LINE_STEPS}), or a list of fractions of the line "
        "between 0 and 1"
    )
    if s.ndim != 1 or not 1 <= len(s) <= MAX_LINE_STEPS or not np.isfinite(s).all():
        raise SettingError(f"steps of shape {s.shape} are invalid; expected {expected}")
    if s.min() < -1e-9 or s.max() > 1.0 + 1e-9:
        raise SettingError(
            f"steps reach {s.min():g}..{s.max():g} of the line; expected fractions in 0..1"
        )
    return np.clip(s, 0.0, 1.0)


class _Line:
    """The goal at each fraction of the line: the position moves evenly from the start's to
    the end's; an asked orientation turns evenly from the start's pitch (and roll) to the
    end's, the end being the IK answer for the whole goal. (The approach direction itself is
    not interpolated: between two directions this arm can point along, most are not.)"""

    def __init__(self, start: Frame, end_goal: Goal, end: Frame) -> None:
        self.p0, self.p1 = start.position, end_goal.position
        whole = end_goal.approach is not None or end_goal.rotation is not None
        turns_pitch = end_goal.pitch is not None or whole
        turns_roll = end_goal.roll is not None or whole
        self.pitch = (start.pitch, _wrap(end.pitch - start.pitch)) if turns_pitch else None
        self.roll = (start.roll, _wrap(end.roll - start.roll)) if turns_roll else None
        self.length = float(np.linalg.norm(self.p1 - self.p0))
        self.turn = max(abs(x[1]) for x in (self.pitch, self.roll, (0.0, 0.0)) if x is not None)

    def goal(self, s: float) -> Goal:
        return Goal(
            position=self.p0 + s * (self.p1 - self.p0),
            pitch=None if self.pitch is None else self.pitch[0] + s * self.pitch[1],
            roll=None if self.roll is None else self.roll[0] + s * self.roll[1],
        )

    def substeps(self, ds: float) -> int:
        """IK solves needed to advance by ``ds`` of the line in small enough stretches."""
        stretches = max(self.length / MAX_SOLVE_STEP_M, self.turn / MAX_SOLVE_STEP_RAD)
        return max(1, math.ceil(abs(ds) * stretches))


def _wrap(angle: float) -> float:
    return (angle + math.pi) % (2.0 * math.pi) - math.pi


def _segment_distances(points: np.ndarray, p0: np.ndarray, p1: np.ndarray) -> np.ndarray:
    d = p1 - p0
    length2 = float(d @ d)
    t = np.zeros(len(points)) if length2 == 0.0 else np.clip((points - p0) @ d / length2, 0, 1)
    return np.linalg.norm(points - (p0 + t[:, None] * d), axis=1)


def _blocked(
    kin: Kinematics, line: _Line, s: float, att: Attempt, settings: Settings
) -> UnreachableError:
    goal = line.goal(s)
    elsewhere, _, _ = solve(kin, goal, att.q, settings)
    why = (
        "the point is reachable, but only with the arm in another configuration, so the tip "
        "would leave the line to get there"
        if settings.accepts(elsewhere)
        else "the point is outside the workspace"
    )
    return UnreachableError(
        f"the straight line from {_xyz(line.p0)} to {_xyz(line.p1)} m cannot be "
        f"followed: {s:.0%} of the way, at {goal.describe()}, {shortfall(goal, att)} ({why}); "
        "expected every point of the line inside the workspace: move the end point, go round "
        "in two moves, or move with path='joint'"
    )


def _xyz(p: np.ndarray) -> str:
    return "(" + ", ".join(f"{float(v):.4f}" for v in p) + ")"


def plan_line(
    start: Pose | np.ndarray,
    target: Sequence[float] | np.ndarray,
    steps: int | Sequence[float] | np.ndarray = 100,
    *,
    pitch: float | None = None,
    approach: Sequence[float] | np.ndarray | None = None,
    roll: float | None = None,
    rotation: Sequence[Sequence[float]] | np.ndarray | None = None,
    tolerance_mm: float = 1.0,
    tolerance_deg: float = 1.0,
    model: mujoco.MjModel | None = None,
) -> LinePlan:
    """Plan a straight-line move of the tip from where ``start`` (a pose dict or six values
    in arm units) puts it to ``target`` (metres, base frame).

    ``steps``: the number of targets (row ``i`` at fraction ``(i + 1) / n``: the first has
    already moved, the last is the end, as :mod:`so101sim.sim.profiles` plans a move), or the
    fractions themselves (e.g. a minimum-jerk profile's, to start and stop smoothly).
    ``pitch``, ``approach``, ``roll`` or ``rotation`` (see
    :func:`~so101sim.kinematics.solve_ik`) are the orientation asked at the end; along the line
    it turns evenly from the start's. With none of them, only the position is steered. The
    gripper keeps the start's value.

    Raises:
        UnreachableError: the end, or some point of the line, cannot be reached within the
            tolerances; nothing has moved. The message says where and how far.
        SettingError: a target, angle, step count or fraction that is not valid.
        JointNameError, JointValueError, JointLimitError: ``start`` is not a valid pose.
    """
    kin = for_model(model)
    goal = make_goal(
        target, {"pitch": pitch, "approach": approach, "roll": roll, "rotation": rotation}
    )
    settings = Settings.checked(
        DEFAULT_RESTARTS, DEFAULT_ITERATIONS, tolerance_mm, tolerance_deg, 0
    )
    fractions = _fractions(steps)
    values = kin.pose_values(start)
    q = np.radians(values[:N_BODY])
    with mujoco_call(), kin.lock:  # refused once the interpreter exits (exitgate)
        end, _, _ = solve(kin, goal, q, settings)
        if not settings.accepts(end):
            raise UnreachableError(
                f"the end of the line {goal.describe()} is out of reach within the joint "
                f"limits: {shortfall(goal, end)}; expected an end point inside the arm's "
                "workspace (so101sim.kinematics.is_reachable tests one); nothing has moved"
            )
        line = _Line(kin.frame_at(q), goal, kin.frame_at(end.q))
        descent = Descent(kin, line.goal(1.0))  # every goal along the line has the same rows
        if len(fractions) <= EXACT_ROWS:
            rows = _solve_rows(kin, line, descent, settings, q, fractions)
        else:  # solved at knots, the joints interpolated between them
            knots = _knots(line)
            solved = _solve_rows(kin, line, descent, settings, q, knots)
            at = np.concatenate([[0.0], knots])
            qs = np.vstack([q[None, :], solved])
            rows = np.column_stack([np.interp(fractions, at, qs[:, j]) for j in range(N_BODY)])
        targets = np.repeat(values[None, :], len(fractions), axis=0)
        targets[:, :N_BODY] = np.degrees(rows)
        return _plan(kin, line, values, targets, fractions)


def _knots(line: _Line) -> np.ndarray:
    """The fractions of a long line solved by IK: evenly spaced, finer than the solve step.

    Raises:
        SettingError: the line asks for more than :data:`MAX_LINE_SOLVES` solves.
    """
    count = max(MIN_KNOTS, KNOTS_PER_SOLVE_STEP * line.substeps(1.0))
    if count > MAX_LINE_SOLVES:
        raise SettingError(
            f"the straight line ({line.length * 1000:.0f} mm, turning "
            f"{math.degrees(line.turn):.0f}°) needs {count} IK solves; expected a line that "
            f"needs at most {MAX_LINE_SOLVES} (the bound on planning work): split it into "
            "shorter lines, or use path='joint'"
        )
    return np.arange(1, count + 1) / count


def _solve_rows(
    kin: Kinematics,
    line: _Line,
    descent: Descent,
    settings: Settings,
    q: np.ndarray,
    fractions: np.ndarray,
) -> np.ndarray:
    """Joint angles (radians) at each fraction of the line, each solve warm-started from the
    previous one, with solves in between where two fractions are far apart.

    Raises:
        UnreachableError: a point of the line is out of reach.
        SettingError: the fractions ask for more than :data:`MAX_LINE_SOLVES` solves.
    """
    ds = np.abs(np.diff(np.concatenate([[0.0], fractions])))
    stretches = max(line.length / MAX_SOLVE_STEP_M, line.turn / MAX_SOLVE_STEP_RAD)
    solves = int(np.maximum(1, np.ceil(ds * stretches)).sum())
    if solves > MAX_LINE_SOLVES:
        raise SettingError(
            f"the straight line ({line.length * 1000:.0f} mm) asked at {len(fractions)} "
            f"fractions needs {solves} IK solves; expected at most {MAX_LINE_SOLVES} (the "
            "bound on planning work): ask for fewer fractions that go back and forth"
        )
    rows = np.empty((len(fractions), N_BODY))
    done = 0.0
    for i, s in enumerate(fractions):
        n = line.substeps(s - done)
        for k in range(1, n + 1):
            here = done + (s - done) * k / n
            descent.goal = line.goal(here)
            att = descent.run(q, DEFAULT_ITERATIONS)
            if not settings.accepts(att):
                raise _blocked(kin, line, here, att, settings)
            q = att.q
        rows[i], done = q, s
    return rows


def _plan(
    kin: Kinematics, line: _Line, start: np.ndarray, targets: np.ndarray, fractions: np.ndarray
) -> LinePlan:
    n = len(targets)
    # forward kinematics of every row up to EXACT_ROWS; beyond, of EXACT_ROWS rows spread
    # evenly (the rows between are joint interpolations: their tips are interpolated too)
    rows = np.arange(n) if n <= EXACT_ROWS else np.unique(np.linspace(0, n - 1, EXACT_ROWS))
    rows = rows.astype(int)
    exact = kin.tip_positions(targets[rows])
    tips = exact if n <= EXACT_ROWS else _interpolated(rows, exact, n)
    before = np.vstack([start[None, :], targets[rows[1:] - 1]]) if n > 1 else start[None, :]
    halfway = kin.tip_positions((before + targets[rows]) / 2.0)
    p0, p1 = line.p0.copy(), line.p1.copy()
    return LinePlan(
        targets=targets,
        fractions=fractions,
        tips=tips,
        start=p0,
        end=p1,
        deviation_mm=float(_segment_distances(tips, p0, p1).max()) * 1000.0,
        between_mm=float(_segment_distances(halfway, p0, p1).max()) * 1000.0,
    )


def _interpolated(rows: np.ndarray, values: np.ndarray, n: int) -> np.ndarray:
    """``values`` known at ``rows`` (sorted), linearly interpolated to every row ``0..n-1``."""
    at = np.arange(n)
    return np.column_stack([np.interp(at, rows, values[:, j]) for j in range(values.shape[1])])


def line_deviation(
    poses: np.ndarray | Sequence[Pose],
    start: Sequence[float] | np.ndarray,
    end: Sequence[float] | np.ndarray,
    model: mujoco.MjModel | None = None,
) -> LineDeviation:
    """How far the tip strays from the straight segment ``start``-``end`` (metres) over
    ``poses``: an ``(n, 6)`` array in arm units (a move's targets, or the joint angles a run
    reached) or a list of pose dicts. Limits are not checked (a measured pose may sit a hair
    past a stop)."""
    kin = for_model(model)
    if isinstance(poses, np.ndarray):
        values = np.atleast_2d(np.asarray(poses, dtype=float))
    else:
        values = np.array([kin.units.pose_to_array(p, check_limits=False) for p in poses])
    if values.ndim != 2 or values.shape[1] not in (N_BODY, GRIPPER_INDEX + 1) or not len(values):
        raise SettingError(
            f"poses of shape {values.shape}; expected an (n, 6) array in arm units or a list "
            "of pose dicts"
        )
    p0, p1 = point(start, "line start"), point(end, "line end")
    d = _segment_distances(kin.tip_positions(values), p0, p1) * 1000.0
    i = int(np.argmax(d))
    return LineDeviation(distances_mm=d, max_mm=float(d[i]), index=i)
