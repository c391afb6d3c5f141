"""``so101sim grade``: an instructor's check of a lab hand-in, from its CSV log (and video).

The lab's spec (:class:`LabSpec`): from the rest pose, move to all zeros in 2 s, hold 2 s,
move back to the start in 2 s. :func:`grade_log` reads a log (:mod:`.gradelog`), finds the
phases in it from the *commanded* angles, not from timestamps or phase names (a student's own
script logs none), and judges each phase against the spec within :class:`Tolerances`:

* ``to_zero``: the arm started at rest; the move took 2 s; the arm reached all zeros.
* ``hold``: it lasted 2 s; the arm held still (the range of each joint over the hold).
* ``return``: the move took 2 s; the arm reached its starting pose; the log ends there.

How the phases are found: each commanded pose is placed on the way from rest to zeros
(``progress``: 0 at rest, 1 at all zeros, its projection on the straight line between them). A
*move* is a stretch where the progress changes faster than a fifth of the spec's pace (0.1 per
second for a 2 s move), widened while it slows smoothly (the ends of a minimum-jerk move) and
kept if it goes a quarter of the way or more. ``to_zero`` is the first move toward zeros
(with the moves toward zeros right after it), ``return`` the first move away after it (with
the moves away right after it), and ``hold`` what lies between. A jump of the command at the
start of a hold (the handout's ``hold_position`` commands the pose the arm reached) is not a
move.

:mod:`.gradevideo` checks the hand-in's video. A folder of hand-ins is graded by
:mod:`.gradefolder`. Results are dataclasses; the text and the CSV summary are made by
:mod:`.gradereport`.
"""

from __future__ import annotations

import itertools
import os
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from ..units import BODY_JOINTS, JOINT_NAMES, STARTING_POSE, ZERO_POSE
from ..validation import check_range
from .gradelog import RunLog, read_run_log
from .gradevideo import VideoResult, check_video

PHASES = ("to_zero", "hold", "return")


@dataclass(frozen=True)
class LabSpec:
    """What the lab asks: rest -> ``target`` in ``move_s``, hold ``hold_s``, back in
    ``return_s`` (seconds; poses in the arm's units, joints in JOINT_NAMES order)."""

    rest: tuple[float, ...] = tuple(STARTING_POSE[n] for n in JOINT_NAMES)
    target: tuple[float, ...] = tuple(ZERO_POSE[n] for n in JOINT_NAMES)
    move_s: float = 2.0
    hold_s: float = 2.0
    return_s: float = 2.0


@dataclass(frozen=True)
class Tolerances:
    """How far a hand-in may be from the spec and pass.

    ``angle_deg``: a reached pose's largest joint error, and the most a joint may move during
    the hold (degrees; the body joints: the gripper is not judged, see :func:`_worst`). 10° by
    default: the fitted STS3215 servos (``--arm sts3215``, so101sim's default) end the lab's
    2 s move 7.8° short at the elbow, as the real arm does; the ideal actuators of the
    official model reach within 0.1°.
    ``time_s``: a phase's duration from the spec's (0.25 s by default, an eighth of a phase).
    """

    angle_deg: float = 10.0
    time_s: float = 0.25

    def __post_init__(self) -> None:
        check_range(self.angle_deg, "--tolerance-deg", low=0.0, high=180.0, low_open=True)
        check_range(self.time_s, "--time-tolerance-s", low=0.0, high=60.0, low_open=True)


@dataclass(frozen=True)
class Check:
    """One judged figure: ``name`` (``start``, ``duration``, ``reached``, ``held``, ``end``;
    ``found`` when the phase was not), its ``value`` and what it is judged by (``limit``: the
    most an angle may be; for a duration the spec's seconds, within the time tolerance), in
    ``unit``; ``text`` says it in words; ``joint``: the worst one."""

    name: str
    passed: bool
    text: str
    value: float | None = None
    limit: float | None = None
    unit: str = ""
    joint: str = ""


@dataclass(frozen=True)
class PhaseResult:
    """A phase of the lab as found in the log (``start``/``end`` in s; None if not found)."""

    name: str
    start: float | None
    end: float | None
    checks: tuple[Check, ...]

    @property
    def found(self) -> bool:
        return self.start is not None

    @property
    def passed(self) -> bool:
        return all(c.passed for c in self.checks)

    def check(self, name: str) -> Check | None:
        return next((c for c in self.checks if c.name == name), None)

    @property
    def duration(self) -> float | None:
        return None if self.start is None or self.end is None else self.end - self.start


