"""The servo bench: one STS3215 swinging a light arm with a point mass, in MuJoCo.

:class:`ServoBench` is the rig of the public STS3215 data set (kscalelabs/sysid: a servo with a
horizontal axis, an aluminium arm of ``length`` m, a point mass at its end, gravity). Its
actuator is made by the same code as the arm's (:func:`so101sim.model.arm.apply_servo`), from
the same profile, so whatever the bench says of a profile holds for the arm.

:class:`BenchBatch` puts many benches in one MuJoCo model (independent pendulums, no contacts),
so a whole data set of runs is simulated in one pass: about a microsecond per pendulum-step.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, replace

import mujoco
import numpy as np

from ..errors import SettingError
from ..model.arm import (
    ArmLike,
    ArmProfile,
    ServoParams,
    apply_servo,
    fill_delay_history,
    load_profile,
)
from ..model.build import build, made_recipe
from ..model.loadfriction import add_load_friction, write_load_friction
from ..model.servo import NOSLIP_ITERATIONS
from ..sim.stepping import advance_unobserved, state_size
from ..validation import check_count, check_range

__all__ = ["BENCH_SUPPLY_V", "BenchBatch", "BenchRig", "ServoBench", "arm_mass_for"]

BENCH_SUPPLY_V = 12.0
"""The bench's servo: the 12 V STS3215 (its supply read 11.9 V during the runs)."""

TIMESTEP = 0.0025
"""The bench's physics step, s (the runs are sampled every 5 ms: two steps a sample)."""

_ADVICE = "expected a servo profile within its bounds (the bench diverged)"
MAX_PENDULUMS = 5000
MAX_SAMPLES = 200_000


def arm_mass_for(length: float) -> float:
    """The bench arm's own mass (kg) for an arm of ``length`` m: 0.036 kg at 0.10 m and
    0.050 kg at 0.15 m (the data set's rig), linear in between and beyond."""
    return max(0.0, 0.036 + (length - 0.10) * 0.28)


@dataclass(frozen=True)
class BenchRig:
    """One pendulum: point ``mass`` (kg) at ``length`` (m), the arm's own ``arm_mass`` (kg),
    driven with firmware P gain ``firmware_kp``."""

    mass: float
    length: float
    firmware_kp: float = 16.0
    arm_mass: float | None = None

    def checked(self) -> BenchRig:
        mass = check_range(self.mass, "mass", low=0.0, high=20.0, unit=" kg")
        length = check_range(self.length, "length", low=0.0, high=2.0, low_open=True, unit=" m")
        kp = check_range(self.firmware_kp, "firmware_kp", low=0.0, high=255.0)
        arm = arm_mass_for(length) if self.arm_mass is None else self.arm_mass
        arm = check_range(arm, "arm_mass", low=0.0, high=20.0, unit=" kg")
        return BenchRig(mass, length, kp, arm)


def bench_servo(profile: ArmProfile, firmware_kp: float) -> ServoParams:
    """The profile's servo as the bench drives it: at the bench's supply, firmware P
    ``firmware_kp``, the full torque (no per-joint limit), no calibration offset."""
    p = profile.with_supply(BENCH_SUPPLY_V) if profile.scale_with_supply else profile
    s = p.joint("__bench__")  # the common servo, scaled to the bench's supply
    return replace(s, firmware_p=float(firmware_kp), torque_scale=1.0, offset=0.0)


