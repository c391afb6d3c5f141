"""Inverse kinematics: the pose (in the arm's units) that puts the tip at a point.

Damped least squares (Levenberg-Marquardt) on MuJoCo's Jacobians (``mj_jacSite``). Each
iteration solves ``(JᵀJ + λI) Δq = Jᵀr`` for the five body joints, with ``r`` the position
error (metres) and, if asked, the orientation error (radians, weighted by
:data:`ORIENTATION_WEIGHT` metres per radian) and ``λ = ½|r|² + 1e-9``: large far from the
target (short, safe steps), vanishing near it (Newton's quadratic convergence). Every iterate
is clipped into the joint limits, so no answer ever leaves them.

Where it starts matters more than how it descends. The attempts start, in turn, until one
lands within the tolerances:

1. from the closed-form answers of the planar chain (:mod:`.geometry`, :mod:`.seeds`) inside
   the joint limits, the one nearest ``initial`` first: exact when the goal fixes pitch and
   roll, so the descent only confirms them; for a position alone, the pitch of ``initial`` is
   kept if it reaches, else the nearest pitch that does (in 10° steps);
2. from ``initial`` itself (the warm start: give the arm's current pose to stay near it);
3. from up to ``restarts`` random in-limit poses (seeded: the same call gives the same
   answer), which escape local minima and the limits' corners.

An attempt ends when it converges (1e-5 mm), stalls, or makes less than 1 % progress for
8 iterations in a row.

Orientation, optional (see :mod:`so101sim.kinematics.core` for the angles):

* ``pitch``: the approach axis' angle above the horizontal in the arm's plane (-90: straight
  down); its error is one angle, exact whatever the heading;
* ``approach``: a direction to point along (three numbers), e.g. ``(0, 0, -1)``; for this arm
  it must lie in the vertical plane through the shoulder and the target, or point straight
  up or down;
* ``roll``: the jaws' turn about the approach axis;
* ``rotation``: the whole tool frame (3x3), e.g. a :class:`TipPose`'s.

The gripper does not move the tip: the answer keeps the gripper value of ``initial`` (or
``gripper``).
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Sequence
from dataclasses import dataclass

import mujoco
import numpy as np

from ..errors import UnreachableError
from ..exitgate import mujoco_call
from ..units import GRIPPER_INDEX, ZERO_POSE, Pose
from .core import N_BODY, Frame, Kinematics, TipPose, cross, for_model
from .goal import (
    DEFAULT_ITERATIONS,
    DEFAULT_RESTARTS,
    Goal,
    Settings,
    make_goal,
)
from .seeds import random_starts, seeds

ORIENTATION_WEIGHT = 0.05
"""Metres of position error worth one radian of orientation error (1° ~ 0.9 mm), in the
least-squares sum that IK minimises (and so in the "closest" answer of an unreachable target)."""

MAX_STEP_RAD = 0.35  # the largest change of one joint in one iteration (about 20°)
_CONVERGED_M = 1e-8  # position error under which an attempt stops (1e-5 mm)
_CONVERGED_RAD = 1e-7  # orientation error under which an attempt stops
_STALLED_RAD = 1e-10  # an iteration that moves no joint by more than this ends the attempt
_PROGRESS = 0.01  # an iteration that lowers the error by less than 1 % makes no progress ...
_PATIENCE = 8  # ... and this many such iterations in a row end the attempt


@dataclass(frozen=True, eq=False)
class IKResult:
    """An IK answer: the pose in the arm's units and how far its tip is from the goal."""

    pose: dict[str, float]  # joint name -> degrees (gripper 0-100)
    values: np.ndarray  # (6,) the same pose as an array in JOINT_NAMES order
    tip: TipPose  # where that pose puts the tip
    position_error_mm: float
    orientation_error_deg: float  # the largest of the asked angles' errors; 0 if none asked
    iterations: int  # over all attempts
    restarts: int  # attempts after the first (closed-form starts, the warm start, random poses)
    reachable: bool  # within the tolerances


@dataclass
class Attempt:
    q: np.ndarray  # radians, five body joints
    position_error: float  # m
    orientation_error: float  # rad
    cost: float  # weighted error norm, m
    iterations: int


def _wrap(angle: float) -> float:
    return (angle + math.pi) % (2.0 * math.pi) - math.pi