@dataclass(frozen=True)
class GradeResult:
    """A graded hand-in: the log's facts, each phase, the video (if any) and the verdict."""

    log: Path
    rows: int
    duration: float
    servo_model: str | None
    phases: tuple[PhaseResult, ...]
    tolerances: Tolerances
    spec: LabSpec
    video: VideoResult | None = None

    @property
    def passed(self) -> bool:
        ok = all(p.passed for p in self.phases)
        return ok and (self.video is None or self.video.passed)

    def phase(self, name: str) -> PhaseResult:
        return next(p for p in self.phases if p.name == name)

    @property
    def failures(self) -> list[str]:
        """Each failed check in words, ``"<phase>: <text>"`` (and the video's)."""
        out = [f"{p.name}: {c.text}" for p in self.phases for c in p.checks if not c.passed]
        if self.video is not None and not self.video.passed:
            out.append(f"video: {self.video.text}")
        return out


# ---------------------------------------------------------------------------- phases
def _progress(poses: np.ndarray, spec: LabSpec) -> np.ndarray:
    """Where each pose lies on the straight way from rest (0) to the target (1): its
    projection on that line, so a straight move of the lab is a straight line in progress and
    a joint moved across it (shoulder_pan, the gripper) leaves it unchanged."""
    target, rest = np.asarray(spec.target), np.asarray(spec.rest)
    way = target - rest
    return (poses - rest) @ way / float(way @ way)


def find_moves(time: np.ndarray, progress: np.ndarray, spec: LabSpec) -> list[tuple[int, int]]:
    """The moves in the log: (first row, last row) of each, in time order (see the module's
    docstring for the rule)."""
    if len(time) < 2:
        return []
    speed = np.diff(progress) / np.diff(time)  # speed[k]: from row k to row k + 1
    fast_limit, slow_limit = 0.2 / spec.move_s, 1e-4 / spec.move_s
    sign = np.sign(speed) * (np.abs(speed) > fast_limit)
    # runs of fast increments of one sign: where the signed flag changes
    edges = np.flatnonzero(np.diff(np.concatenate([[0], sign, [0]])))
    moves = []
    for a, b in itertools.pairwise(edges):
        if sign[a] == 0:
            continue
        first, last, s = int(a), int(b) - 1, sign[a]

        def smooth(k: int, towards: int, s: float = s) -> bool:  # the slowing end of a move
            v = speed[k + towards]
            return np.sign(v) == s and slow_limit < abs(v) < abs(speed[k]) * 0.999

        while first > 0 and smooth(first, -1):
            first -= 1
        while last < len(speed) - 1 and smooth(last, 1):
            last += 1
        if abs(progress[last + 1] - progress[first]) >= 0.25:
            moves.append((first, last + 1))
    return _merge_overlaps(moves)


def _merge_overlaps(moves: list[tuple[int, int]]) -> list[tuple[int, int]]:
    out: list[tuple[int, int]] = []
    for a, b in moves:
        if out and a < out[-1][1]:  # widened into the one before: one move
            out[-1] = (out[-1][0], max(b, out[-1][1]))
        else:
            out.append((a, b))
    return out


def _phase_rows(log: RunLog, spec: LabSpec) -> tuple[tuple[int, int] | None, ...]:
    """Rows (first, last) of to_zero, hold and return, None where not found."""
    progress = _progress(log.commanded, spec)
    moves = find_moves(log.time, progress, spec)
    direction = [np.sign(progress[b] - progress[a]) for a, b in moves]
    i = next((k for k, d in enumerate(direction) if d > 0), None)
    if i is None:
        return None, None, None
    j = i
    while j + 1 < len(moves) and direction[j + 1] > 0:
        j += 1
    to_zero = (moves[i][0], moves[j][1])
    if j + 1 >= len(moves):  # never moved back: the hold is the rest of the log
        return to_zero, (to_zero[1], log.rows - 1), None
    k = j + 1
    while k + 1 < len(moves) and direction[k + 1] < 0:
        k += 1
    back = (moves[j + 1][0], moves[k][1])
    return to_zero, (to_zero[1], back[0]), back


def _moving_at_start(log: RunLog, spec: LabSpec) -> bool:
    """Whether the command of the first row already moved away from where the arm started
    (a motion file's first step), rather than being the start pose (a handout-style script,
    whose first command is where the arm is)."""
    if log.rows < 2:
        return False
    commanded = _progress(log.commanded[:2], spec)
    began = _progress(log.measured[:1], spec)[0]
    first, step = commanded[0] - began, commanded[1] - commanded[0]
    return bool(step != 0 and np.sign(first) == np.sign(step) and abs(first) >= abs(step) / 2)


# ---------------------------------------------------------------------------- checks
def _worst(values: np.ndarray) -> tuple[float, str]:
    """The largest of a pose's values over the body joints, and its joint. The gripper is not
    judged: the handout's gripper unit (``qpos * 100 / 3.14159``) is not so101sim's 0-100
    over the gripper's range, so a script that follows the handout keeps its gripper at
    so101sim's 9.1, not 0, and would fail for the units alone."""
    body = values[: len(BODY_JOINTS)]
    k = int(np.argmax(body))
    return float(body[k]), JOINT_NAMES[k]


