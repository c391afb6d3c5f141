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

The efforts are fractions of the arm profile's torque limits (the actuators' ``forcerange``:
the default ``sts3215`` at 7.4 V, ±3.92 N·m; ``official``, ±3.35 N·m; see
:mod:`so101sim.model.arm`), and the arm is the profile's: the fitted STS3215 sags under the
arm's weight and lags a moving goal (its firmware slews the goal at most 4.9 rad/s, P = 16
gives 11 N·m/rad, a 27 ms delay), so its tracking errors are those of the real arm (up to
9.2° in the lab motion) and the default ``max_tracking_error`` (15°) is set for it. Its
efforts stay well inside the limit in the lab's moves (the slew-limited goal does not kick
the motor at a move's start).

Why a time and not the bare peak: the ``linear`` shape (the lab's) starts and stops each move
with a step in velocity, and the vendored model's stiff actuators (``--arm official``, kp ≈
998 N·m/rad) meet it by saturating for a few milliseconds (shoulder and elbow: 6–14 ms in the
lab motion) while the tracking error stays under 0.3°. The servo follows; the report notes
the spike. A move that is too fast, or pushes into the floor, saturates for far longer and
fails.

The gripper is exempt from the limit margin (it is meant to close against its stop; 0 *is* its
lower limit) but not from the other checks.

The default limit margin is 1°: the shipped rest pose holds ``shoulder_lift`` at −98°, 2° from
its −100° limit, so the lab motion passes; a target at a limit, or within a degree of it, fails.
(A target beyond a limit never gets this far: the motion-file loader refuses it.)

The run is the same physics as ``so101sim run`` (same steps, bit for bit), stepped in whole
blocks in C; every physics step's figures are derived from what the blocks recorded
(:mod:`so101sim.preflight.states`), so a check costs about what a plain run costs.

Three parts: :mod:`so101sim.preflight.measure` runs the motion and measures it,
:mod:`so101sim.preflight.judge` compares the figures with the :class:`Thresholds` once, and this
module puts the findings into words (:class:`PreflightReport`, :func:`format_report`) and holds
the public entry points, :func:`preflight` and :func:`check_motion_file`.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import mujoco
import numpy as np

from ..model.arm import ArmLike
from ..model.load import arm_units, load_model
from ..motion.file import load_motion
from ..motion.segments import Segment
from ..units import STARTING_POSE, Pose, format_value
from ..validation import escape_controls
from .judge import (
    ContactFinding,
    EffortFinding,
    Finding,
    LimitFinding,
    StretchFinding,
    Thresholds,
    TrackingFinding,
    judge,
)
from .measure import Contact, JointCheck, StepCheck, measure


@dataclass(frozen=True)
class PreflightReport:
    """The measured steps, the thresholds they were judged by, and the verdict in words.

    ``findings`` are the same failures and notes as data (which step, joint and check);
    :func:`format_report` marks the table from them.
    """

    steps: tuple[StepCheck, ...]
    thresholds: Thresholds
    failures: tuple[str, ...]
    notes: tuple[str, ...] = field(default=())  # e.g. moves stretched by the joint limits
    findings: tuple[Finding, ...] = field(default=(), repr=False)

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


def preflight(
    steps: Sequence[Segment],
    *,
    start: Pose = STARTING_POSE,
    model: mujoco.MjModel | str | Path | None = None,
    thresholds: Thresholds | None = None,
    lines: Sequence[int] = (),
    strict: bool = False,
    arm: ArmLike = None,
    known: Mapping[int, tuple[np.ndarray, np.ndarray]] | None = None,
) -> PreflightReport:
    """Simulate ``steps`` headless from ``start`` (at rest) and judge them.

    ``model``: a compiled model, or a file loaded with the arm profile ``arm`` (None: the
    default, see :func:`so101sim.model.load_model`); the efforts are fractions of that
    profile's torque limits (the actuators' ``forcerange``).

    ``lines`` (the motion file's line of each step) only label the report. With ``strict``,
    a ``limited`` move shorter than the joint limits allow raises TrajectoryLimitError first.
    ``known``: tip moves already planned on ``model`` (``MotionFile.tip_plans``).

    Raises:
        So101SimError: an invalid step (bad target, duration, shape), or strict refusal.
    """
    th = thresholds if thresholds is not None else Thresholds()
    m = model if isinstance(model, mujoco.MjModel) else load_model(model, arm=arm)
    measured = measure(
        steps,
        start=start,
        model=m,
        saturation_level=th.max_effort,
        lines=lines,
        strict=strict,
        known=known,
    )
    findings = judge(measured, th)
    return PreflightReport(
        measured.steps,
        th,
        failures=tuple(describe(f, th) for f in findings if f.failed),
        notes=tuple(describe(f, th) for f in findings if not f.failed),
        findings=findings,
    )


