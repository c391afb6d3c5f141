"""Preflight, first part: run a motion headless and measure it, per step and per joint.

:func:`measure` runs the motion exactly as ``so101sim run`` does (same steps, bit for bit), in
whole blocks in C through the stepping kernel, and derives what an observer called after every
physics step would read from what the blocks recorded
(:class:`~so101sim.preflight.states.StateRecorder`: the same samples, bit for bit, as
:class:`StepRecorder`, which watches a model they cannot be derived for after every step).
It returns :class:`Measurements`: for every step
and joint the closest approach to a limit, the peak effort, the longest saturation and the peak
tracking error, and every contact. Nothing here judges: :mod:`so101sim.preflight.judge`
compares the figures with the thresholds.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import mujoco
import numpy as np

from ..kinematics import line_deviation, tip_pose
from ..model.load import arm_index, arm_units
from ..motion.plan import plan_segments, run_plan
from ..motion.segments import Move, Segment, SegmentResult
from ..sim.limited import ShortMove
from ..sim.simulation import Observer, Simulation
from ..units import JOINT_NAMES, Pose
from .states import StateRecorder, derivable

_EPS_T = 1e-9  # s: slack when comparing simulated times with a step's end


@dataclass(frozen=True)
class JointCheck:
    """One joint over one step."""

    limit_margin: float  # closest approach to a limit (arm units); < 0: past it
    limit_side: str  # "lower" | "upper": the limit it came closest to
    peak_effort: float  # max |force| / force limit
    # s: longest unbroken stretch with effort above max_effort that reaches into this step
    # (a stretch that began in an earlier step counts from when it began)
    saturated: float
    peak_tracking_error: float  # arm units
    saturation_time: float = 0.0  # s: when the longest saturation began
    peak_tracking_time: float = 0.0  # s: when the tracking error peaked


@dataclass(frozen=True)
class Contact:
    """Two bodies that touched during a step."""

    body1: str
    body2: str
    first_time: float  # s
    max_penetration: float  # m (>= 0)


@dataclass(frozen=True)
class StepCheck:
    """The figures of one step of the motion."""

    index: int  # 1-based
    phase: str
    kind: str  # "move" | "hold"
    line: int  # line in the motion file (0: not from a file)
    start_time: float
    end_time: float
    joints: dict[str, JointCheck]
    contacts: tuple[Contact, ...]
    # a straight-line tip move: the largest distance (mm) of the commanded and of the measured
    # tip from the line; None for other steps
    line_deviation_mm: tuple[float, float] | None = None


@dataclass(frozen=True)
class Measurements:
    """What :func:`measure` found: the figures of every step, the joint limits they were
    measured against, and the ``limited`` moves stretched because they were too short."""

    steps: tuple[StepCheck, ...]
    limits: dict[str, tuple[float, float]]  # joint -> (lower, upper), arm units
    stretched: tuple[ShortMove, ...]


class StepRecorder(Observer):
    """Called after every physics step: records actuator forces and contacts."""

    def __init__(self, m: mujoco.MjModel) -> None:
        self.act = arm_index(m).actuator
        self.dt = m.opt.timestep
        self.times: list[float] = []
        self.forces: list[np.ndarray] = []
        self.contacts: list[tuple[float, int, int, float]] = []
        self._next = -math.inf

    def next_time(self) -> float:
        return self._next

    def on_time(self, m: mujoco.MjModel, d: mujoco.MjData) -> bool:
        # After mj_step, actuator_force and contact hold what acted during that step.
        self.times.append(float(d.time))
        self.forces.append(d.actuator_force[self.act].copy())
        for k in range(d.ncon):
            c = d.contact[k]
            b1, b2 = int(m.geom_bodyid[c.geom[0]]), int(m.geom_bodyid[c.geom[1]])
            self.contacts.append((float(d.time), b1, b2, float(c.dist)))
        self._next = d.time + 0.5 * self.dt
        return True

    def effort(self, m: mujoco.MjModel) -> np.ndarray:
        """(samples, 6): ``|actuator force|`` over the force limit, after every step."""
        return np.abs(np.array(self.forces)) / np.abs(m.actuator_forcerange[self.act, 1])


def measure(
    steps: Sequence[Segment],
    *,
    start: Pose,
    model: mujoco.MjModel,
    saturation_level: float,
    lines: Sequence[int] = (),
    strict: bool = False,
    known: Mapping[int, tuple[np.ndarray, np.ndarray]] | None = None,
) -> Measurements:
    """Run ``steps`` headless from ``start`` (at rest) and measure every step.

    ``saturation_level`` is the effort (fraction of the force limit) above which a joint
    counts as saturated; ``lines`` only label the steps. With ``strict``, a ``limited`` move
    too short for the joint limits raises TrajectoryLimitError before anything moves.
    ``known``: tip moves already planned on ``model`` (``MotionFile.tip_plans``), not solved
    again.
    """
    sim = Simulation(model, initial_pose=start)
    plan = plan_segments(model, steps, sim.commanded_array(), strict=strict, known=known)
    # whole blocks stepped in C, the samples derived from what they recorded (bit for bit the
    # step recorder's); a model where they cannot be is watched after every step
    rec = StateRecorder(model) if derivable(model) else StepRecorder(model)
    result = run_plan(sim, plan, observers=[rec], trace=True)
    return collect(model, steps, result.segments, rec, saturation_level, lines, plan.stretched)


def collect(
    model: mujoco.MjModel,
    steps: Sequence[Segment],
    segments: Sequence[SegmentResult],
    rec: StepRecorder | StateRecorder,
    saturation_level: float,
    lines: Sequence[int] = (),
    stretched: Sequence[ShortMove] = (),
) -> Measurements:
    """The figures of ``segments`` (results of ``steps``, run with ``rec`` observing every
    step, or a :class:`~so101sim.preflight.states.StateRecorder` deriving the same samples
    from the recorded states; per-step traces kept)."""
    units = arm_units(model)
    # per joint, then per sample (rows of 6 contiguous samples: NumPy reduces along a
    # contiguous axis several times faster than down columns)
    effort = _by_joint(rec.effort(model))
    saturated = _run_lengths(effort > saturation_level) * model.opt.timestep
    ends = np.array([s.end_time for s in segments])
    times = np.asarray(rec.times, dtype=float)
    step_of_sample = np.searchsorted(ends + _EPS_T, times)
    lo, hi = units.limits
    checks = []
    for k, seg in enumerate(segments):
        in_step = step_of_sample == k
        joints = _joint_checks(
            seg, lo, hi, effort[:, in_step], saturated[:, in_step], times[in_step]
        )
        contacts = _contacts(model, rec.contacts, seg.start_time, seg.end_time, first=(k == 0))
        checks.append(
            StepCheck(
                index=k + 1,
                phase=seg.phase,
                kind=seg.kind,
                line=int(lines[k]) if k < len(lines) else 0,
                start_time=seg.start_time,
                end_time=seg.end_time,
                joints=joints,
                contacts=tuple(contacts),
                line_deviation_mm=_line_deviation(model, steps[k], seg) if k < len(steps) else None,
            )
        )
    return Measurements(tuple(checks), units.limits_dict(), tuple(stretched))


def _line_deviation(
    model: mujoco.MjModel, step: Segment, seg: SegmentResult
) -> tuple[float, float] | None:
    """(commanded, measured) largest distance in mm of the tip from a tip move's line."""
    if not isinstance(step, Move) or step.tip is None or step.path != "line" or not seg.steps:
        return None
    start = tip_pose(seg.start, model=model).position
    commanded = line_deviation(seg.commanded, start, step.tip, model=model).max_mm
    measured = line_deviation(seg.measured, start, step.tip, model=model).max_mm
    return float(commanded), float(measured)


