"""The contact screen: the contacts the per-step recorder would record at every position of a
block, found after the block from the recorded positions, calling MuJoCo's collision
detection only where parts may touch (for :class:`~so101sim.preflight.states.StateRecorder`).

The contacts of step i are those of the positions before it (MuJoCo detects them before it
integrates). At one position, a scratch copy of the model whose margins are widened by
:data:`SCREEN_M` tells how far each pair of bodies that can touch (:func:`_body_pairs`:
MuJoCo's filters, a superset) is from touching (:func:`gaps`): the widened contacts'
distances, else at least :data:`SCREEN_M` and at least the geoms' bounding spheres' distance.
A pair's geoms move towards each other by at most each joint's travel (the recorded angles'
differences summed step by step; for ball and free joints, the velocities' bound) times a
lever bounded over every configuration from the model's offsets (the farthest geom point from
the joint's anchor; joints above both bodies move them together and do not count). So a
screened position clears the positions before and after it until some pair's bound reaches
its gap (one sorted search: the bounds are cumulative sums), and the screens leapfrog (a
screen ahead clears back towards the last one). Only positions that may touch are tested
with the model itself (``mj_kinematics`` + ``mj_collision`` on scratch data): the same
contacts, bit for bit, as the step itself found.
"""

from __future__ import annotations

import copy
import threading
import weakref

import mujoco
import numpy as np

SCREEN_M = 0.04
"""How much wider than the model's the screening copy's margins are (metres)."""
_TOLERANCE_M = 1e-5
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


def record_contacts(
    m: mujoco.MjModel, d: mujoco.MjData, t: float, out: list[tuple[float, int, int, float]]
) -> None:
    """Append ``d``'s contacts to ``out`` as ``(t, body1, body2, dist)``: what the per-step
    recorder records."""
    for k in range(d.ncon):
        c = d.contact[k]
        b1, b2 = int(m.geom_bodyid[c.geom[0]]), int(m.geom_bodyid[c.geom[1]])
        out.append((t, b1, b2, float(c.dist)))


def contacts_at(
    m: mujoco.MjModel,
    q: np.ndarray,
    v_before: np.ndarray,
    v_after: np.ndarray,
    times: np.ndarray,
    mocap: tuple[np.ndarray, np.ndarray],
    out: list[tuple[float, int, int, float]],
) -> None:
    """Append to ``out`` the contacts at each position ``q[j]`` (full ``qpos`` rows, stamped
    ``times[j]``; ``v_before``/``v_after``: the velocities before and after each step;
    ``mocap``: the mocap bodies' positions and orientations), testing with the model only
    the positions the screen cannot clear."""
    scr = _screen(m)
    for data in (scr.wide_data, scr.data):
        data.mocap_pos[:], data.mocap_quat[:] = mocap
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
        travel[1:, o] = safety * m.opt.timestep * speed
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
        gap = None if touching or not scr.usable else gaps(m, scr, q[t], top)
        if gap is None or (gap.size and gap.min() <= _TOLERANCE_M):
            if t > j:  # the position ahead may touch: screen at j instead
                hop = 0
                continue
            d = scr.data  # may touch here: the model's own collision detection
            d.qpos[:] = q[j]
            mujoco.mj_kinematics(m, d)
            mujoco.mj_collision(m, d)
            record_contacts(m, d, float(times[j]), out)
            touching = d.ncon > 0
            j, hop = j + 1, 0
            continue
        # clear from the first to the last position where no pair may have closed its gap
        at = closed[t] + offset
        end = int((np.searchsorted(ends, at + gap - _TOLERANCE_M) - first).min(initial=k))
        if t == j:
            j, hop = end, end - t
            continue
        back = np.searchsorted(ends, at - gap + _TOLERANCE_M, "right") - first
        start = int(back.max(initial=0))
        if start <= j:
            j, hop = end, end - t
        else:  # a hole between j and what t cleared: screen at j, then jump
            ahead, hop = (start, end), 0


def gaps(m: mujoco.MjModel, scr: _Screen, qpos: np.ndarray, top: float) -> np.ndarray:
    """Per body pair of :func:`_body_pairs`, how far at ``qpos`` its geoms are from
    touching (at most :data:`SCREEN_M`); <= 0: they may touch."""
    w, d = scr.wide, scr.wide_data
    d.qpos[:] = qpos
    mujoco.mj_kinematics(w, d)
    mujoco.mj_collision(w, d)
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
        bodies = m.geom_bodyid[con.geom[: d.ncon]]
        pair = scr.pair_of[bodies[:, 0], bodies[:, 1]]
        if (pair < 0).any():  # a pair the filters were thought to drop: test them all
            gap[:] = 0.0
        else:
            np.minimum.at(gap, pair, con.dist[: d.ncon] - top)
    return gap


__all__ = ["SCREEN_M", "contacts_at", "gaps", "record_contacts"]