class BenchBatch:
    """Many bench rigs in one model, simulated together.

    ``rigs``: the pendulums; ``arm``: the profile (name, path or :class:`ArmProfile`).
    ``max_delay_s`` sizes the actuators' history so :meth:`set_servo` may change the delay
    without rebuilding.
    """

    def __init__(
        self,
        rigs: Sequence[BenchRig],
        arm: ArmLike = None,
        *,
        max_delay_s: float | None = None,
        timestep: float = TIMESTEP,
        slew: bool = False,
    ) -> None:
        check_count(len(rigs), "number of bench rigs", minimum=1, maximum=MAX_PENDULUMS)
        self.rigs = [r.checked() for r in rigs]
        self.profile = load_profile(arm)
        self.timestep = check_range(timestep, "timestep", low=1e-5, high=0.01, unit=" s")
        spec = mujoco.MjSpec()
        spec.option.timestep = self.timestep
        spec.option.gravity = [0.0, 0.0, -9.81]
        spec.modelname = "servo_bench"
        servos = [bench_servo(self.profile, r.firmware_kp) for r in self.rigs]
        self.slew = slew or any(s.max_velocity > 0 for s in servos)
        hist = max_delay_s if max_delay_s is not None else max(s.delay_s for s in servos)
        hist = check_range(hist, "max_delay_s", low=0.0, high=0.5, unit=" s")
        for i, rig in enumerate(self.rigs):
            m, a, length = rig.mass, rig.arm_mass or 0.0, rig.length
            total = max(m + a, 1e-6)
            com = -(m * length + a * length / 2) / total
            inertia = m * length**2 + a * length**2 / 3  # about the axis
            icom = max(inertia - total * com**2, 1e-9)
            body = spec.worldbody.add_body(name=f"arm{i}", pos=[0.0, 0.3 * i, 0.5])
            body.mass = total
            body.ipos = [0.0, 0.0, com]
            body.inertia = [icom, icom, icom]
            body.explicitinertial = True
            body.add_joint(name=f"servo{i}", type=mujoco.mjtJoint.mjJNT_HINGE, axis=[0, 1, 0])
            act = spec.add_actuator(name=f"servo{i}", target=f"servo{i}")
            act.trntype = mujoco.mjtTrn.mjTRN_JOINT
            delayed = replace(servos[i], delay_s=max(hist, servos[i].delay_s))
            if self.slew:  # every pendulum slew-limited (a huge limit: none), to refit it
                delayed = replace(delayed, max_velocity=delayed.max_velocity or 1e3)
            apply_servo(spec, f"servo{i}", act, delayed, self.timestep)
        if self.profile.static_friction:  # as apply_profile does for the arm
            spec.option.noslip_iterations = NOSLIP_ITERATIONS
        # a load-friction slot per pendulum (0: none), its coefficient written by set_servo
        add_load_friction(spec, {f"servo{i}": 0.0 for i in range(len(self.rigs))})
        # the model builder compiles it (a model made by code: built each time, never cached)
        self.model = build(made_recipe("servo bench", lambda: spec, arm=self.profile))
        self.data = mujoco.MjData(self.model)
        self.servos = servos
        self.set_servo(servos)

    @property
    def size(self) -> int:
        return len(self.rigs)

    def set_servo(self, servos: Sequence[ServoParams]) -> None:
        """Change every pendulum's servo in place (the delay up to the history's reach)."""
        m = self.model
        reach = np.maximum(m.actuator_history[:, 0] - 2, 0) * self.timestep
        for i, s in enumerate(servos):
            if s.delay_s > reach[i] + 1e-12:
                raise SettingError(
                    f"delay_s = {s.delay_s} s is beyond the bench's history "
                    f"({reach[i]:.4f} s); expected a delay <= max_delay_s"
                )
        self.servos = list(servos)
        kp = np.array([s.kp for s in servos])
        self._gain = np.zeros_like(kp) if self.slew else kp
        self._bias = np.stack(
            [-kp * np.array([s.offset for s in servos]), -kp, -np.array([s.kv for s in servos])],
            axis=1,
        )
        self._damp_on = np.array([s.joint_damping for s in servos])
        self._damp_off = np.array([s.viscous for s in servos])
        self._fric_on = np.array([s.joint_frictionloss for s in servos])
        self._fric_off = np.array([s.frictionloss for s in servos])
        m.actuator_forcerange[:, 0] = [-s.force_limit for s in servos]
        m.actuator_forcerange[:, 1] = [s.force_limit for s in servos]
        m.dof_armature[:] = [s.armature for s in servos]
        for i, s in enumerate(servos):
            write_load_friction(m, int(m.jnt_dofadr[i]), s.load_friction)
        m.actuator_delay[:] = [s.delay_s for s in servos]
        if self.slew:
            m.actuator_dynprm[:, 1] = [s.max_velocity or 1e3 for s in servos]
        self._set_enabled(np.ones(self.size, dtype=bool))

    def _set_enabled(self, on: np.ndarray) -> None:
        m = self.model
        m.actuator_gainprm[:, 0] = np.where(on, self._gain, 0.0)
        m.actuator_biasprm[:, :3] = np.where(on[:, None], self._bias, 0.0)
        m.dof_damping[:] = np.where(on, self._damp_on, self._damp_off)
        m.dof_frictionloss[:] = np.where(on, self._fric_on, self._fric_off)
        self._enabled = on.copy()

    def simulate(
        self,
        period: float,
        goals: np.ndarray,
        initial: np.ndarray,
        torque_enabled: np.ndarray | None = None,
    ) -> np.ndarray:
        """Positions (rad), shape ``(n, T)``, at the sample times ``k * period`` of each
        pendulum driven with ``goals`` (rad, ``(n, T)``; goal ``k`` is written at sample ``k``)
        from rest at ``initial`` (rad, ``(n,)``). ``torque_enabled`` (bool ``(n, T)``): where
        False the servo lets go (no drive, no back-EMF, no drive friction;
        the mechanical friction stays)."""
        goals = np.asarray(goals, dtype=float)
        n, t = goals.shape if goals.ndim == 2 else (0, 0)
        if n != self.size:
            raise SettingError(f"goals have shape {goals.shape}; expected ({self.size}, T)")
        check_count(t, "number of samples", minimum=1, maximum=MAX_SAMPLES)
        period = check_range(period, "period", low=self.timestep / 2, high=1.0, unit=" s")
        sub = max(1, round(period / self.timestep))
        en = (
            np.ones((n, t), dtype=bool)
            if torque_enabled is None
            else np.asarray(torque_enabled, dtype=bool).reshape(n, t)
        )
        m, d = self.model, self.data
        mujoco.mj_resetData(m, d)
        d.qpos[:] = np.asarray(initial, dtype=float).reshape(n)
        d.ctrl[:] = goals[:, 0]
        self._set_enabled(en[:, 0])
        mujoco.mj_forward(m, d)
        fill_delay_history(m, d)
        out = np.empty((n, t))
        scratch = np.empty(state_size(m))
        last = en[:, 0]
        for k in range(t):
            out[:, k] = d.qpos
            d.ctrl[:] = goals[:, k]
            if not np.array_equal(en[:, k], last):
                last = en[:, k]
                self._set_enabled(last)
            advance_unobserved(m, d, None, sub, self.timestep, scratch, advice=_ADVICE)
        if not np.isfinite(out).all():
            raise SettingError("the bench simulation diverged; expected finite servo values")
        return out


