"""Arm profiles: the actuator model of the SO-101's servos, named and loaded from TOML, and
applied to the model at load with :class:`mujoco.MjSpec` (the official files stay unchanged).

A profile describes one Feetech STS3215 as LeRobot drives it (firmware P = 16, I = 0, D = 32,
a goal position written every control tick), in MuJoCo's own terms:

* ``kp``: the position actuator's stiffness, ``kp_per_p`` N·m/rad per firmware P unit times
  ``firmware_p``. The servo's firmware computes a PWM duty from the position error times P; the
  duty times the supply voltage, through the motor's winding, is a torque;
* ``torque_limit``: the actuator's ``forcerange`` (the firmware's largest duty, and the stall
  torque at the supply);
* ``damping``: the motor's back-EMF, kt²/R, as *joint* damping: it brakes the joint outside the
  duty clamp (as a DC motor does), where an actuator ``kv`` would be clipped with the drive;
* ``viscous``, ``frictionloss`` (Coulomb), ``armature`` (the rotor's inertia through the
  1:345 gearbox): joint properties; ``drive_frictionloss``: Coulomb friction added while the
  servo drives (the firmware's dead zone around the goal and the gear train under the motor's
  load hold the joint; a servo with its torque off swings freer);
* ``delay_s``: the time from a goal written on the bus to the motor acting on it (and the
  position read back), MuJoCo 4's actuator ``delay`` with a history of ``nsample`` samples;
* ``max_velocity``: the fastest the firmware moves its internal goal toward the written one
  (rad/s; 0: it jumps), MuJoCo 4's PID actuator with ``slewmax`` (kp only, no I or D);
* ``smoothing_s``: the firmware's goal smoothing, as a first-order filter of that time
  constant on the delayed goal (MuJoCo's ``<position timeconst>``: ``filterexact`` dynamics);
* ``offset``: a calibration offset (rad) per joint: the servo holds ``goal - offset``;
* ``kv``: an actuator velocity gain (only the vendored model uses one).

A profile may carry an ``[uncertainty]`` table: a standard deviation (at ``measured_at_v``,
in the field's own unit) for some of :data:`UNCERTAIN_FIELDS`, e.g. a fit's standard errors.
Domain randomisation (``scenes.randomize``, family ``actuator_sigmas``) draws each joint's
servo from it (:func:`draw_servo_deltas`); it does not change the model the profile loads.

Values are given at ``measured_at_v`` volts; the profile's ``supply_v`` (7.4 V for the
standard SO-101, 12 V for the "pro" kit) scales the torque-related ones (``kp_per_p``,
``torque_limit``, ``damping``) by the ratio of the two servo versions' rated stall torques
(:data:`STALL_TORQUE_NM`). The friction, armature and delay do not depend on the supply.

Shipped profiles (``so101sim/data/arms``): ``official`` (the vendored model's values),
``sts3215`` (fitted on a real STS3215 pendulum bench at 12 V, driven at 7.4 V) and
``sts3215-12v`` (the same fit at 12 V). :func:`load_profile` takes a name or a TOML path.

This module is the profiles' public face; the work is done by one module per job: the data
and its bounds (:mod:`.servo`), loading and writing TOML (:mod:`.profiles`), applying a profile
to an ``MjSpec`` at load (:mod:`.apply`), writes into a compiled model at run time
(:mod:`.runtime`) and draws from a profile's uncertainty (:mod:`.draw`).
"""

from __future__ import annotations

from ..errors import ProfileError
from .apply import apply_profile, apply_servo, delay_samples
from .draw import draw_servo_deltas
from .profiles import (
    gripper_full_range,
    load_profile,
    profile_from_toml,
    profile_key,
    profile_names,
    profile_toml,
)
from .runtime import fill_delay_history, write_servo
from .servo import (
    MAX_SIGMAS,
    OFFICIAL,
    PROFILE_DEFAULT,
    STALL_TORQUE_NM,
    UNCERTAIN_FIELDS,
    UNCERTAIN_LIMIT,
    ArmLike,
    ArmProfile,
    ServoParams,
)

__all__ = [
    "MAX_SIGMAS",
    "OFFICIAL",
    "PROFILE_DEFAULT",
    "STALL_TORQUE_NM",
    "UNCERTAIN_FIELDS",
    "UNCERTAIN_LIMIT",
    "ArmLike",
    "ArmProfile",
    "ProfileError",
    "ServoParams",
    "apply_profile",
    "apply_servo",
    "delay_samples",
    "draw_servo_deltas",
    "fill_delay_history",
    "gripper_full_range",
    "load_profile",
    "profile_from_toml",
    "profile_key",
    "profile_names",
    "profile_toml",
    "write_servo",
]
