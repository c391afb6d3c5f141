"""What ``so101sim check``'s step recorder reads after every step, derived after the fact from
the states the stepping kernel recorded: vectorised, a block at a time, no Python per step.

:class:`StateRecorder` is an :class:`~so101sim.sim.stepping.Observer` that asks for no call
between steps (so the kernel steps whole blocks in C) and sees each block's states
(:attr:`Trace.states <so101sim.sim.stepping.Trace>`). From them it gives what
:class:`~so101sim.preflight.measure.StepRecorder` gives, sample for sample (one sample before
the first step, one after each step), for :func:`~so101sim.preflight.measure.collect`:

* **forces**: the force each arm actuator applied during step i, from the target of step i and
  the joint angle and velocity before it, with MuJoCo's affine actuator law (``gain * ctrl +
  bias0 + bias1 * length + bias2 * velocity``, clamped to the force range), for position
  actuators on a joint (:func:`vectorisable` says when; otherwise the lab helpers watch every
  step with the step recorder, as before);
* **contacts**: the contacts of step i are those of the positions before it (MuJoCo detects
  them before it integrates). A scratch copy of the model whose margins are widened by
  :data:`SCREEN_M` tells, at one position, how far every pair of geoms is from touching; no
  point of a geom moves further in a step than the joint velocities times the longest lever
  (bounded from the model's body and geom offsets), so a position clear by a gap clears the
  steps that follow until the sum of their moves reaches half the gap. Only positions that
  may touch are tested with the model itself (``mj_kinematics`` + ``mj_collision`` on scratch
  data): the same contacts, bit for bit, as the step itself found.
"""

from __future__ import annotations

import bisect
import copy
import threading
import weakref

import mujoco
import numpy as np

from ..model.load import arm_index
from ..sim.stepping import Observer, Trace

SCREEN_M = 0.003
"""How much wider than the model's the screening copy's margins are (metres)."""

_EXACT = (
    mujoco.mjtIntegrator.mjINT_EULER,
    mujoco.mjtIntegrator.mjINT_IMPLICIT,
    mujoco.mjtIntegrator.mjINT_IMPLICITFAST,
)
"""Integrators that move the positions by ``timestep * velocity after the step``: the bound
holds as it is (times 1.01 for rounding); for the others (RK4) it is doubled."""
_SYNCED = (
    "geom_size", "geom_pos", "geom_quat", "geom_gap", "geom_contype", "geom_conaffinity",
    "geom_rbound", "geom_aabb", "body_pos", "body_quat", "body_ipos", "body_iquat",
    "jnt_pos", "jnt_axis", "pair_gap",
)  # fmt: skip
"""Model fields a user may change after load that collision detection reads: copied into the
screening model before each use, so it never goes stale."""