def _joint_checks(
    seg: SegmentResult,
    lo: np.ndarray,
    hi: np.ndarray,
    effort: np.ndarray,
    saturated: np.ndarray,
    times: np.ndarray,
) -> dict[str, JointCheck]:
    """Every joint's figures over one step; ``effort`` and ``saturated`` (one row per joint)
    and ``times`` are its samples."""
    start = np.array([seg.start[n] for n in JOINT_NAMES])
    n = len(seg.commanded)
    both = np.empty((len(JOINT_NAMES), 2 * n + 1))
    both[:, 0] = start
    both[:, 1 : n + 1] = seg.commanded.T
    both[:, n + 1 :] = seg.measured.T
    # min(x - lo) == min(x) - lo exactly (rounding is monotonic)
    to_lower = both.min(axis=1) - lo
    to_upper = hi - both.max(axis=1)
    none = np.zeros(len(JOINT_NAMES))
    samples = effort.shape[1]
    peak = effort.max(axis=1) if samples else none
    longest = saturated.max(axis=1) if samples else none
    # when each joint's longest saturation began, and when its tracking error peaked
    sat_end = times[saturated.argmax(axis=1)] if samples else none + seg.start_time
    sat_start = np.maximum(sat_end - longest, seg.start_time)
    track = np.abs(both[:, 1 : n + 1] - both[:, n + 1 :])
    track_at = seg.times[track.argmax(axis=1)] if n else none + seg.start_time
    return {
        name: JointCheck(
            limit_margin=float(min(to_lower[i], to_upper[i])),
            limit_side="lower" if to_lower[i] <= to_upper[i] else "upper",
            peak_effort=float(peak[i]),
            saturated=float(longest[i]),
            peak_tracking_error=float(seg.max_tracking_error[name]),
            saturation_time=float(sat_start[i]),
            peak_tracking_time=float(track_at[i]),
        )
        for i, name in enumerate(JOINT_NAMES)
    }


