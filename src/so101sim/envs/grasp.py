"""Measuring grasps: does the SO-101's gripper, closing on a cube, lift it and hold it without
slipping, without the cube jumping or sinking into the table, and without parts passing into
each other? And does a cube left on the table stay put?

:func:`grasp_trial` runs one top-down pick at a placement (approach, descend, close, lift) and
then holds the cube up for a while, measuring:

* ``slip_mm``: how far the cube moved relative to the gripper during the hold;
* ``penetration_mm``: the deepest overlap of the cube with anything (jaw pads, table), over
  the whole trial, sampled every physics step;
* ``disturbed_mm``: how far the cube moved before the jaws closed (the fingers must not push
  it away as they come down);
* ``lifted_mm``: how high the cube's centre rose.

:func:`rest_trial` leaves a cube on the table and measures its drift and sinking.
:func:`grasp_trials` draws placements from a seed as the ``pick_cube`` preset does. The bench
(``bench/bench_envs.py``) runs 50 placements; the tests run a smaller sample with the same
thresholds (:data:`GRASP_LIMITS`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import mujoco
import numpy as np

from ..model.arm import ArmLike, gripper_full_range, load_profile
from ..model.load import arm_index
from ..robot.config import GRIPPER_TORQUE_FRACTION
from ..scenes import (
    ContactSettings,
    SceneObject,
    TableScene,
    build_scene,
    object_pose,
    preset_scene,
    sample_placements,
)
from ..sim.simulation import Observer, Simulation
from ..units import GRIPPER_INDEX
from ..validation import check_count, check_duration, check_range
from .planning import CLOSED_GRIPPER, OPEN_GRIPPER, ThroughSag, top_grasp

GRASP_LIMITS = {"slip_mm": 5.0, "penetration_mm": 1.0, "disturbed_mm": 1.0, "lifted_mm": 30.0}
"""What a good grasp keeps to: slip and penetration at most, disturbance at most, lift at
least (millimetres)."""
REST_LIMITS = {"drift_mm": 1.0, "sink_mm": 1.0}
"""What a cube left on the table keeps to (millimetres)."""
GRASP_Z_M = 0.009
"""The tip's height when the jaws close on a 2.5 cm cube (the fixed jaw's end then clears the
table by about 3 mm)."""
LIFT_Z_M = 0.055
"""The tip's height after the lift (a top-down tool reaches this high over most of the
table)."""
CUBE_SIZE_M = 0.025


@dataclass(frozen=True)
class GraspTrial:
    """One measured pick: where the cube stood, and what happened (see the module's text)."""

    x: float
    y: float
    yaw: float
    mass: float
    lifted_mm: float
    slip_mm: float
    penetration_mm: float
    disturbed_mm: float

    @property
    def ok(self) -> bool:
        """Whether every figure is within :data:`GRASP_LIMITS`."""
        lim = GRASP_LIMITS
        return (
            self.lifted_mm >= lim["lifted_mm"]
            and self.slip_mm <= lim["slip_mm"]
            and self.penetration_mm <= lim["penetration_mm"]
            and self.disturbed_mm <= lim["disturbed_mm"]
        )


@dataclass(frozen=True)
class RestTrial:
    """A cube left on the table: the farthest it drifted sideways and sank or rose (mm) at
    any time, and how much it turned by the end (degrees)."""

    drift_mm: float
    sink_mm: float
    turn_deg: float

    @property
    def ok(self) -> bool:
        return self.drift_mm <= REST_LIMITS["drift_mm"] and self.sink_mm <= REST_LIMITS["sink_mm"]


class ContactWatch(Observer):
    """Every physics step, the deepest overlap (metres) of ``body``'s geoms with anything."""

    def __init__(self, model: mujoco.MjModel, body: str) -> None:
        bid = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, body)
        self.geoms = set(np.flatnonzero(model.geom_bodyid == bid).tolist())
        self.deepest = 0.0
        self._next = -math.inf
        self._dt = float(model.opt.timestep)

    def next_time(self) -> float:
        return self._next

    def on_time(self, m: mujoco.MjModel, d: mujoco.MjData) -> bool:
        self.deepest = max(self.deepest, deepest_contact(d, self.geoms))
        self._next = d.time + self._dt * 0.5
        return True


