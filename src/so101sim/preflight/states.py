"""What ``so101sim check``'s step recorder reads after every step, derived after the fact from
the states the stepping kernel recorded: vectorised, a block at a time, no Python per step.

:class:`StateRecorder` is an :class:`~so101sim.sim.stepping.Observer` that asks for no call
between steps (so the kernel steps whole blocks in C) and sees each block's states
(:attr:`Trace.states <so101sim.sim.stepping.Trace>`). From them it gives what
:class:`~so101sim.preflight.measure.StepRecorder` gives, sample for sample (one sample before
the first step, one after each step), for :func:`~so101sim.preflight.measure.collect`:

* **forces**: the force each arm actuator applied during step i. Where the kernel stepped on
  the model's contact twin (:mod:`so101sim.model.twin`), MuJoCo's own, recorded in C by the
  twin's ``actuatorfrc`` sensors; otherwise from the target of step i and the joint angle and
  velocity before it, with MuJoCo's affine actuator law (``gain * ctrl + bias0 + bias1 *
  length + bias2 * velocity``, clamped to the force range), for position actuators on a joint
  (:func:`vectorisable` says when; otherwise the lab helpers watch every step with the step
  recorder, as before);
* **contacts**: the contacts of step i are those of the positions before it (MuJoCo detects
  them before it integrates). Where the kernel stepped on the model's contact twin
  (:mod:`so101sim.model.twin`: the model loaded from a file, with a ``contact`` sensor), it
  recorded each step's contact count in C; MuJoCo's collision detection is then called again
  only at the positions of the steps that found contacts. For any other model, the contact
  screen (:mod:`so101sim.preflight.screen`) calls it only at positions where parts may touch.
  Either way, the same contacts, bit for bit, as the step itself found.
"""

from __future__ import annotations

import weakref

import mujoco
import numpy as np

from ..model.load import arm_index
from ..model.twin import contact_twin
from ..sim.stepping import Observer, Trace
from .screen import contacts_at, record_contacts

_VECTORISABLE_FIELDS = (
    "actuator_dyntype", "actuator_gaintype", "actuator_biastype", "actuator_trntype",
    "actuator_trnid", "jnt_type", "actuator_damping", "actuator_armature",
    "actuator_dampingpoly", "actuator_delay", "actuator_history",
)  # fmt: skip
_vectorisable: weakref.WeakKeyDictionary[mujoco.MjModel, tuple[bytes, bool]] = (
    weakref.WeakKeyDictionary()
)


def vectorisable(m: mujoco.MjModel) -> bool:
    """Whether the arm's actuator forces follow from the states alone: position-style
    actuators (no activation, fixed gain, affine or no bias) on a hinge or slide joint, with
    no actuator damping, armature, delay or history, and actuation enabled (worked out again
    only when one of the fields it reads changed)."""
    key = b"".join(
        getattr(m, name).tobytes() for name in _VECTORISABLE_FIELDS if hasattr(m, name)
    ) + int(m.opt.disableflags).to_bytes(4, "little")
    known = _vectorisable.get(m)
    if known is not None and known[0] == key:
        return known[1]
    result = _vectorisable_now(m)
    _vectorisable[m] = (key, result)
    return result


def derivable(m: mujoco.MjModel) -> bool:
    """Whether :class:`StateRecorder` gives the step recorder's samples bit for bit on ``m``:
    its forces follow from the states (:func:`vectorisable`), or the kernel steps it on its
    contact twin (whose sensors record MuJoCo's own forces)."""
    return vectorisable(m) or contact_twin(m) is not None


def _vectorisable_now(m: mujoco.MjModel) -> bool:
    act = arm_index(m).actuator
    if m.opt.disableflags & int(mujoco.mjtDisableBit.mjDSBL_ACTUATION):
        return False
    jnt = m.actuator_trnid[act, 0]
    checks = [
        (m.actuator_dyntype[act] == mujoco.mjtDyn.mjDYN_NONE).all(),
        (m.actuator_gaintype[act] == mujoco.mjtGain.mjGAIN_FIXED).all(),
        all(
            b in (mujoco.mjtBias.mjBIAS_NONE, mujoco.mjtBias.mjBIAS_AFFINE)
            for b in m.actuator_biastype[act].tolist()
        ),
        (m.actuator_trntype[act] == mujoco.mjtTrn.mjTRN_JOINT).all(),
        all(
            t in (mujoco.mjtJoint.mjJNT_HINGE, mujoco.mjtJoint.mjJNT_SLIDE)
            for t in m.jnt_type[jnt].tolist()
        ),
    ]
    for name in ("actuator_damping", "actuator_armature", "actuator_dampingpoly"):
        field = getattr(m, name, None)
        checks.append(field is None or not np.any(field[act]))
    for name in ("actuator_delay", "actuator_history"):
        field = getattr(m, name, None)
        checks.append(field is None or not np.any(field[act]))
    return bool(all(checks))