def _by_joint(samples: np.ndarray) -> np.ndarray:
    """``(samples, joints)`` -> ``(joints, samples)``, contiguous."""
    return np.ascontiguousarray(np.asarray(samples).T)


def _run_lengths(above: np.ndarray) -> np.ndarray:
    """Per joint (row) and sample (column): how many consecutive samples up to it have been
    True."""
    if not above.any():  # nothing saturated: no run anywhere
        return np.zeros(above.shape, dtype=int)
    idx = np.arange(1, above.shape[1] + 1)[None, :]
    last_false = np.maximum.accumulate(np.where(above, 0, idx), axis=1)
    return (idx - last_false).astype(int)


def _body_label(m: mujoco.MjModel, body: int) -> str:
    return "floor" if body == 0 else m.body(body).name


def _contacts(
    m: mujoco.MjModel,
    records: list[tuple[float, int, int, float]],
    t0: float,
    t1: float,
    *,
    first: bool,
) -> list[Contact]:
    """The pairs of bodies that touched in ``(t0, t1]`` (from the start if ``first``), in the
    order they first touched, each with its deepest penetration."""
    pairs: dict[tuple[int, int], list[float]] = {}
    for t, b1, b2, dist in records:
        if not (t0 + _EPS_T < t <= t1 + _EPS_T or (first and t <= t0 + _EPS_T)):
            continue
        key = (min(b1, b2), max(b1, b2))
        if key in pairs:
            pairs[key][1] = max(pairs[key][1], -dist)
        else:
            pairs[key] = [t, -dist]
    return [
        Contact(_body_label(m, a), _body_label(m, b), t, max(0.0, pen))
        for (a, b), (t, pen) in sorted(pairs.items(), key=lambda kv: kv[1][0])
    ]


__all__ = [
    "Contact",
    "JointCheck",
    "Measurements",
    "StepCheck",
    "StepRecorder",
    "collect",
    "measure",
]