class Descent:
    """Damped least squares towards one goal, with its buffers allocated once."""

    def __init__(self, kin: Kinematics, goal: Goal) -> None:
        self.kin, self.goal = kin, goal
        rows = 3 + (goal.pitch is not None) + 3 * (goal.approach is not None)
        rows += (goal.roll is not None) + 3 * (goal.rotation is not None)
        self.j = np.zeros((rows, N_BODY))
        self.r = np.zeros(rows)
        self.a = np.zeros((N_BODY, N_BODY))

    def residual(self, f: Frame, jr: np.ndarray | None) -> float:
        """Fill the orientation rows of ``r`` (and of ``j`` if ``jr`` is given); return the
        orientation error in radians (the largest of the asked angles)."""
        goal, w, r, j = self.goal, ORIENTATION_WEIGHT, self.r, self.j
        row, err = 3, 0.0
        a = f.rotation[:, 0]
        if goal.pitch is not None:
            e = _wrap(goal.pitch - f.pitch)
            r[row], err = w * e, abs(e)
            if jr is not None:  # a turn about the plane's normal tilts the approach down
                j[row] = -w * (f.normal @ jr)
            row += 1
        if goal.approach is not None:
            r[row : row + 3] = w * (goal.approach - a)
            err = max(err, math.acos(min(1.0, max(-1.0, float(goal.approach @ a)))))
            if jr is not None:  # d a / d q_i = ω_i × a
                j[row : row + 3] = w * cross(jr, a[:, None])
            row += 3
        if goal.roll is not None:
            e = _wrap(goal.roll - f.roll)
            r[row], err = w * e, max(err, abs(e))
            if jr is not None:
                j[row] = -w * (a @ jr)
                j[row, 0] = 0.0  # the pan turns the reference (the plane's normal) with the jaws
            row += 1
        if goal.rotation is not None:  # the turn that takes the tool frame onto the asked one
            rot, want = f.rotation, goal.rotation
            turn = 0.5 * sum(cross(rot[:, k], want[:, k]) for k in range(3))
            r[row : row + 3] = w * turn
            cos = (float(np.einsum("ij,ij->", rot, want)) - 1.0) / 2.0
            err = max(err, math.acos(min(1.0, max(-1.0, cos))))
            if jr is not None:
                j[row : row + 3] = w * jr
        return err

    def run(self, q0: np.ndarray, max_iterations: int) -> Attempt:
        """Descend from ``q0`` (radians); call with ``kin.lock`` held."""
        kin, goal, j, r = self.kin, self.goal, self.j, self.r
        q = np.clip(q0, kin.lower, kin.upper)
        best = Attempt(q, math.inf, math.inf, math.inf, 0)
        since_progress = 0
        for it in range(max_iterations + 1):
            f = kin.frame_at(q, jacobians=True)
            jp, jr = kin.jacobians()
            r[:3] = goal.position - f.position
            j[:3] = jp
            oerr = self.residual(f, jr)
            cost = math.sqrt(float(r @ r))
            since_progress += 1
            if cost < best.cost:
                if cost < best.cost * (1.0 - _PROGRESS):
                    since_progress = 0
                pos_err = math.sqrt(float(r[:3] @ r[:3]))
                best = Attempt(q, pos_err, oerr, cost, it)
            converged = best.position_error < _CONVERGED_M and oerr < _CONVERGED_RAD
            if converged or it == max_iterations or since_progress > _PATIENCE:
                break
            q_next = q + self._step(q, 0.5 * cost * cost + 1e-9)
            np.clip(q_next, kin.lower, kin.upper, out=q_next)
            if float(np.max(np.abs(q_next - q))) < _STALLED_RAD:
                break
            q = q_next
        best.iterations = it
        return best

    def _step(self, q: np.ndarray, lam: float) -> np.ndarray:
        """The damped Gauss-Newton step; joints on a limit that the step would push further
        out are held, and the step is solved again without them."""
        kin, j = self.kin, self.j
        step = self._solve(j, lam)
        pushing = ((q <= kin.lower) & (step < 0.0)) | ((q >= kin.upper) & (step > 0.0))
        if pushing.any():
            held = j.copy()
            held[:, pushing] = 0.0
            step = self._solve(held, lam)
            step[pushing] = 0.0
        biggest = float(np.max(np.abs(step)))
        return step * (MAX_STEP_RAD / biggest) if biggest > MAX_STEP_RAD else step

    def _solve(self, j: np.ndarray, lam: float) -> np.ndarray:
        a = self.a
        np.matmul(j.T, j, out=a)
        a.flat[:: N_BODY + 1] += lam
        mujoco.mju_cholFactor(a, 0.0)
        step = np.empty(N_BODY)
        mujoco.mju_cholSolve(step, a, j.T @ self.r)
        return step


def _result(kin: Kinematics, att: Attempt, gripper: float, restarts: int, ok: bool) -> IKResult:
    values = np.empty(len(kin.units.lower))
    values[:N_BODY] = np.degrees(att.q)
    values[GRIPPER_INDEX] = gripper
    return IKResult(
        pose=kin.units.array_to_pose(values),
        values=values,
        tip=kin.frame_at(att.q).tip_pose(),
        position_error_mm=att.position_error * 1000.0,
        orientation_error_deg=math.degrees(att.orientation_error),
        iterations=att.iterations,
        restarts=restarts,
        reachable=ok,
    )