def vectorisable(m: mujoco.MjModel) -> bool:
    """Whether the arm's actuator forces follow from the states alone: position-style
    actuators (no activation, fixed gain, affine or no bias) on a hinge or slide joint, with
    no actuator damping, armature, delay or history, and actuation enabled."""
    act = arm_index(m).actuator
    if m.opt.disableflags & int(mujoco.mjtDisableBit.mjDSBL_ACTUATION):
        return False
    jnt = m.actuator_trnid[act, 0]
    checks = [
        (m.actuator_dyntype[act] == mujoco.mjtDyn.mjDYN_NONE).all(),
        (m.actuator_gaintype[act] == mujoco.mjtGain.mjGAIN_FIXED).all(),
        np.isin(
            m.actuator_biastype[act], [mujoco.mjtBias.mjBIAS_NONE, mujoco.mjtBias.mjBIAS_AFFINE]
        ).all(),
        (m.actuator_trntype[act] == mujoco.mjtTrn.mjTRN_JOINT).all(),
        np.isin(m.jnt_type[jnt], [mujoco.mjtJoint.mjJNT_HINGE, mujoco.mjtJoint.mjJNT_SLIDE]).all(),
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
        limited = m.actuator_ctrllimited[act].astype(bool)
        c = np.where(limited, np.clip(c, lo, hi), c)
    gain = m.actuator_gainprm[act, 0]
    prm = m.actuator_biasprm[act]
    affine = m.actuator_biastype[act] == mujoco.mjtBias.mjBIAS_AFFINE
    bias = np.where(affine, prm[:, 0] + prm[:, 1] * length + prm[:, 2] * velocity, 0.0)
    force = gain * c + bias
    limited = m.actuator_forcelimited[act].astype(bool)
    if limited.any():
        lo, hi = m.actuator_forcerange[act].T
        force = np.where(limited, np.clip(force, lo, hi), force)
    return force


class _Screen:
    """One thread's scratch copies for a model: the widened model and its data, the model's
    own scratch data, and each degree of freedom's lever (metres per radian, 1 for a slide)."""

    def __init__(self, m: mujoco.MjModel) -> None:
        self.wide = copy.copy(m)
        self.wide_data = mujoco.MjData(self.wide)
        self.data = mujoco.MjData(m)
        self.lever = _levers(m)

    def sync(self, m: mujoco.MjModel) -> None:
        w = self.wide
        for name in _SYNCED:
            getattr(w, name)[:] = getattr(m, name)
        w.geom_margin[:] = m.geom_margin + SCREEN_M
        w.pair_margin[:] = m.pair_margin + SCREEN_M
        w.opt.disableflags, w.opt.enableflags = m.opt.disableflags, m.opt.enableflags
        w.opt.o_margin = m.opt.o_margin + SCREEN_M


_local = threading.local()


def _screen(m: mujoco.MjModel) -> _Screen:
    table = getattr(_local, "screens", None)
    if table is None:
        table = _local.screens = weakref.WeakKeyDictionary()
    s = table.get(m)
    if s is None:
        s = table[m] = _Screen(m)
    s.sync(m)
    return s


def _levers(m: mujoco.MjModel) -> np.ndarray:
    """Per degree of freedom, the farthest any point of a geom it moves can be from its axis
    (a bound that holds in every configuration: the sum of the offsets down the tree)."""
    reach = np.zeros(m.nbody)  # farthest geom point below each body, from the body's origin
    for g in range(m.ngeom):
        b = m.geom_bodyid[g]
        reach[b] = max(reach[b], np.linalg.norm(m.geom_pos[g]) + m.geom_rbound[g])
    for b in range(m.nbody - 1, 0, -1):  # children come after their parents
        p = m.body_parentid[b]
        if p:
            reach[p] = max(reach[p], np.linalg.norm(m.body_pos[b]) + reach[b])
    lever = np.ones(m.nv)
    for j in range(m.njnt):
        adr, b = m.jnt_dofadr[j], m.jnt_bodyid[j]
        r = np.linalg.norm(m.jnt_pos[j]) + reach[b]
        t = m.jnt_type[j]
        if t == mujoco.mjtJoint.mjJNT_HINGE:
            lever[adr] = r
        elif t == mujoco.mjtJoint.mjJNT_BALL:
            lever[adr : adr + 3] = r
        elif t == mujoco.mjtJoint.mjJNT_FREE:
            lever[adr + 3 : adr + 6] = r
    return lever


class StateRecorder(Observer):
    """The step recorder's samples (``times``, ``forces``, ``contacts``, :meth:`effort`),
    derived from the kernel's states after each block (see the module). Only for
    :func:`vectorisable` models."""

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
        # the sample the step recorder takes before the first step: d as it is
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
        self._forces.append(actuator_forces(self.m, trace.ctrl, q_before, v_before))
        self._contacts_of(q_before, v_before, v, states[:, 0])
        self._qpos, self._qvel = q[-1].copy(), v[-1].copy()

    # -- contacts
    def _record_contacts(self, d: mujoco.MjData, t: float) -> None:
        m = self.m
        for k in range(d.ncon):
            c = d.contact[k]
            b1, b2 = int(m.geom_bodyid[c.geom[0]]), int(m.geom_bodyid[c.geom[1]])
            self.contacts.append((t, b1, b2, float(c.dist)))

    def _contacts_of(
        self, q: np.ndarray, v_before: np.ndarray, v_after: np.ndarray, times: np.ndarray
    ) -> None:
        """The contacts at each position ``q[j]`` (stamped ``times[j]``), testing with the
        model only the positions the screen cannot clear."""
        m, scr = self.m, _screen(self.m)
        speed = np.maximum(np.abs(v_before), np.abs(v_after)) @ scr.lever
        safety = 1.01 if m.opt.integrator in _EXACT else 2.0
        moved = np.concatenate([[0.0], np.cumsum(safety * self.dt * speed)]).tolist()
        top = max(float(m.geom_margin.max(initial=0.0)), float(m.pair_margin.max(initial=0.0)))
        if m.opt.enableflags & int(mujoco.mjtEnableBit.mjENBL_OVERRIDE):
            top = max(top, float(m.opt.o_margin))
        for data in (scr.wide_data, scr.data):
            data.mocap_pos[:], data.mocap_quat[:] = self._mocap
        j, k, touching = 0, len(q), False
        while j < k:
            # while touching, the next step likely touches too: no screening there
            gap = 0.0 if touching else self._gap(scr, q[j], top)
            if gap <= 0.0:  # may touch here: the model's own collision detection
                d = scr.data
                d.qpos[:] = q[j]
                mujoco.mj_kinematics(m, d)
                mujoco.mj_collision(m, d)
                self._record_contacts(d, float(times[j]))
                touching = d.ncon > 0
                j += 1
                continue
            # clear until the geoms may have closed the gap (each moves at most `moved`)
            j = max(j + 1, bisect.bisect_left(moved, moved[j] + 0.5 * gap))

    @staticmethod
    def _gap(scr: _Screen, qpos: np.ndarray, top: float) -> float:
        """How far, at ``qpos``, the closest pair of geoms is from touching (at most
        :data:`SCREEN_M`); <= 0: it may touch."""
        w, d = scr.wide, scr.wide_data
        d.qpos[:] = qpos
        mujoco.mj_kinematics(w, d)
        mujoco.mj_collision(w, d)
        if not d.ncon:
            return SCREEN_M
        return min(SCREEN_M, float(d.contact.dist[: d.ncon].min()) - top)


__all__ = ["SCREEN_M", "StateRecorder", "actuator_forces", "vectorisable"]