def check_motion_file(
    path: str | Path,
    *,
    model: mujoco.MjModel | str | Path | None = None,
    thresholds: Thresholds | None = None,
    strict: bool = False,
    arm: ArmLike = None,
) -> PreflightReport:
    """Load a motion file and :func:`preflight` it from its start pose (on ``model`` with the
    arm profile ``arm``, see :func:`preflight`)."""
    m = model if isinstance(model, mujoco.MjModel) else load_model(model, arm=arm)
    motion = load_motion(path, units=arm_units(m), model=m)
    return preflight(
        motion.steps,
        start=motion.start,
        model=m,
        thresholds=thresholds,
        lines=motion.lines,
        strict=strict,
        known=motion.tip_plans,  # the loader's tip lines, planned on m: not solved again
    )


# ---------------------------------------------------------------------------- wording
def describe(finding: Finding, th: Thresholds) -> str:
    """A finding in words, as listed under FAIL or as a note."""
    label = f"step {finding.step} ({escape_controls(finding.phase, lines=False)})"
    name = finding.joint

    def value(v: float) -> str:
        return format_value(name, v, 2)

    match finding:
        case StretchFinding(requested=requested, needed=needed):
            return (
                f"{label}: stretched from {requested:.3f} s to {needed:.3f} s by the joint limits"
            )
        case LimitFinding(margin=margin, side=side, limit=limit):
            return (
                f"{label}: {name} comes within {value(margin)} of its {side} limit "
                f"({value(limit)}); the limit margin is {value(th.limit_margin)}"
            )
        case EffortFinding(failed=True, peak=peak, saturated=saturated, at=at):
            return (
                f"{label}: {name}'s actuator effort stays above {th.max_effort:.0%} of its "
                f"force limit for {saturated * 1000:.0f} ms from t = {at:.3f} s (peak {peak:.0%}; "
                f"at most {th.max_saturation * 1000:.0f} ms allowed): the real servo would "
                "not follow"
            )
        case EffortFinding(peak=peak, saturated=saturated):
            return (
                f"{label}: {name}'s effort peaks at {peak:.0%} of its force limit "
                f"for {saturated * 1000:.0f} ms (allowed: up to "
                f"{th.max_saturation * 1000:.0f} ms); a smooth shape "
                '(shape = "minimum_jerk") avoids the spike'
            )
        case TrackingFinding(error=error, at=at):
            return (
                f"{label}: {name} lags its target by up to {value(error)} at t = {at:.3f} s "
                f"(max {value(th.max_tracking_error)})"
            )
        case ContactFinding(contact=c):
            return (
                f"{label}: {c.body1} touches {c.body2} at t = {c.first_time:.3f} s "
                f"(up to {c.max_penetration * 1000:.1f} mm deep)"
            )
    raise TypeError(f"no wording for {type(finding).__name__}; expected one of preflight.judge's")


_HEAD = (
    f"{'step':<5}{'phase':<14}{'joint':<15}{'limit margin':>20}"
    f"{'peak effort':>13}{'saturated':>11}{'peak tracking':>15}"
)
_MARKED = (LimitFinding, EffortFinding, TrackingFinding)  # the table's columns marked "!"


def format_report(report: PreflightReport) -> str:
    """The report as a table, then PASS or FAIL with the reasons.

    A figure that failed is marked ``!``, after the report's findings (nothing is compared
    again here).
    """
    marked = {(f.step, f.joint, type(f)) for f in report.findings if f.failed}
    rows = [_HEAD, "-" * len(_HEAD)]
    for s in report.steps:
        rows.extend(_step_rows(s, marked))
    rows.append("")
    rows.extend(f"note: {note}" for note in report.notes)
    th = report.thresholds
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


def _step_rows(s: StepCheck, marked: set[tuple[int, str, type]]) -> list[str]:
    where = f" (line {s.line})" if s.line else ""
    phase = escape_controls(s.phase, lines=False)[:13]  # a name from the API may hold anything
    rows = [f"{s.index:<5}{phase:<14}{s.kind} {s.start_time:.3f}-{s.end_time:.3f} s{where}"]
    for name, j in s.joints.items():
        flags = ["!" if (s.index, name, kind) in marked else " " for kind in _MARKED]
        rows.append(_joint_row(name, j, flags))
    rows.extend(
        f"{'':<19}contact: {c.body1} - {c.body2} at t = {c.first_time:.3f} s "
        f"({c.max_penetration * 1000:.1f} mm)"
        for c in s.contacts
    )
    if s.line_deviation_mm is not None:
        commanded, measured = s.line_deviation_mm
        rows.append(
            f"{'':<19}tip off the straight line: {commanded:.2f} mm commanded, "
            f"{measured:.2f} mm measured (largest)"
        )
    return rows


def _joint_row(name: str, j: JointCheck, flags: list[str]) -> str:
    margin = f"{format_value(name, j.limit_margin, 2)} ({j.limit_side})"
    return (
        f"{'':<5}{'':<14}{name:<15}{margin:>19}{flags[0]}"
        f"{j.peak_effort:>12.1%} {j.saturated * 1000:>7.0f} ms{flags[1]}"
        f"{format_value(name, j.peak_tracking_error, 2):>14}{flags[2]}"
    )


__all__ = [
    "Contact",
    "Finding",
    "JointCheck",
    "PreflightReport",
    "StepCheck",
    "Thresholds",
    "check_motion_file",
    "describe",
    "format_report",
    "preflight",
]
