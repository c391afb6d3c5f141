"""Applying an arm profile to a model at load: the servos written onto an :class:`mujoco.MjSpec`
(:func:`apply_profile`, the one place a profile is applied; :func:`apply_servo` for one joint)."""

from __future__ import annotations

import math
from typing import Any

import mujoco
import numpy as np

from ..errors import ProfileError
from ..units import JOINT_NAMES
from .loadfriction import add_load_friction
from .profiles import load_profile
from .servo import NOSLIP_ITERATIONS, ArmLike, ArmProfile, ServoParams


def delay_samples(delay_s: float, timestep: float) -> int:
    """History samples an actuator needs to delay its control by ``delay_s`` at ``timestep``."""
    return math.ceil(delay_s / timestep - 1e-9) + 2


def apply_servo(
    spec: mujoco.MjSpec, joint: str, actuator: Any, params: ServoParams, timestep: float
) -> None:
    """Write ``params`` onto ``joint`` (a joint name in ``spec``) and ``actuator`` (an
    ``MjsActuator`` driving it): a position actuator with ``kp``, ``kv``, ``forcerange``,
    ``delay``; the joint's damping, frictionloss and armature."""
    j = spec.joint(joint)
    j.damping = [params.joint_damping, 0.0, 0.0]  # MuJoCo 4: [linear, polynomial terms]
    j.frictionloss = params.joint_frictionloss
    j.armature = params.armature
    kp = params.kp
    if params.max_velocity > 0:  # a slew-limited goal: MuJoCo 4's PID actuator, P only
        if params.smoothing_s > 0:
            raise ProfileError("smoothing_s and max_velocity cannot be combined; expected one")
        actuator.set_to_pid(kp, 0.0, -1, -1, -1, params.max_velocity, 0, 1)  # position input only
        actuator.biasprm = np.r_[-kp * params.offset, -kp, -params.kv, np.zeros(7)]
        actuator.forcelimited = mujoco.mjtLimited.mjLIMITED_TRUE
        actuator.forcerange = np.array([-params.force_limit, params.force_limit])
        _set_delay(actuator, params, timestep)
        return
    if params.smoothing_s > 0:  # the goal through a first-order filter (<position timeconst>)
        actuator.dyntype = mujoco.mjtDyn.mjDYN_FILTEREXACT
        actuator.dynprm = np.r_[params.smoothing_s, np.zeros(9)]
    else:
        actuator.dyntype = mujoco.mjtDyn.mjDYN_NONE
    actuator.gaintype = mujoco.mjtGain.mjGAIN_FIXED
    actuator.biastype = mujoco.mjtBias.mjBIAS_AFFINE
    actuator.gainprm = np.r_[kp, np.zeros(9)]
    actuator.biasprm = np.r_[-kp * params.offset, -kp, -params.kv, np.zeros(7)]
    actuator.forcelimited = mujoco.mjtLimited.mjLIMITED_TRUE
    actuator.forcerange = np.array([-params.force_limit, params.force_limit])
    _set_delay(actuator, params, timestep)


def _set_delay(actuator: Any, params: ServoParams, timestep: float) -> None:
    if params.delay_s > 0:
        actuator.delay = params.delay_s
        actuator.nsample = delay_samples(params.delay_s, timestep)
        actuator.interp = 1  # linear between the per-step samples (smooth in the delay)
    else:
        actuator.delay = 0.0
        actuator.nsample = 0


def apply_profile(spec: mujoco.MjSpec, profile: ArmLike) -> ArmProfile:
    """Apply ``profile`` to every SO-101 joint of ``spec`` and the actuator driving it; returns
    the profile. Joints the spec lacks are skipped (a scene may hold only part of the arm)."""
    prof = load_profile(profile)
    by_joint = {a.target: a for a in spec.actuators}
    timestep = float(spec.option.timestep)
    names = {j.name for j in spec.joints}
    if prof.static_friction:  # Coulomb friction that holds (no creep under a steady load)
        spec.option.noslip_iterations = max(spec.option.noslip_iterations, NOSLIP_ITERATIONS)
    driven = [n for n in JOINT_NAMES if n in names and n in by_joint]
    for name in driven:
        apply_servo(spec, name, by_joint[name], prof.joint(name), timestep)
    loads = {n: prof.joint(n).load_friction for n in driven}
    if any(k > 0 for k in loads.values()):  # friction that grows with the servo's torque
        add_load_friction(spec, loads)
    return prof