def deepest_contact(d: mujoco.MjData, geoms: set[int]) -> float:
    """The deepest overlap (metres, >= 0) of a contact involving one of ``geoms``."""
    deepest = 0.0
    for i in range(d.ncon):
        c = d.contact[i]
        if c.geom1 in geoms or c.geom2 in geoms:
            deepest = max(deepest, -float(c.dist))
    return deepest


def cube_scene(
    x: float, y: float, yaw: float, mass: float, contact: ContactSettings | None = None
) -> TableScene:
    """A table with one 2.5 cm cube of ``mass`` kg at (x, y) turned by ``yaw`` degrees."""
    cube = SceneObject("cube", size=(CUBE_SIZE_M,), mass=mass, pos=(x, y), yaw=yaw)
    return TableScene(objects=(cube,), contact=contact or ContactSettings(), name="grasp")


def limit_gripper(
    model: mujoco.MjModel, fraction: float = GRIPPER_TORQUE_FRACTION, arm: ArmLike = None
) -> None:
    """Bound the gripper's force as the real gripper's torque limit does: ``fraction`` of the
    arm profile ``arm``'s gripper torque limit (LeRobot writes 50 %; None: the default
    profile, which ``model`` must have been built with)."""
    a = arm_index(model).actuator[GRIPPER_INDEX]
    model.actuator_forcerange[a] = gripper_full_range(arm) * fraction


def _relative(d: mujoco.MjData, site: int, pos: np.ndarray) -> np.ndarray:
    rot = d.site_xmat[site].reshape(3, 3)
    return rot.T @ (pos - d.site_xpos[site])


def grasp_trial(
    x: float,
    y: float,
    yaw: float = 0.0,
    mass: float = 0.03,
    *,
    hold: float = 3.0,
    contact: ContactSettings | None = None,
    torque_fraction: float = GRIPPER_TORQUE_FRACTION,
    arm: ArmLike = None,
) -> GraspTrial:
    """Pick a 2.5 cm cube of ``mass`` kg standing at (x, y), turned ``yaw`` degrees, hold it
    up for ``hold`` s and measure it (see the module's text)."""
    hold = check_duration(hold, "hold", maximum=600.0)
    check_range(mass, "mass", low=0.001, high=1.0, unit=" kg")
    profile = load_profile(arm)  # type: ignore[arg-type]
    model = build_scene(cube_scene(x, y, yaw, mass, contact), arm=profile)
    limit_gripper(model, torque_fraction, profile)
    sim = Simulation(model)
    watch = ContactWatch(model, "cube")
    sim.observers.append(watch)
    start = object_pose(model, sim.data, "cube")[:3]
    sim.command({"gripper": OPEN_GRIPPER})
    grasp = top_grasp(model, start[:2], yaw, CUBE_SIZE_M, GRASP_Z_M, sim.commanded_array())
    above = grasp.at_height(0.07)
    sim.move_to(
        tip=above, pitch=-90, roll=grasp.roll, duration=1.5, path="joint", shape="minimum_jerk"
    )
    sim.move_to(tip=grasp.position, pitch=-90, roll=grasp.roll, duration=1.0, shape="minimum_jerk")
    sim.hold(0.1)
    disturbed = np.linalg.norm(object_pose(model, sim.data, "cube")[:3] - start)
    sim.move_to({**sim.commanded(), "gripper": CLOSED_GRIPPER}, 0.5)
    sim.hold(0.2)
    # the lift, commanded through the servos' sag (as the experts do): the default arm (a real
    # STS3215 at P = 16) would hold the cube a centimetre below the planned height
    _, rows = sim.plan_tip_move(
        grasp.at_height(LIFT_Z_M), 1.0, pitch=-90, roll=grasp.roll, shape="minimum_jerk"
    )
    aim = ThroughSag(model)
    sim.advance(np.array([aim(row) for row in rows]), keep_trace=False)
    sim.hold(0.2)
    site = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_SITE, "gripperframe")
    held0 = _relative(sim.data, site, object_pose(model, sim.data, "cube")[:3])
    slip = _SlipWatch(site, held0, model)
    sim.hold(hold, observers=[slip])
    lifted = object_pose(model, sim.data, "cube")[2] - start[2]
    return GraspTrial(
        x=x,
        y=y,
        yaw=yaw,
        mass=mass,
        lifted_mm=1000 * float(lifted),
        slip_mm=1000 * slip.worst,
        penetration_mm=1000 * watch.deepest,
        disturbed_mm=1000 * float(disturbed),
    )


