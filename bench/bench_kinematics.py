"""IK time per target and success rate: so101sim's IK side by side with mink's and placo's,
on the same targets and the same model.

    python bench/bench_kinematics.py [--targets 1000] [--seed 0]

The targets are the tip poses of random in-limit poses (so each is reachable). A target
counts as reached within 1 mm and 1° (the rotation between the reached and the asked tool
frame) with every joint inside its limits; an answer past a limit by more than 1e-9 rad is
counted (last column) and not reached. Times are per target, all attempts included: CPU time
of the thread (steady on a shared machine) and wall time, median and 99th percentile.

The same stop rules for all (so101sim's, from ``so101sim/kinematics/ik.py``, applied around
mink's and placo's iterations by :func:`attempts`): an attempt ends when it converges (1e-8 m,
1e-7 rad), stalls, makes less than 1 % progress for 8 iterations in a row, or after 100
iterations; attempts follow one another until the best answer so far is within the
tolerances, and the best answer is returned. mink and placo start from the zero pose, then
up to 8 random in-limit poses (the same ones for both); so101sim starts from its closed-form
seeds, then the zero pose, then up to 8 random in-limit poses of its own (``restarts=8``).
Joint limits are enforced by all: so101sim clips every iterate, mink adds its
``ConfigurationLimit`` to the QP (daqp, mink's default damping), placo its joint-limit
constraints (``enable_joint_limits``). Orientation weights are each library's own:
so101sim's ``ORIENTATION_WEIGHT``, mink's ``orientation_cost=1``, placo's frame task weights
1 and 1.

mink and placo are not dependencies of so101sim; install them in the bench's own
environment and run the bench with its Python:

    python3 -m venv /tmp/bench-venv
    /tmp/bench-venv/bin/pip install -e . mink placo
    /tmp/bench-venv/bin/python bench/bench_kinematics.py

A solver that is not installed is skipped with a note. placo needs a URDF: the bench writes
one from the compiled MuJoCo model (the bodies' offsets, the joint axes and limits, the
``gripperframe`` site as a fixed frame) and checks its forward kinematics against MuJoCo's
before timing anything. (Over 400 lines: three solvers' adapters and the URDF writer stay in
one file, so that the bench runs alone.)
"""

from __future__ import annotations

import argparse
import math
import tempfile
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import mujoco
import numpy as np

from so101sim.kinematics import solve_ik, tip_pose
from so101sim.kinematics.goal import DEFAULT_ITERATIONS, DEFAULT_RESTARTS
from so101sim.kinematics.ik import _CONVERGED_M as CONVERGED_M
from so101sim.kinematics.ik import _CONVERGED_RAD as CONVERGED_RAD
from so101sim.kinematics.ik import _PATIENCE as PATIENCE
from so101sim.kinematics.ik import _PROGRESS as PROGRESS
from so101sim.kinematics.ik import _STALLED_RAD as STALLED_RAD
from so101sim.kinematics.ik import ORIENTATION_WEIGHT
from so101sim.model import arm_index, arm_units, load_model
from so101sim.units import JOINT_NAMES

RESTARTS = DEFAULT_RESTARTS
ITERATIONS = DEFAULT_ITERATIONS
TOL_MM, TOL_DEG = 1.0, 1.0
MINK_DT = 0.01  # s; the velocity is integrated over the same dt: a full step


@dataclass
class Target:
    position: np.ndarray  # (3,) m, world = base frame in the shipped model
    rotation: np.ndarray  # (3, 3)
    pitch: float
    roll: float


@dataclass
class Outcome:
    q: np.ndarray  # radians, the arm's six joints
    cpu_s: float
    wall_s: float


def rotation_error_deg(a: np.ndarray, b: np.ndarray) -> float:
    c = (np.trace(a.T @ b) - 1.0) / 2.0
    return math.degrees(math.acos(min(1.0, max(-1.0, c))))


def make_targets(model: mujoco.MjModel, n: int, seed: int) -> tuple[list[Target], np.ndarray]:
    lo, hi = arm_units(model).limits
    values = np.random.default_rng(seed).uniform(lo, hi, size=(n, len(JOINT_NAMES)))
    targets = []
    for v in values:
        t = tip_pose(v, model=model)
        targets.append(Target(t.position, t.rotation, t.pitch, t.roll))
    return targets, values


def starts(model: mujoco.MjModel, seed: int) -> np.ndarray:
    """The zero pose, then RESTARTS random in-limit poses (radians), the same for all."""
    idx = arm_index(model)
    rng = np.random.default_rng(seed + 1)
    return np.vstack([np.zeros(len(JOINT_NAMES)), rng.uniform(idx.lower, idx.upper, (RESTARTS, 6))])