def solve(kin: Kinematics, goal: Goal, start: np.ndarray, s: Settings) -> tuple[Attempt, int, int]:
    """The best of the attempts from the closed-form seeds, from ``start`` (radians) and from
    up to ``s.restarts`` random poses, stopping at the first within the tolerances:
    ``(attempt, attempts after the first, total iterations)``. Call with ``kin.lock`` held."""
    descent = Descent(kin, goal)
    best: Attempt | None = None
    total = tries = 0
    randoms = random_starts(kin, goal, s.restarts, s.seed)
    for q0 in itertools.chain(seeds(kin, goal, start), [start], randoms):
        att = descent.run(q0, s.max_iterations)
        total += att.iterations
        tries += 1
        if best is None or att.cost < best.cost:
            best = att
        if s.accepts(best):
            break
    assert best is not None
    return best, tries - 1, total


def shortfall(goal: Goal, att: Attempt) -> str:
    """``the closest the tip gets is 3.2 mm away [and 1.0° off the asked orientation]``."""
    off = f"{att.position_error * 1000.0:.1f} mm away"
    if goal.oriented:
        off += f" and {math.degrees(att.orientation_error):.1f}° off the asked orientation"
    return f"the closest the tip gets is {off}"


def unreachable_message(goal: Goal, att: Attempt) -> str:
    return (
        f"tip target {goal.describe()} is out of reach within the joint limits: "
        f"{shortfall(goal, att)}; expected a target inside the arm's workspace (test one with "
        "so101sim.kinematics.is_reachable, draw it with plot_workspace), or pass "
        "closest=True to get the closest reachable pose"
    )


def solve_ik(
    target: Sequence[float] | np.ndarray,
    *,
    pitch: float | None = None,
    approach: Sequence[float] | np.ndarray | None = None,
    roll: float | None = None,
    rotation: Sequence[Sequence[float]] | np.ndarray | None = None,
    initial: Pose | np.ndarray | None = None,
    gripper: float | None = None,
    restarts: int = DEFAULT_RESTARTS,
    max_iterations: int = DEFAULT_ITERATIONS,
    tolerance_mm: float = 1.0,
    tolerance_deg: float = 1.0,
    seed: int = 0,
    closest: bool = False,
    model: mujoco.MjModel | None = None,
) -> IKResult:
    """The pose that puts the tip at ``target`` (metres, base frame: x forward, y left, z up),
    optionally pointing with ``pitch`` (degrees above the horizontal; -90 straight down) or
    along ``approach`` (a direction), and with ``roll`` (degrees); or with the whole tool frame
    ``rotation`` (3x3, as :attr:`TipPose.rotation` gives; the roll alone is measured from the
    arm's plane, so it cannot tell an arm reaching forward from one reaching back over its
    base, a rotation can).

    ``initial`` (a pose dict, partial ones filled from the zero pose, or six arm-unit values)
    is the warm start: give the arm's current pose to get the answer nearest to it. Its gripper
    value is kept unless ``gripper`` is given. Up to ``restarts`` further attempts start from
    random in-limit poses drawn with ``seed``. The answer is accepted within ``tolerance_mm``
    of the position and ``tolerance_deg`` of each asked angle (it is usually far closer).

    Returns:
        IKResult: the pose (arm units, always within the joint limits) and its residuals.

    Raises:
        UnreachableError: no attempt came within the tolerances (unless ``closest``, which
            returns the closest pose found, with ``reachable=False``); the message says how
            far the closest pose's tip is.
        SettingError: a target, angle or setting that is not valid.
        JointNameError, JointValueError, JointLimitError: ``initial`` is not a valid pose.
    """
    kin = for_model(model)
    asked = {"pitch": pitch, "approach": approach, "roll": roll, "rotation": rotation}
    goal = make_goal(target, asked)
    s = Settings.checked(restarts, max_iterations, tolerance_mm, tolerance_deg, seed)
    base = kin.units.pose_to_array(ZERO_POSE)
    start = base if initial is None else kin.pose_values(initial, base=base)
    if gripper is not None:
        start = kin.pose_values({"gripper": gripper}, base=start)
    with mujoco_call(), kin.lock:  # refused once the interpreter exits (exitgate)
        att, used, total = solve(kin, goal, np.radians(start[:N_BODY]), s)
        ok = s.accepts(att)
        att.iterations = total
        if not ok and not closest:
            raise UnreachableError(unreachable_message(goal, att))
        return _result(kin, att, float(start[GRIPPER_INDEX]), used, ok)