class _SlipWatch(Observer):
    """The largest distance of the cube from where it was held, in the gripper's frame."""

    def __init__(self, site: int, held: np.ndarray, model: mujoco.MjModel) -> None:
        self.site, self.held, self.worst = site, held, 0.0
        self._q = slice(int(model.jnt_qposadr[_free_joint(model, "cube")]), None)
        self._next = -math.inf
        self._period = 0.01

    def next_time(self) -> float:
        return self._next

    def on_time(self, m: mujoco.MjModel, d: mujoco.MjData) -> bool:
        moved = _relative(d, self.site, d.qpos[self._q][:3]) - self.held
        self.worst = max(self.worst, float(np.linalg.norm(moved)))
        self._next = d.time + self._period
        return True


def _free_joint(model: mujoco.MjModel, body: str) -> int:
    return int(mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, f"{body}_joint"))


def rest_trial(
    x: float = 0.25,
    y: float = 0.0,
    yaw: float = 0.0,
    mass: float = 0.03,
    *,
    duration: float = 60.0,
    contact: ContactSettings | None = None,
    arm: ArmLike = None,
) -> RestTrial:
    """Leave a 2.5 cm cube on the table for ``duration`` s (the arm holding its rest pose) and
    measure, every 50 ms, how far it drifted sideways and up or down from where it was put."""
    duration = check_duration(duration, "duration", maximum=3600.0)
    model = build_scene(cube_scene(x, y, yaw, mass, contact), arm=arm)
    sim = Simulation(model)
    p0 = object_pose(model, sim.data, "cube")
    watch = _PoseWatch(model, p0)
    sim.hold(duration, observers=[watch])
    p1 = object_pose(model, sim.data, "cube")
    dq = abs(float(np.dot(p0[3:], p1[3:])))
    return RestTrial(
        drift_mm=1000 * watch.drift,
        sink_mm=1000 * watch.rise,
        turn_deg=math.degrees(2 * math.acos(min(1.0, dq))),
    )


class _PoseWatch(Observer):
    """The largest sideways and vertical distance of the cube from ``start``."""

    def __init__(self, model: mujoco.MjModel, start: np.ndarray) -> None:
        self._q = slice(int(model.jnt_qposadr[_free_joint(model, "cube")]), None)
        self.start, self.drift, self.rise = start, 0.0, 0.0
        self._next = -math.inf

    def next_time(self) -> float:
        return self._next

    def on_time(self, m: mujoco.MjModel, d: mujoco.MjData) -> bool:
        p = d.qpos[self._q][:3]
        self.drift = max(self.drift, float(np.linalg.norm(p[:2] - self.start[:2])))
        self.rise = max(self.rise, abs(float(p[2] - self.start[2])))
        self._next = d.time + 0.05
        return True


def sample_cube_placements(
    n: int, seed: int = 0, masses: tuple[float, float] = (0.01, 0.05)
) -> list[tuple[float, float, float, float]]:
    """``n`` placements (x, y, yaw, mass) drawn from ``seed``: positions and turns as the
    ``pick_cube`` preset draws them, masses uniform in ``masses`` (kg)."""
    n = check_count(n, "n", minimum=1, maximum=10_000)
    scene = preset_scene("pick_cube")
    rng = np.random.default_rng(seed)
    out = []
    for _ in range(n):
        x, y, yaw = sample_placements(scene.objects, rng, scene.keep_out)["cube"]
        out.append((x, y, yaw, float(rng.uniform(*masses))))
    return out


def grasp_trials(n: int, seed: int = 0, **kwargs: object) -> list[GraspTrial]:
    """:func:`grasp_trial` at ``n`` placements drawn from ``seed``
    (:func:`sample_cube_placements`)."""
    return [
        grasp_trial(x, y, yaw, mass, **kwargs)  # type: ignore[arg-type]
        for x, y, yaw, mass in sample_cube_placements(n, seed)
    ]


def default_contact() -> ContactSettings:
    """MuJoCo's own defaults for the objects' contacts (for comparison with the tuned ones)."""
    return replace(
        ContactSettings(),
        condim=3,
        solref=(0.02, 1.0),
        solimp=(0.9, 0.95, 0.001, 0.5, 2.0),
        cone="pyramidal",
        impratio=1.0,
        pad_friction=1.0,
        torsional=0.005,
    )