def timed(fn: Callable[[], np.ndarray]) -> Outcome:
    c0, w0 = time.thread_time(), time.perf_counter()
    q = fn()
    return Outcome(q, time.thread_time() - c0, time.perf_counter() - w0)


# ---------------------------------------------------------------------------- so101sim
def so101sim_solver(model: mujoco.MjModel, full: bool, pitch_only: bool = False):
    units = arm_units(model)

    def solve(t: Target) -> np.ndarray:
        kw: dict = {}
        if full:
            kw = {"rotation": t.rotation}
        elif pitch_only:
            kw = {"pitch": t.pitch}
        r = solve_ik(t.position, closest=True, restarts=RESTARTS, model=model, **kw)
        return units.to_radians(r.values)

    return solve


# ---------------------------------------------------------------------------- the same stops
@dataclass
class Stepper:
    """Another solver on one goal, for :func:`attempts`."""

    start: Callable[[np.ndarray], None]  # put the arm at six joint values (radians)
    step: Callable[[], float]  # one iteration of the solver; returns the largest joint change
    error: Callable[[], tuple[float, float]]  # (position m, orientation rad) now
    q: Callable[[], np.ndarray]  # the arm's six joints now (radians)


def attempts(s: Stepper, q0s: np.ndarray) -> np.ndarray:
    """so101sim's stop rules (``kinematics/ik.py``) around another solver's iterations.

    An attempt stops when it converges (``CONVERGED_M``, ``CONVERGED_RAD``), when an iteration
    moves no joint by more than ``STALLED_RAD``, after ``PATIENCE`` iterations in a row that
    lower the error (position and orientation weighted as in so101sim) by less than
    ``PROGRESS``, or after ``ITERATIONS``. Attempts start from ``q0s`` in turn until the best
    pose so far is within the tolerances; the best pose is the answer."""
    best_q, best_cost, best_ok = q0s[0], math.inf, False
    for q0 in q0s:
        s.start(q0)
        attempt_best, since_progress = math.inf, 0
        for it in range(ITERATIONS + 1):
            pos, rot = s.error()
            cost = math.hypot(pos, ORIENTATION_WEIGHT * rot)
            since_progress += 1
            if cost < attempt_best:
                if cost < attempt_best * (1.0 - PROGRESS):
                    since_progress = 0
                attempt_best = cost
                if cost < best_cost:
                    best_q, best_cost = s.q(), cost
                    best_ok = pos * 1000.0 <= TOL_MM and math.degrees(rot) <= TOL_DEG
            converged = pos < CONVERGED_M and rot < CONVERGED_RAD
            if converged or it == ITERATIONS or since_progress > PATIENCE:
                break
            if s.step() < STALLED_RAD:
                break
        if best_ok:
            break
    return best_q


# ---------------------------------------------------------------------------- mink
def mink_solver(model: mujoco.MjModel, full: bool, seed: int):
    import mink

    cfg = mink.Configuration(model)
    task = mink.FrameTask("gripperframe", "site", position_cost=1.0, orientation_cost=float(full))
    limits = [mink.ConfigurationLimit(model)]
    q0s = starts(model, seed)
    idx = arm_index(model)
    site = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_SITE, "gripperframe")
    goal: list[Target] = []

    def start(q0: np.ndarray) -> None:
        q = cfg.q.copy()
        q[idx.qpos] = q0
        cfg.update(q)

    def step() -> float:
        vel = mink.solve_ik(cfg, [task], MINK_DT, "daqp", limits=limits)  # default damping
        cfg.integrate_inplace(vel, MINK_DT)
        return float(np.max(np.abs(vel))) * MINK_DT

    def error() -> tuple[float, float]:
        t, d = goal[0], cfg.data
        pos = float(np.linalg.norm(d.site_xpos[site] - t.position))
        if not full:
            return pos, 0.0
        return pos, math.radians(rotation_error_deg(d.site_xmat[site].reshape(3, 3), t.rotation))

    stepper = Stepper(start, step, error, lambda: cfg.q[idx.qpos].copy())

    def solve(t: Target) -> np.ndarray:
        goal[:] = [t]
        task.set_target(
            mink.SE3.from_rotation_and_translation(mink.SO3.from_matrix(t.rotation), t.position)
        )
        return attempts(stepper, q0s)

    return solve


