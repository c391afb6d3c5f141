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
  :data:`SCREEN_M` tells, at one position, how far each pair of bodies that can touch
  (:func:`_body_pairs`: MuJoCo's filters, a superset) is from touching: the widened
  contacts' distances, else at least :data:`SCREEN_M` and at least the geoms' bounding
  spheres' distance. A pair's geoms move towards each other by at most each joint's travel
  (the recorded angles' differences, summed step by step) times a lever bounded over every
  configuration from the model's offsets (the farthest geom point from the joint's anchor;
  joints above both bodies move them together and do not count). So a position clears the
  positions that follow until some pair's bound
  reaches its gap (the bound is symmetric: a screen ahead clears back towards the last one
  too, so the screens leapfrog). Only positions that may touch are tested with the model itself
  (``mj_kinematics`` + ``mj_collision`` on scratch data): the same contacts, bit for bit,
  as the step itself found.
"""

from __future__ import annotations

import copy
import threading
import weakref

import mujoco
import numpy as np

from ..model.load import arm_index
from ..sim.stepping import Observer, Trace

SCREEN_M = 0.04
"""How much wider than the model's the screening copy's margins are (metres)."""
_TOLERANCE_M = 1e-6
"""Metres a screened gap must exceed the geoms' possible moves by (rounding in the distances)."""

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
_LEVER_FIELDS = (
    "geom_pos", "geom_rbound", "geom_contype", "geom_conaffinity", "body_pos", "jnt_pos",
    "pair_geom1", "pair_geom2",
)  # fmt: skip
"""Model fields the body pairs and their levers come from: redone when one changes."""


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
    own scratch data, and the body pairs that can touch with their levers
    (:func:`_body_pairs`, redone when the fields they come from change)."""

    def __init__(self, m: mujoco.MjModel) -> None:
        self.wide = copy.copy(m)
        self.wide_data = mujoco.MjData(self.wide)
        self.data = mujoco.MjData(m)
        hinge = np.isin(m.jnt_type, [mujoco.mjtJoint.mjJNT_HINGE, mujoco.mjtJoint.mjJNT_SLIDE])
        self.angle_dof = m.jnt_dofadr[hinge]  # dofs whose qpos is their coordinate
        self.angle_col = m.jnt_qposadr[hinge]
        self.other_dof = np.setdiff1d(np.arange(m.nv), self.angle_dof)  # ball, free
        self._key = b""

    def sync(self, m: mujoco.MjModel) -> None:
        w = self.wide
        for name in _SYNCED:
            getattr(w, name)[:] = getattr(m, name)
        w.geom_margin[:] = m.geom_margin + SCREEN_M
        w.pair_margin[:] = m.pair_margin + SCREEN_M
        w.opt.disableflags, w.opt.enableflags = m.opt.disableflags, m.opt.enableflags
        w.opt.o_margin = m.opt.o_margin + SCREEN_M
        key = b"".join(getattr(m, name).tobytes() for name in _LEVER_FIELDS)
        key += int(m.opt.disableflags).to_bytes(4, "little")
        if key != self._key:
            self._key = key
            self.pairs, self.lever = _body_pairs(m)
            self.pair_of = np.full((m.nbody, m.nbody), -1)
            for p, (b1, b2) in enumerate(self.pairs):
                self.pair_of[b1, b2] = self.pair_of[b2, b1] = p
            geoms = np.flatnonzero((m.geom_contype != 0) | (m.geom_conaffinity != 0))
            geoms = np.union1d(geoms, np.concatenate([m.pair_geom1, m.pair_geom2])).astype(int)
            # every geom pair of every body pair, for a lower bound from bounding spheres
            on = [geoms[m.geom_bodyid[geoms] == b] for b in range(m.nbody)]
            g1, g2, gp = [], [], []
            for p, (b1, b2) in enumerate(self.pairs):
                for a in on[b1]:
                    for b in on[b2]:
                        g1.append(a), g2.append(b), gp.append(p)
            gp_ = np.array(gp, int)
            starts = np.flatnonzero(np.r_[True, gp_[1:] != gp_[:-1]]) if gp else gp_
            self.sphere = (np.array(g1, int), np.array(g2, int), starts)
            self.plane = m.geom_type[self.sphere[0]] == mujoco.mjtGeom.mjGEOM_PLANE
            # a plane on a moving body, or flexes: no bound here, every position is tested
            plane = (m.geom_type == mujoco.mjtGeom.mjGEOM_PLANE) & (m.geom_bodyid > 0)
            self.usable = not plane.any() and not getattr(m, "nflex", 0)


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


def _body_pairs(m: mujoco.MjModel) -> tuple[np.ndarray, np.ndarray]:
    """The pairs of bodies whose geoms MuJoCo may test for contact (``(P, 2)``: a superset of
    what its filters let through: contype/conaffinity, same weld, parent and child, plus the
    explicit pairs) and, per pair and degree of freedom, the lever (``(P, nv)``): how far the
    two bodies' geoms can move towards each other per radian (metre, for a slide) of that
    degree of freedom, in every configuration. Degrees of freedom above both bodies move them
    together and do not count; for the others, the lever is the distance from the joint's
    anchor down the tree to the farthest point of the body's geoms (offsets summed)."""
    col = np.flatnonzero((m.geom_contype != 0) | (m.geom_conaffinity != 0))
    reach = np.zeros(m.nbody)  # farthest collision-geom point from each body's origin
    for g in np.union1d(col, np.concatenate([m.pair_geom1, m.pair_geom2])).astype(int):
        b = m.geom_bodyid[g]
        reach[b] = max(reach[b], float(np.linalg.norm(m.geom_pos[g])) + m.geom_rbound[g])
    chain = [[b] for b in range(m.nbody)]  # each body and its ancestors, the body first
    for b in range(1, m.nbody):
        chain[b] = [b, *chain[m.body_parentid[b]]] if m.body_parentid[b] else [b, 0]
    weld = m.body_weldid
    weldparent = weld[m.body_parentid[weld]]
    filterparent = not m.opt.disableflags & int(mujoco.mjtDisableBit.mjDSBL_FILTERPARENT)
    found = set()
    for i, g1 in enumerate(col):
        for g2 in col[i + 1 :]:
            b1, b2 = sorted((int(m.geom_bodyid[g1]), int(m.geom_bodyid[g2])))
            w1, w2 = weld[b1], weld[b2]
            if w1 == w2:
                continue
            if filterparent and w1 and w2 and (w1 == weldparent[b2] or w2 == weldparent[b1]):
                continue
            if m.geom_contype[g1] & m.geom_conaffinity[g2] or (
                m.geom_contype[g2] & m.geom_conaffinity[g1]
            ):
                found.add((b1, b2))
    for k in range(m.npair):
        b1, b2 = sorted((int(m.geom_bodyid[m.pair_geom1[k]]), int(m.geom_bodyid[m.pair_geom2[k]])))
        if b1 != b2:
            found.add((b1, b2))
    pairs = np.array(sorted(found), dtype=int).reshape(-1, 2)
    lever = np.zeros((len(pairs), m.nv))
    for p, (b1, b2) in enumerate(pairs):
        for b, other in ((b1, b2), (b2, b1)):
            shared = set(chain[other])
            below = 0.0  # from the current body's origin down to b's farthest geom point
            path = chain[b]
            for n, a in enumerate(path):
                if a in shared:
                    break
                for j in range(m.body_jntadr[a], m.body_jntadr[a] + m.body_jntnum[a]):
                    _add_lever(m, lever[p], j, a, path[n - 1] if n else -1, below, reach[b])
                if n:
                    below += float(np.linalg.norm(m.body_pos[path[n - 1]]))
    return pairs, lever


def _add_lever(
    m: mujoco.MjModel, row: np.ndarray, j: int, body: int, child: int, below: float, reach: float
) -> None:
    """Add joint ``j``'s lever (on ``body``, whose ``child`` leads down to the geoms:
    ``below`` past that child's origin, then ``reach``) to ``row``."""
    anchor = m.jnt_pos[j]
    to_child = m.body_pos[child] if child >= 0 else np.zeros(3)
    r = float(np.linalg.norm(to_child - anchor)) + below + reach
    adr, t = m.jnt_dofadr[j], m.jnt_type[j]
    if t == mujoco.mjtJoint.mjJNT_HINGE:
        row[adr] += r
    elif t == mujoco.mjtJoint.mjJNT_SLIDE:
        row[adr] += 1.0
    elif t == mujoco.mjtJoint.mjJNT_BALL:
        row[adr : adr + 3] += r
    else:  # free: three translations, three rotations about the body's origin
        row[adr : adr + 3] += 1.0
        row[adr + 3 : adr + 6] += float(np.linalg.norm(to_child)) + below + reach


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
        for data in (scr.wide_data, scr.data):
            data.mocap_pos[:], data.mocap_quat[:] = self._mocap
        top = max(float(m.geom_margin.max(initial=0.0)), float(m.pair_margin.max(initial=0.0)))
        if m.opt.enableflags & int(mujoco.mjtEnableBit.mjENBL_OVERRIDE):
            top = max(top, float(m.opt.o_margin))
        # each degree of freedom's travel from each position to the next: the angles'
        # difference (hinges, slides), the velocities' bound (others), summed along the block;
        # times each pair's levers: how far a pair's geoms may have closed in, cumulated
        # (nondecreasing per pair, laid end to end with offsets: one sorted array to search)
        travel = np.zeros((len(q), m.nv))
        travel[1:, scr.angle_dof] = np.abs(np.diff(q[:, scr.angle_col], axis=0))
        if scr.other_dof.size:
            safety = 1.01 if m.opt.integrator in _EXACT else 2.0
            o = scr.other_dof
            speed = np.maximum(np.abs(v_before[:-1, o]), np.abs(v_after[:-1, o]))
            travel[1:, o] = safety * self.dt * speed
        closed = np.cumsum(travel, axis=0) @ scr.lever.T  # (k, P)
        offset = np.arange(closed.shape[1]) * (float(closed[-1].max(initial=0.0)) + 1.0)
        ends = (closed + offset).T.ravel()
        first = np.arange(closed.shape[1]) * len(q)
        k, touching = len(q), False
        j = 0  # the first position not known to be clear
        hop = 0  # how far the last screen cleared ahead of itself (0: screen at j)
        ahead: tuple[int, int] | None = None  # positions a screen ahead of j cleared
        while j < k:
            if ahead is not None and j >= ahead[0]:
                j, ahead = max(j, ahead[1]), None
                continue
            # a screen ahead of j clears positions before it too (the bound is symmetric)
            t = min(k - 1, j + (4 * hop) // 5)
            # while touching, the next step likely touches too: no screening there
            gap = None if touching or not scr.usable else self._gaps(scr, q[t], top)
            if gap is None or (gap.size and gap.min() <= _TOLERANCE_M):
                if t > j:  # the position ahead may touch: screen at j instead
                    hop = 0
                    continue
                d = scr.data  # may touch here: the model's own collision detection
                d.qpos[:] = q[j]
                mujoco.mj_kinematics(m, d)
                mujoco.mj_collision(m, d)
                self._record_contacts(d, float(times[j]))
                touching = d.ncon > 0
                j, hop = j + 1, 0
                continue
            # clear from the first to the last position where no pair may have closed its gap
            at = closed[t] + offset
            end = int((np.searchsorted(ends, at + gap - _TOLERANCE_M) - first).min(initial=k))
            if t == j:
                j, hop = end, end - t
                continue
            start = int((np.searchsorted(ends, at - gap + _TOLERANCE_M, "right") - first).max())
            if start <= j:
                j, hop = end, end - t
            else:  # a hole between j and what t cleared: screen at j, then jump
                ahead, hop = (start, end), 0

    def _gaps(self, scr: _Screen, qpos: np.ndarray, top: float) -> np.ndarray:
        """Per body pair of :func:`_body_pairs`, how far at ``qpos`` its geoms are from
        touching (at most :data:`SCREEN_M`); <= 0: they may touch."""
        w, d = scr.wide, scr.wide_data
        d.qpos[:] = qpos
        mujoco.mj_kinematics(w, d)
        mujoco.mj_collision(w, d)
        m = self.m
        # unreported pairs are at least SCREEN_M apart, and at least their bounding spheres'
        # distance (MuJoCo's own bound: a geom's points lie within geom_rbound of its centre)
        g1, g2, starts = scr.sphere
        c1, c2 = d.geom_xpos[g1], d.geom_xpos[g2]
        apart = np.linalg.norm(c1 - c2, axis=1) - m.geom_rbound[g1]
        if scr.plane.any():  # a plane (on the world): the height above it
            k = scr.plane
            normal = d.geom_xmat[g1[k]].reshape(-1, 3, 3)[:, :, 2]
            apart[k] = np.einsum("ij,ij->i", c2[k] - c1[k], normal)
        apart -= m.geom_rbound[g2]
        gap = np.full(len(scr.pairs), SCREEN_M)
        if len(starts):  # every pair has a geom pair (it was found from one)
            gap = np.maximum(np.minimum.reduceat(apart, starts) - top, SCREEN_M)
        if d.ncon:
            con = d.contact
            bodies = self.m.geom_bodyid[con.geom[: d.ncon]]
            pair = scr.pair_of[bodies[:, 0], bodies[:, 1]]
            if (pair < 0).any():  # a pair the filters were thought to drop: test them all
                gap[:] = 0.0
            else:
                np.minimum.at(gap, pair, con.dist[: d.ncon] - top)
        return gap


__all__ = ["SCREEN_M", "StateRecorder", "actuator_forces", "vectorisable"]
