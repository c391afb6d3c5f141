"""Rhoban's BAM model "M1" of a servo, simulated on the pendulum bench for comparison.

BAM (Better Actuator Models, Duclusaud & Passault, 2025) models a position servo as its
firmware's proportional law driving a DC motor, plus friction; M1 is its simplest friction:

* the firmware writes a PWM duty ``clip(P · error_gain · (goal − q), ±max_pwm)``; the motor sees
  ``duty · vin`` volts;
* the motor's torque is ``kt · V / R − kt² / R · q̇`` (back-EMF), none when torque is off;
* friction is Coulomb ``friction_base`` plus viscous ``friction_viscous · |q̇|``, as a bound on
  the torque that stops the joint within one step (so it can hold the joint still);
* the load is the bench's pendulum (point mass plus the arm's own mass, gravity acting at
  ``q + q_offset``) plus the rotor's ``armature``; explicit integration at the log's period.

The parameters are those the data's authors fitted (``friction_params/m1.json`` beside the
data set's ``processed/`` folder: ``kt``, ``R``, ``armature``, ``q_offset``,
``friction_base``, ``friction_viscous``). This is an implementation of the published model,
written here from its description, to score it in the same measure as so101sim's profiles.
"""

from __future__ import annotations

import json
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..errors import SettingError
from .bench import arm_mass_for
from .benchdata import BenchRun

__all__ = ["BamM1", "load_m1", "simulate_m1"]

GRAVITY = 9.80665


@dataclass(frozen=True)
class BamM1:
    """BAM M1's parameters, and the firmware constants of the STS3215 it drives."""

    kt: float
    R: float
    armature: float
    q_offset: float
    friction_base: float
    friction_viscous: float
    # as BAM reads it from each run's "vin" (15.0 in every run; the supply read 11.9 V)
    vin: float = 15.0
    error_gain: float = 0.16489  # duty per rad per P unit, measured by the data's authors
    max_pwm: float = 0.97


def load_m1(path: str | Path) -> BamM1:
    """M1's parameters from the authors' ``m1.json``."""
    p = Path(path).expanduser()
    try:
        raw = json.loads(p.read_text(encoding="utf-8"))
        return BamM1(
            **{
                k: float(raw[k])
                for k in ("kt", "R", "armature", "q_offset", "friction_base", "friction_viscous")
            }
        )
    except (OSError, ValueError, KeyError, TypeError) as exc:
        raise SettingError(
            f"BAM M1 parameters {str(p)!r} cannot be read ({exc}); expected the data set's "
            "friction_params/m1.json"
        ) from exc


def simulate_m1(runs: Sequence[BenchRun], m1: BamM1) -> list[np.ndarray]:
    """Each run's predicted positions (rad) under M1, all runs stepped together."""
    n = len(runs)
    t = max(len(r.t) for r in runs)
    dt = float(np.median(np.diff(runs[0].t)))
    goal = np.empty((n, t))
    en = np.empty((n, t), dtype=bool)
    for i, r in enumerate(runs):
        k = len(r.t)
        goal[i, :k], goal[i, k:] = r.goal, r.goal[-1]
        en[i, :k], en[i, k:] = r.enabled, r.enabled[-1]
    mass = np.array([r.mass for r in runs])
    length = np.array([r.length for r in runs])
    arm = np.array([arm_mass_for(r.length) for r in runs])
    kp = np.array([r.kp for r in runs])
    inertia = mass * length**2 + arm / 3 * length**2 + m1.armature
    weight = (mass + arm / 2) * GRAVITY * length
    q = np.array([r.pos[0] for r in runs], dtype=float)
    dq = np.zeros(n)
    out = np.empty((n, t))
    gain, emf = m1.kt / m1.R, m1.kt**2 / m1.R
    for k in range(t):
        out[:, k] = q
        duty = np.clip(kp * m1.error_gain * (goal[:, k] - q), -m1.max_pwm, m1.max_pwm)
        motor = np.where(en[:, k], gain * m1.vin * duty - emf * dq, 0.0)
        net = motor - weight * np.sin(q + m1.q_offset)
        stop = inertia / dt * dq + net  # the torque that would stop the joint in one step
        bound = m1.friction_base + m1.friction_viscous * np.abs(dq)
        net = net - np.sign(stop) * np.minimum(np.abs(stop), bound)
        acc = net / inertia
        dq = dq + acc * dt
        q = q + dq * dt + 0.5 * acc * dt**2
    return [out[i, : len(r.t)] for i, r in enumerate(runs)]