# ---------------------------------------------------------------------------- placo
def _rpy(quat: np.ndarray) -> str:
    """A MuJoCo quaternion as URDF roll-pitch-yaw (fixed axes x, y, z)."""
    m = np.zeros(9)
    mujoco.mju_quat2Mat(m, quat)
    r = m.reshape(3, 3)
    pitch = math.atan2(-r[2, 0], math.hypot(r[0, 0], r[1, 0]))
    if math.hypot(r[0, 0], r[1, 0]) < 1e-12:  # pointing straight up or down
        return f"0 {pitch!r} {math.atan2(-r[0, 1], r[1, 1])!r}"
    return f"{math.atan2(r[2, 1], r[2, 2])!r} {pitch!r} {math.atan2(r[1, 0], r[0, 0])!r}"


def _xyz(v: np.ndarray) -> str:
    return " ".join(repr(float(x)) for x in v)


def urdf_from_model(model: mujoco.MjModel) -> str:
    """A kinematic URDF of ``model``: one link per body, one joint per hinge (at the body's
    origin, as in the SO-101's MJCF), the sites as fixed frames."""
    name = lambda obj, i: mujoco.mj_id2name(model, obj, i)  # noqa: E731
    body = mujoco.mjtObj.mjOBJ_BODY
    out = ['<?xml version="1.0"?>', '<robot name="so101">']
    for b in range(1, model.nbody):
        mass = max(float(model.body_mass[b]), 1e-6)
        inertia = [max(float(x), 1e-9) for x in model.body_inertia[b]]
        out.append(
            f'<link name="{name(body, b)}"><inertial><origin xyz="{_xyz(model.body_ipos[b])}" '
            f'rpy="{_rpy(model.body_iquat[b])}"/><mass value="{mass!r}"/><inertia '
            f'ixx="{inertia[0]!r}" iyy="{inertia[1]!r}" izz="{inertia[2]!r}" ixy="0" ixz="0" '
            'iyz="0"/></inertial></link>'
        )
        parent = int(model.body_parentid[b])
        if parent == 0:
            continue  # the root link (the base, at the world's origin)
        origin = f'<origin xyz="{_xyz(model.body_pos[b])}" rpy="{_rpy(model.body_quat[b])}"/>'
        j = int(model.body_jntadr[b])
        if model.body_jntnum[b] == 1 and model.jnt_type[j] == mujoco.mjtJoint.mjJNT_HINGE:
            assert np.allclose(model.jnt_pos[j], 0.0), "a joint off its body's origin"
            lo, hi = (float(x) for x in model.jnt_range[j])
            out.append(
                f'<joint name="{name(mujoco.mjtObj.mjOBJ_JOINT, j)}" type="revolute">'
                f'<parent link="{name(body, parent)}"/><child link="{name(body, b)}"/>{origin}'
                f'<axis xyz="{_xyz(model.jnt_axis[j])}"/><limit lower="{lo!r}" upper="{hi!r}" '
                'effort="10" velocity="10"/></joint>'
            )
        else:
            out.append(
                f'<joint name="fixed_{name(body, b)}" type="fixed"><parent '
                f'link="{name(body, parent)}"/><child link="{name(body, b)}"/>{origin}</joint>'
            )
    for s in range(model.nsite):
        site, parent = name(mujoco.mjtObj.mjOBJ_SITE, s), name(body, int(model.site_bodyid[s]))
        out.append(
            f'<link name="{site}"/><joint name="fixed_{site}" type="fixed"><parent '
            f'link="{parent}"/><child link="{site}"/><origin xyz="{_xyz(model.site_pos[s])}" '
            f'rpy="{_rpy(model.site_quat[s])}"/></joint>'
        )
    out.append("</robot>")
    return "\n".join(out)


def placo_solver(model: mujoco.MjModel, full: bool, seed: int, folder: Path):
    import placo

    path = folder / "so101.urdf"
    path.write_text(urdf_from_model(model), encoding="utf-8")
    robot = placo.RobotWrapper(str(path), placo.Flags.ignore_collisions)
    solver = placo.KinematicsSolver(robot)
    solver.mask_fbase(True)
    solver.enable_velocity_limits(False)
    solver.enable_joint_limits(True)
    if full:
        task = solver.add_frame_task("gripperframe", np.eye(4))
        task.configure("gripperframe", "soft", 1.0, 1.0)
    else:
        task = solver.add_position_task("gripperframe", np.zeros(3))
        task.configure("gripperframe", "soft", 1.0)
    q0s = starts(model, seed)

    def set_q(q: np.ndarray) -> None:
        for n, v in zip(JOINT_NAMES, q, strict=True):
            robot.set_joint(n, float(v))
        robot.update_kinematics()

    def get_q() -> np.ndarray:
        return np.array([robot.get_joint(n) for n in JOINT_NAMES])

    def step() -> float:
        dq = solver.solve(True)
        robot.update_kinematics()
        return float(np.max(np.abs(dq)))

    def error() -> tuple[float, float]:
        t, frame = goal[0], robot.get_T_world_frame("gripperframe")
        pos = float(np.linalg.norm(frame[:3, 3] - t.position))
        if not full:
            return pos, 0.0
        return pos, math.radians(rotation_error_deg(frame[:3, :3], t.rotation))

    goal: list[Target] = []
    stepper = Stepper(set_q, step, error, get_q)

    def solve(t: Target) -> np.ndarray:
        goal[:] = [t]
        if full:
            pose = np.eye(4)
            pose[:3, :3], pose[:3, 3] = t.rotation, t.position
            task.T_world_frame = pose
        else:
            task.target_world = t.position
        return attempts(stepper, q0s)

    def fk_check() -> float:
        data = mujoco.MjData(model)
        site = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_SITE, "gripperframe")
        idx = arm_index(model)
        worst = 0.0
        for q in np.random.default_rng(seed).uniform(idx.lower, idx.upper, (200, 6)):
            set_q(q)
            data.qpos[idx.qpos] = q
            mujoco.mj_kinematics(model, data)
            frame = robot.get_T_world_frame("gripperframe")
            worst = max(worst, float(np.abs(frame[:3, 3] - data.site_xpos[site]).max()))
        return worst

    return solve, fk_check