class ServoBench:
    """One servo on the pendulum bench.

    >>> bench = ServoBench(mass=0.535, length=0.15, firmware_kp=16, arm="sts3215")
    >>> q = bench.simulate(times, goals, initial=0.0)   # predicted positions, rad
    """

    def __init__(
        self,
        mass: float,
        length: float,
        firmware_kp: float = 16,
        arm: ArmLike = None,
        *,
        arm_mass: float | None = None,
    ) -> None:
        self.rig = BenchRig(mass, length, firmware_kp, arm_mass).checked()
        self._batch = BenchBatch([self.rig], arm)
        self.profile = self._batch.profile
        self.model = self._batch.model

    @property
    def servo(self) -> ServoParams:
        """The servo the bench drives (the profile's, at 12 V and this P gain)."""
        return self._batch.servos[0]

    def simulate(
        self,
        times: Sequence[float] | np.ndarray,
        goals: Sequence[float] | np.ndarray,
        initial: float = 0.0,
        torque_enabled: Sequence[bool] | np.ndarray | None = None,
    ) -> np.ndarray:
        """Predicted positions (rad) at ``times`` (s, evenly spaced) with goal ``goals[k]``
        written at ``times[k]``, from rest at ``initial`` (rad). ``torque_enabled``: one bool
        per sample; False lets the servo go (no actuator force; friction stays)."""
        t = np.asarray(times, dtype=float).ravel()
        g = np.asarray(goals, dtype=float).ravel()
        if len(t) != len(g) or len(t) < 1:
            raise SettingError(
                f"times ({len(t)}) and goals ({len(g)}) differ in length; expected one goal "
                "per sample time"
            )
        check_count(len(t), "number of samples", minimum=1, maximum=MAX_SAMPLES)
        if not np.isfinite(t).all() or not np.isfinite(g).all():
            raise SettingError("times and goals must be finite numbers (s, rad)")
        period = float(np.median(np.diff(t))) if len(t) > 1 else TIMESTEP
        if len(t) > 1 and (period <= 0 or np.abs(np.diff(t) - period).max() > 0.1 * period):
            raise SettingError("times must be evenly spaced and increasing; expected a fixed rate")
        initial = check_range(initial, "initial", low=-10.0, high=10.0, unit=" rad")
        en = None if torque_enabled is None else np.asarray(torque_enabled, dtype=bool)[None, :]
        if en is not None and en.shape[1] != len(t):
            raise SettingError(
                f"torque_enabled has {en.shape[1]} values; expected one per sample ({len(t)})"
            )
        return self._batch.simulate(period, g[None, :], np.array([initial]), en)[0]