def actuator_forces(
    m: mujoco.MjModel, ctrl: np.ndarray, qpos: np.ndarray, qvel: np.ndarray
) -> np.ndarray:
    """``(k, 6)``: the arm actuators' forces for the targets ``ctrl`` (``(k, 6)`` radians) at
    the full ``qpos``/``qvel`` rows before each step (MuJoCo's affine law, as
    ``mj_fwdActuation`` computes it for :func:`vectorisable` models)."""
    act = arm_index(m).actuator
    jnt = m.actuator_trnid[act, 0]
    gear = m.actuator_gear[act, 0]
    length = gear * qpos[:, m.jnt_qposadr[jnt]]
    velocity = gear * qvel[:, m.jnt_dofadr[jnt]]
    c = np.asarray(ctrl, dtype=float)
    clamp = not m.opt.disableflags & int(mujoco.mjtDisableBit.mjDSBL_CLAMPCTRL)
    if clamp and m.actuator_ctrllimited[act].any():
        lo, hi = m.actuator_ctrlrange[act].T
        lo = np.where(m.actuator_ctrllimited[act] != 0, lo, -np.inf)
        hi = np.where(m.actuator_ctrllimited[act] != 0, hi, np.inf)
        c = np.minimum(np.maximum(c, lo), hi)  # np.clip, faster
    gain = m.actuator_gainprm[act, 0]
    prm = m.actuator_biasprm[act]
    affine = m.actuator_biastype[act] == mujoco.mjtBias.mjBIAS_AFFINE
    bias = np.where(affine, prm[:, 0] + prm[:, 1] * length + prm[:, 2] * velocity, 0.0)
    force = gain * c + bias
    limited = m.actuator_forcelimited[act] != 0
    if limited.any():
        lo, hi = m.actuator_forcerange[act].T
        lo, hi = np.where(limited, lo, -np.inf), np.where(limited, hi, np.inf)
        force = np.minimum(np.maximum(force, lo), hi)
    return force


class StateRecorder(Observer):
    """The step recorder's samples (``times``, ``forces``, ``contacts``, :meth:`effort`),
    derived from the kernel's states after each block (see the module), over one segment or
    several in a row (one sample before the first, one after every step, as the step
    recorder). Only where :func:`derivable` says so."""

    wants_contact_counts = True  # the kernel's contact twin says which steps touched

    def __init__(self, m: mujoco.MjModel) -> None:
        self.m = m
        self.act = arm_index(m).actuator
        self.nq, self.nv = m.nq, m.nv
        self.dt = m.opt.timestep
        self._times: list[np.ndarray] = []
        self._forces: list[np.ndarray] = []
        self.contacts: list[tuple[float, int, int, float]] = []
        self._qpos = self._qvel = np.zeros(0)

    # -- what StepRecorder offers
    @property
    def times(self) -> np.ndarray:
        return np.concatenate(self._times) if self._times else np.zeros(0)

    @property
    def forces(self) -> np.ndarray:
        return np.vstack(self._forces) if self._forces else np.zeros((0, len(self.act)))

    def effort(self, m: mujoco.MjModel) -> np.ndarray:
        """(samples, 6): ``|actuator force|`` over the force limit, after every step."""
        return np.abs(self.forces) / np.abs(m.actuator_forcerange[self.act, 1])

    # -- the observer
    def on_start(self, m: mujoco.MjModel, d: mujoco.MjData) -> None:
        if not self._times:  # the sample the step recorder takes before the first step
            self._times.append(np.array([d.time]))
            self._forces.append(d.actuator_force[self.act][None].copy())
            self._record_contacts(d, float(d.time))
        self._qpos, self._qvel = d.qpos.copy(), d.qvel.copy()
        self._mocap = (d.mocap_pos.copy(), d.mocap_quat.copy())

    def on_steps(self, trace: Trace, phase: str) -> None:
        states = trace.states
        if states is None or not len(states):
            return
        nq, nv = self.nq, self.nv
        q = states[:, 1 : 1 + nq]
        v = states[:, 1 + nq : 1 + nq + nv]
        q_before = np.vstack([self._qpos[None], q[:-1]])
        v_before = np.vstack([self._qvel[None], v[:-1]])
        self._times.append(states[:, 0].copy())
        if trace.actuator_forces is not None:  # MuJoCo's own, recorded in C
            self._forces.append(trace.actuator_forces[:, self.act])
        else:
            self._forces.append(actuator_forces(self.m, trace.ctrl, q_before, v_before))
        if trace.contact_counts is not None:
            self._contacts_where(trace.contact_counts, q_before, states[:, 0])
        else:
            contacts_at(self.m, q_before, v_before, v, states[:, 0], self._mocap, self.contacts)
        self._qpos, self._qvel = q[-1].copy(), v[-1].copy()

    # -- contacts
    def _contacts_where(self, counts: np.ndarray, q: np.ndarray, times: np.ndarray) -> None:
        """The contacts of the steps whose count (the contact twin's) is not zero: MuJoCo's
        collision detection at the positions before them, the same contacts bit for bit."""
        steps = np.flatnonzero(counts)
        if not steps.size:
            return
        d = self._scratch()
        for i in steps.tolist():
            d.qpos[:] = q[i]
            mujoco.mj_kinematics(self.m, d)
            mujoco.mj_collision(self.m, d)
            record_contacts(self.m, d, float(times[i]), self.contacts)

    def _scratch(self) -> mujoco.MjData:
        d = getattr(self, "_data", None)
        if d is None:
            d = self._data = mujoco.MjData(self.m)
            d.mocap_pos[:], d.mocap_quat[:] = self._mocap
        return d

    def _record_contacts(self, d: mujoco.MjData, t: float) -> None:
        record_contacts(self.m, d, t, self.contacts)


__all__ = ["StateRecorder", "actuator_forces", "derivable", "vectorisable"]