def _pose_check(name: str, what: str, error: np.ndarray, tol: Tolerances) -> Check:
    value, joint = _worst(np.abs(error))
    ok = value <= tol.angle_deg
    text = f"{what} within {value:.1f}° ({joint})"
    if not ok:
        text = f"{what}: {value:.1f}° off at {joint}; expected within {tol.angle_deg:g}°"
    return Check(name, ok, text, value, tol.angle_deg, "deg", joint)


def _duration_check(verb: str, seconds: float, spec_s: float, tol: Tolerances) -> Check:
    ok = abs(seconds - spec_s) <= tol.time_s
    text = f"{verb} {seconds:.3f} s"
    if not ok:
        text += f"; expected {spec_s:g} ± {tol.time_s:g} s"
    return Check("duration", ok, text, seconds, spec_s, "s")


def _missing(name: str, text: str) -> PhaseResult:
    return PhaseResult(name, None, None, (Check("found", False, text),))


def grade_run(
    log: RunLog, tolerances: Tolerances | None = None, spec: LabSpec | None = None
) -> GradeResult:
    """Judge a log already read (:func:`~.gradelog.read_run_log`) against ``spec``."""
    tol = tolerances if tolerances is not None else Tolerances()
    spec = spec if spec is not None else LabSpec()
    rows = _phase_rows(log, spec)
    t, q = log.time.copy(), log.measured
    if _moving_at_start(log, spec):  # row 0 holds the first step of a move: it began before
        t[0] = log.start_time
    start_pose, target = q[0], np.asarray(spec.target)
    began = _pose_check("start", "started at rest", start_pose - np.asarray(spec.rest), tol)
    phases = []
    if rows[0] is None:
        text = "the commands never moved toward all zeros (no move found)"
        phases.append(PhaseResult("to_zero", None, None, (began, Check("found", False, text))))
    else:
        a, b = rows[0]
        phases.append(
            PhaseResult(
                "to_zero",
                float(t[a]),
                float(t[b]),
                (
                    began,
                    _duration_check("took", float(t[b] - t[a]), spec.move_s, tol),
                    _pose_check("reached", "reached all zeros", q[b] - target, tol),
                ),
            )
        )
    if rows[1] is None:
        phases.append(_missing("hold", "no hold: the commands never went to all zeros first"))
    else:
        a, b = rows[1]
        moved, joint = _worst(np.ptp(q[a : b + 1], axis=0))
        ok = moved <= tol.angle_deg
        text = f"moved {moved:.1f}° ({joint})" if ok else (
            f"did not hold: {joint} moved {moved:.1f}°; expected at most {tol.angle_deg:g}°"
        )  # fmt: skip
        held = Check("held", ok, text, moved, tol.angle_deg, "deg", joint)
        lasted = _duration_check("lasted", float(t[b] - t[a]), spec.hold_s, tol)
        phases.append(PhaseResult("hold", float(t[a]), float(t[b]), (lasted, held)))
    ended = _pose_check("end", "ended at the start pose", q[-1] - start_pose, tol)
    if rows[2] is None:
        text = "the commands never moved back toward the start (no move found)"
        phases.append(PhaseResult("return", None, None, (Check("found", False, text), ended)))
    else:
        a, b = rows[2]
        checks = (
            _duration_check("took", float(t[b] - t[a]), spec.return_s, tol),
            _pose_check("reached", "reached the start pose", q[b] - start_pose, tol),
            ended,
        )
        phases.append(PhaseResult("return", float(t[a]), float(t[b]), checks))
    return GradeResult(log.path, log.rows, log.duration, log.servo_model, tuple(phases), tol, spec)


def grade_log(
    path: str | os.PathLike[str],
    *,
    video: str | os.PathLike[str] | None = None,
    tolerances: Tolerances | None = None,
    spec: LabSpec | None = None,
) -> GradeResult:
    """Grade the hand-in whose CSV log is at ``path`` (and its ``video``, if given).

    Raises:
        SettingError: ``path`` is not a readable file.
        NotASo101SimLogError: the file is not a so101sim log, or is damaged.
    """
    tol = tolerances if tolerances is not None else Tolerances()
    result = grade_run(read_run_log(path), tol, spec)
    if video is None:
        return result
    checked = check_video(video, result.duration, tol.time_s)
    return replace(result, video=checked)


__all__ = [
    "Check",
    "GradeResult",
    "LabSpec",
    "PhaseResult",
    "Tolerances",
    "find_moves",
    "grade_log",
    "grade_run",
]
