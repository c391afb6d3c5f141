"""Preflight: simulate a motion headless and judge whether it is safe to run on the real arm.

For every step of the motion and every joint it reports:

* **limit margin**: the closest the joint (measured) or its target (commanded, from the
  step's starting target on) comes to either joint limit, in the arm's units (degrees; 0–100
  units for the gripper). Negative: past it.
* **peak effort**: the largest ``|actuator force|`` as a fraction of the actuator's force limit
  (``model.actuator_forcerange``), and **saturated**: the longest unbroken stretch of time the
  effort stayed above ``max_effort``. At 1.0 the actuator saturates; if it stays there, the real
  servo cannot follow the motion as commanded.
* **peak tracking error**: the largest ``|commanded - measured|``.

and every **contact** between two parts of the arm, or between the arm and the floor (bodies
named, with the first time and the deepest penetration).

The motion PASSes when, on every step: every body joint keeps at least ``limit_margin`` from its
limits, no effort stays above ``max_effort`` for longer than ``max_saturation`` (default 30 ms,
about one period of LeRobot's 30 Hz control loop), every tracking error stays at or below
``max_tracking_error``, and nothing touches.

Why a time and not the bare peak: the ``linear`` profile (the lab's) starts and stops each move
with a step in velocity, and the shipped model's stiff actuators (kp ≈ 998 N·m/rad) meet it by
saturating for a few milliseconds (shoulder and elbow: 6–14 ms in the lab motion) while the
tracking error stays under 0.3°. The servo follows; the report notes the spike. A move that is
too fast, or pushes into the floor, saturates for far longer and fails. ``minimum_jerk`` and
``limited`` keep the lab's moves under about 40 %.

The gripper is exempt from the limit margin (it is meant to close against its stop; 0 *is* its
lower limit) but not from the other checks.

The default limit margin is 1°: the shipped rest pose holds ``shoulder_lift`` at −98°, 2° from
its −100° limit, so the lab motion passes; a target at a limit, or within a degree of it, fails.
(A target beyond a limit never gets this far: the motion-file loader refuses it.)

The run is the same physics as ``so101sim run`` (same steps, bit for bit), observed after every
physics step, so it is slower than a plain run.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import mujoco
import numpy as np

from .errors import SettingError
from .model import arm_index, load_model
from .motion import RunResult, Segment, run_motion
from .motionfile import load_motion
from .simulation import Observer, Simulation
from .trajectory import check_limited_moves
from .units import GRIPPER, GRIPPER_INDEX, JOINT_NAMES, STARTING_POSE, Pose


@dataclass(frozen=True)
class Thresholds:
    """What a motion must stay within to PASS."""

    max_effort: float = 0.9  # fraction of the actuator's force limit
    max_saturation: float = 0.03  # s: longest time the effort may stay above max_effort
    max_tracking_error: float = 5.0  # degrees (gripper: 0–100 units)
    limit_margin: float = 1.0  # degrees from a body joint's limits

    def __post_init__(self) -> None:
        for name in ("max_effort", "max_saturation", "max_tracking_error", "limit_margin"):
            v = getattr(self, name)
            if not (isinstance(v, int | float) and math.isfinite(v) and v >= 0):
                raise SettingError(f"{name} = {v!r} is invalid; expected a finite number >= 0")


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


@dataclass(frozen=True)
class Contact:
    """Two bodies that touched during a step."""

    body1: str
    body2: str
    first_time: float  # s
    max_penetration: float  # m (>= 0)


@dataclass(frozen=True)
class StepCheck:
    index: int  # 1-based
    phase: str
    kind: str  # "move" | "hold"
    line: int  # line in the motion file (0: not from a file)
    start_time: float
    end_time: float
    joints: dict[str, JointCheck]
    contacts: tuple[Contact, ...]


@dataclass(frozen=True)
class PreflightReport:
    steps: tuple[StepCheck, ...]
    thresholds: Thresholds
    failures: tuple[str, ...]
    notes: tuple[str, ...] = field(default=())  # e.g. moves stretched by the joint limits

    @property
    def passed(self) -> bool:
        return not self.failures

    def to_dict(self) -> dict[str, Any]:
        """Plain data for JSON: ``passed``, ``failures``, ``notes``, ``thresholds``, ``steps``."""
        return {
            "passed": self.passed,
            "failures": list(self.failures),
            "notes": list(self.notes),
            "thresholds": asdict(self.thresholds),
            "steps": [asdict(s) for s in self.steps],
        }


class _Recorder(Observer):
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


def _run_lengths(above: np.ndarray) -> np.ndarray:
    """Per sample and column: how many consecutive samples up to it have been True."""
    out = np.zeros(above.shape, dtype=int)
    count = np.zeros(above.shape[1:], dtype=int)
    for i, row in enumerate(above):
        count = np.where(row, count + 1, 0)
        out[i] = count
    return out


def _body_label(m: mujoco.MjModel, body: int) -> str:
    return "floor" if body == 0 else m.body(body).name


def _fmt(joint: str, v: float) -> str:
    v = round(v, 2) + 0.0  # no "-0.00"
    return f"{v:.2f}" if joint == GRIPPER else f"{v:.2f}°"


def preflight(
    steps: Sequence[Segment],
    *,
    start: Pose = STARTING_POSE,
    model: mujoco.MjModel | str | Path | None = None,
    thresholds: Thresholds | None = None,
    lines: Sequence[int] = (),
    strict: bool = False,
) -> PreflightReport:
    """Simulate ``steps`` headless from ``start`` (at rest) and judge them.

    ``lines`` (the motion file's line of each step) only label the report. With ``strict``,
    a ``limited`` move shorter than the joint limits allow raises TrajectoryLimitError first.

    Raises:
        So101SimError: an invalid step (bad target, duration, profile), or strict refusal.
    """
    th = thresholds if thresholds is not None else Thresholds()
    m = model if isinstance(model, mujoco.MjModel) else load_model(model)
    sim = Simulation(m, initial_pose=start)
    units = sim.units
    notes = [
        f"step {s.index + 1} ({s.phase}): stretched from {s.requested:.3f} s to "
        f"{s.needed:.3f} s by the joint limits"
        for s in check_limited_moves(
            sim.commanded_array(), steps, sim.timestep, units=units, strict=strict
        )
    ]
    rec = _Recorder(m)
    result: RunResult = run_motion(m, sim.data, steps, observers=[rec])

    times = np.array(rec.times)
    effort = np.abs(np.array(rec.forces)) / np.abs(m.actuator_forcerange[rec.act, 1])
    ends = np.array([s.end_time for s in result.segments])
    seg_of_sample = np.searchsorted(ends + 1e-9, times)
    run = _run_lengths(effort > th.max_effort) * m.opt.timestep
    lo, hi = units.limits

    checks: list[StepCheck] = []
    failures: list[str] = []
    for k, seg in enumerate(result.segments):
        label = f"step {k + 1} ({seg.phase})"
        start_pose = np.array([seg.start[n] for n in JOINT_NAMES])
        both = np.vstack([start_pose, seg.commanded, seg.measured])
        to_lower = (both - lo).min(axis=0)
        to_upper = (hi - both).min(axis=0)
        in_seg = seg_of_sample == k
        peak = effort[in_seg].max(axis=0) if in_seg.any() else np.zeros(len(JOINT_NAMES))
        sat = run[in_seg].max(axis=0) if in_seg.any() else np.zeros(len(JOINT_NAMES))
        joints: dict[str, JointCheck] = {}
        for i, name in enumerate(JOINT_NAMES):
            side = "lower" if to_lower[i] <= to_upper[i] else "upper"
            margin = float(min(to_lower[i], to_upper[i]))
            jc = JointCheck(
                limit_margin=margin,
                limit_side=side,
                peak_effort=float(peak[i]),
                saturated=float(sat[i]),
                peak_tracking_error=float(seg.max_tracking_error[name]),
            )
            joints[name] = jc
            if i != GRIPPER_INDEX and margin < th.limit_margin:
                limit = lo[i] if side == "lower" else hi[i]
                failures.append(
                    f"{label}: {name} comes within {_fmt(name, margin)} of its {side} limit "
                    f"({_fmt(name, limit)}); the limit margin is {_fmt(name, th.limit_margin)}"
                )
            if jc.saturated > th.max_saturation + 1e-12:
                failures.append(
                    f"{label}: {name}'s actuator effort stays above {th.max_effort:.0%} of its "
                    f"force limit for {jc.saturated * 1000:.0f} ms (peak {jc.peak_effort:.0%}; "
                    f"at most {th.max_saturation * 1000:.0f} ms allowed): the real servo would "
                    "not follow"
                )
            elif jc.peak_effort > th.max_effort:
                notes.append(
                    f"{label}: {name}'s effort peaks at {jc.peak_effort:.0%} of its force limit "
                    f"for {jc.saturated * 1000:.0f} ms (allowed: up to "
                    f"{th.max_saturation * 1000:.0f} ms); a smooth profile avoids the spike"
                )
            if jc.peak_tracking_error > th.max_tracking_error:
                failures.append(
                    f"{label}: {name} lags its target by up to "
                    f"{_fmt(name, jc.peak_tracking_error)} "
                    f"(max {_fmt(name, th.max_tracking_error)})"
                )
        contacts = _contacts(m, rec.contacts, seg.start_time, seg.end_time, first=(k == 0))
        for c in contacts:
            failures.append(
                f"{label}: {c.body1} touches {c.body2} at t = {c.first_time:.3f} s "
                f"(up to {c.max_penetration * 1000:.1f} mm deep)"
            )
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
            )
        )
    return PreflightReport(tuple(checks), th, tuple(failures), tuple(notes))


def _contacts(
    m: mujoco.MjModel,
    records: list[tuple[float, int, int, float]],
    t0: float,
    t1: float,
    *,
    first: bool,
) -> list[Contact]:
    pairs: dict[tuple[int, int], list[float]] = {}
    for t, b1, b2, dist in records:
        if not (t0 + 1e-9 < t <= t1 + 1e-9 or (first and t <= t0 + 1e-9)):
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


def check_motion_file(
    path: str | Path,
    *,
    model: mujoco.MjModel | str | Path | None = None,
    thresholds: Thresholds | None = None,
    strict: bool = False,
) -> PreflightReport:
    """Load a motion file and :func:`preflight` it from its start pose."""
    m = model if isinstance(model, mujoco.MjModel) else load_model(model)
    from .model import arm_units

    motion = load_motion(path, units=arm_units(m))
    return preflight(
        motion.steps,
        start=motion.start,
        model=m,
        thresholds=thresholds,
        lines=motion.lines,
        strict=strict,
    )


def format_report(report: PreflightReport) -> str:
    """The report as a table, then PASS or FAIL with the reasons."""
    head = (
        f"{'step':<5}{'phase':<14}{'joint':<15}{'limit margin':>20}"
        f"{'peak effort':>13}{'saturated':>11}{'peak tracking':>15}"
    )
    th = report.thresholds
    rows = [head, "-" * len(head)]
    for s in report.steps:
        where = f" (line {s.line})" if s.line else ""
        rows.append(
            f"{s.index:<5}{s.phase[:13]:<14}{s.kind} {s.start_time:.3f}-{s.end_time:.3f} s{where}"
        )
        for name, j in s.joints.items():
            margin_bad = name != GRIPPER and j.limit_margin < th.limit_margin
            flags = [
                "!" if margin_bad else " ",
                "!" if j.saturated > th.max_saturation + 1e-12 else " ",
                "!" if j.peak_tracking_error > th.max_tracking_error else " ",
            ]
            margin = f"{_fmt(name, j.limit_margin)} ({j.limit_side})"
            rows.append(
                f"{'':<5}{'':<14}{name:<15}{margin:>19}{flags[0]}"
                f"{j.peak_effort:>12.1%} {j.saturated * 1000:>7.0f} ms{flags[1]}"
                f"{_fmt(name, j.peak_tracking_error):>14}{flags[2]}"
            )
        for c in s.contacts:
            rows.append(
                f"{'':<19}contact: {c.body1} - {c.body2} at t = {c.first_time:.3f} s "
                f"({c.max_penetration * 1000:.1f} mm)"
            )
    rows.append("")
    for note in report.notes:
        rows.append(f"note: {note}")
    rows.append(
        f"thresholds: limit margin {th.limit_margin:g}° (body joints), effort above "
        f"{th.max_effort:.0%} of the force limit for at most {th.max_saturation * 1000:g} ms, "
        f"tracking error {th.max_tracking_error:g}° (gripper: same figures in 0-100 units)"
    )
    if report.passed:
        rows.append("PASS")
    else:
        rows.append(f"FAIL ({len(report.failures)} reason(s))")
        rows.extend(f"  - {f}" for f in report.failures)
    return "\n".join(rows)


__all__ = [
    "Contact",
    "JointCheck",
    "PreflightReport",
    "StepCheck",
    "Thresholds",
    "check_motion_file",
    "format_report",
    "preflight",
]