# ---------------------------------------------------------------------------- running
def run(name: str, solve, model, targets: list[Target], full: bool) -> str:
    idx = arm_index(model)
    ok = outside = 0
    worst = 0.0  # rad, the farthest an answer went past a joint limit
    cpu, wall = [], []
    data = mujoco.MjData(model)
    site = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_SITE, "gripperframe")
    solve(targets[0])  # warm caches and imports
    for t in targets:
        out = timed(lambda t=t: solve(t))
        cpu.append(out.cpu_s)
        wall.append(out.wall_s)
        data.qpos[idx.qpos] = out.q
        mujoco.mj_kinematics(model, data)
        err_mm = np.linalg.norm(data.site_xpos[site] - t.position) * 1000.0
        err_deg = (
            rotation_error_deg(data.site_xmat[site].reshape(3, 3), t.rotation) if full else 0.0
        )
        excess = max(0.0, float(np.max(idx.lower - out.q)), float(np.max(out.q - idx.upper)))
        inside = excess <= 1e-9
        outside += not inside
        worst = max(worst, excess)
        ok += err_mm <= TOL_MM and err_deg <= TOL_DEG and inside
    c, w = np.array(cpu) * 1000.0, np.array(wall) * 1000.0
    times = " ".join(
        f"{x:8.3f}" for x in (*np.percentile(c, [50, 99]), *np.percentile(w, [50, 99]))
    )
    past = f" (by up to {math.degrees(worst):.1e}°)" if outside else ""
    return f"{name:<34} {100.0 * ok / len(targets):7.1f} % {times}   {outside}{past}"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--targets", type=int, default=1000)
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args()
    model = load_model()
    targets, _ = make_targets(model, args.targets, args.seed)
    print(
        f"{args.targets} targets (tip poses of random in-limit poses, seed {args.seed}); "
        f"reached: within {TOL_MM:g} mm and {TOL_DEG:g}°, inside the joint limits"
    )
    print(
        f"{'solver, goal':<34} {'reached':>9} {'cpu ms':>8} {'p99':>8} {'wall ms':>8} {'p99':>8}"
        "   outside limits"
    )
    lines = []
    for full, goal in ((False, "position"), (True, "full pose")):
        print(run(f"so101sim, {goal}", so101sim_solver(model, full), model, targets, full))
        if not full:
            solver = so101sim_solver(model, False, pitch_only=True)
            print(run("so101sim, position + pitch", solver, model, targets, False))
        try:
            solver = mink_solver(model, full, args.seed)
        except ImportError:
            lines.append(
                "mink: not installed (pip install mink in the bench's environment); skipped"
            )
        else:
            print(run(f"mink (daqp), {goal}", solver, model, targets, full))
        try:
            with tempfile.TemporaryDirectory() as tmp:
                solver, fk_check = placo_solver(model, full, args.seed, Path(tmp))
                worst = fk_check()
                if full:
                    lines.append(
                        f"placo's URDF (written from the MuJoCo model): its tip "
                        f"differs from MuJoCo's by at most {worst:.1e} m over 200 poses"
                    )
                print(run(f"placo, {goal}", solver, model, targets, full))
        except ImportError:
            lines.append(
                "placo: not installed (pip install placo in the bench's environment); skipped"
            )
    for line in dict.fromkeys(lines):
        print(line)
    print(
        "full pose: so101sim is asked the tool frame (rotation=); position + pitch is judged "
        "on the position (the pitch is met to 1e-5°)"
    )


if __name__ == "__main__":
    main()
