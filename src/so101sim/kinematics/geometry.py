"""The arm as a textbook chain: a vertical pan axis, then three parallel pitch axes (shoulder
lift, elbow, wrist flex) working in one vertical plane, then the wrist roll along the tool.

:func:`planar_arm` reads the chain's numbers from the model at the zero pose (nothing is typed
in by hand); :func:`closed_form` solves the geometry in closed form for a tip position, a
pitch and a wrist roll: the pan that turns the arm's plane onto the target, then the classic
two-link triangle for the shoulder and elbow, then the wrist flex that gives the pitch. Up to
four answers (reaching forward or back over the base, elbow up or down). IK uses them as
starting points, so that damped least squares, which also handles what the planar picture
leaves out, needs only a couple of iterations.
"""

from __future__ import annotations

import math
import weakref
from dataclasses import dataclass

import mujoco
import numpy as np

from .core import N_BODY, Kinematics, for_model

_PARALLEL = 1e-9  # how far from parallel/vertical the axes may be for the planar picture


@dataclass(frozen=True)
class PlanarArm:
    """The chain's numbers at the zero pose, in the base frame (metres, radians).

    In the arm's plane (x forward, z up at ``shoulder_pan = 0``) each pitch joint turns the
    links after it by ``-sign * angle`` (a positive ``shoulder_lift`` tilts the arm forward
    and down). The tip lies off the wrist-roll axis, so at the zero pose it circles that axis
    as the wrist rolls: ``tip(r) = tip_center + cos(r) * tip_cos + sin(r) * tip_sin``.
    """

    pan_point: tuple[float, float]  # (x, y) of the pan axis
    pan_sign: float  # +1 if the pan axis points up, -1 if down: yaw = pan_sign * pan
    shoulder: tuple[float, float]  # (x, z) of the shoulder_lift axis
    signs: tuple[float, float, float]  # +1/-1: lift, elbow, flex axes along +y or -y
    upper: tuple[float, float]  # shoulder -> elbow: length, angle above horizontal
    fore: tuple[float, float]  # elbow -> wrist flex: length, angle above horizontal
    wrist: tuple[float, float]  # (x, z) of the wrist_flex axis
    pitch0: float  # the tool's pitch at the zero pose
    tip_center: np.ndarray  # (3,)
    tip_cos: np.ndarray  # (3,)
    tip_sin: np.ndarray  # (3,)

    def tip_at_zero(self, wrist_roll: float) -> np.ndarray:
        """The tip at the zero pose but for ``wrist_roll`` (radians)."""
        return (
            self.tip_center
            + math.cos(wrist_roll) * self.tip_cos
            + math.sin(wrist_roll) * self.tip_sin
        )

    def rolls_for_lateral(self, lateral: float) -> list[float]:
        """The wrist rolls that put the tip ``lateral`` metres left of the pan axis' plane."""
        r = math.hypot(self.tip_cos[1], self.tip_sin[1])
        rhs = lateral + self.pan_point[1] - self.tip_center[1]
        if r < 1e-12 or abs(rhs) > r:
            return []
        phi = math.atan2(self.tip_sin[1], self.tip_cos[1])
        return [_wrap(phi + math.acos(rhs / r)), _wrap(phi - math.acos(rhs / r))]


def planar_arm(model: mujoco.MjModel | None = None) -> PlanarArm | None:
    """The chain's numbers (link lengths, angles, axes) read from ``model`` (the shipped one
    if None), or None if its axes are not arranged as the SO-101's (a vertical pan, three
    parallel horizontal pitch axes across the plane)."""
    kin = for_model(model)
    with kin.lock:
        return planar_arm_of(kin)


def _read_planar_arm(kin: Kinematics) -> PlanarArm | None:
    axes = kin.zero_frame_axes()
    (_, pan_p, pan_a), (_, s, sa), (_, e, ea), (_, w, wa), _roll = axes
    if abs(abs(pan_a[2]) - 1.0) > _PARALLEL:
        return None
    if any(abs(abs(a[1]) - 1.0) > _PARALLEL for a in (sa, ea, wa)):
        return None
    up, fore = e - s, w - e
    t0 = kin.frame_at(np.zeros(N_BODY)).position
    t90 = kin.frame_at(np.array([0.0, 0.0, 0.0, 0.0, math.pi / 2])).position
    t180 = kin.frame_at(np.array([0.0, 0.0, 0.0, 0.0, math.pi])).position
    center = (t0 + t180) / 2.0
    return PlanarArm(
        pan_point=(float(pan_p[0]), float(pan_p[1])),
        pan_sign=float(np.sign(pan_a[2])),
        shoulder=(float(s[0]), float(s[2])),
        signs=(float(np.sign(sa[1])), float(np.sign(ea[1])), float(np.sign(wa[1]))),
        upper=(math.hypot(up[0], up[2]), math.atan2(up[2], up[0])),
        fore=(math.hypot(fore[0], fore[2]), math.atan2(fore[2], fore[0])),
        wrist=(float(w[0]), float(w[2])),
        pitch0=kin.frame_at(np.zeros(N_BODY)).pitch,
        tip_center=center,
        tip_cos=t0 - center,
        tip_sin=t90 - center,
    )


_arms: weakref.WeakKeyDictionary[Kinematics, PlanarArm | None] = weakref.WeakKeyDictionary()


def planar_arm_of(kin: Kinematics) -> PlanarArm | None:
    """:func:`planar_arm` of ``kin``, computed once; call with ``kin.lock`` held."""
    if kin not in _arms:
        _arms[kin] = _read_planar_arm(kin)
    return _arms[kin]


def _wrap(angle: float) -> float:
    return (angle + math.pi) % (2.0 * math.pi) - math.pi


def _in_plane(arm: PlanarArm, x: float, z: float, pitch: float) -> list[tuple[float, ...]]:
    """(lift, elbow, flex) putting the wrist flex axis at (x, z) in the plane, the tool at
    ``pitch``: the two-link triangle, elbow one way and the other."""
    sx, sz = arm.shoulder
    la, aa = arm.upper
    lb, ab = arm.fore
    dx, dz = x - sx, z - sz
    c = (dx * dx + dz * dz - la * la - lb * lb) / (2.0 * la * lb)
    if abs(c) > 1.0:
        return []
    out = []
    for gamma in (math.acos(c), -math.acos(c)):
        a1 = math.atan2(dz, dx) - math.atan2(lb * math.sin(gamma), la + lb * math.cos(gamma)) - aa
        a2 = gamma + aa - ab
        a3 = pitch - arm.pitch0 - a1 - a2
        s1, s2, s3 = arm.signs
        out.append((_wrap(-a1 / s1), _wrap(-a2 / s2), _wrap(-a3 / s3)))
    return out


def closed_form(
    arm: PlanarArm, target: np.ndarray, pitch: float, wrist_roll: float
) -> list[np.ndarray]:
    """Joint angles (radians, five body joints) that put the tip at ``target`` with ``pitch``
    and ``wrist_roll``, in closed form: up to four (reaching forward or back, elbow one way or
    the other); joint limits are not applied. Empty if the triangle has no answer."""
    tip0 = arm.tip_at_zero(wrist_roll)
    px, py = arm.pan_point
    lateral = float(tip0[1]) - py  # the tip's offset across the plane (the jaw's side)
    vx, vz = float(tip0[0]) - arm.wrist[0], float(tip0[2]) - arm.wrist[1]
    dx, dy = float(target[0]) - px, float(target[1]) - py
    rho2 = dx * dx + dy * dy - lateral * lateral
    if rho2 < 0.0:
        return []
    alpha = pitch - arm.pitch0  # the tool's turn in the plane from the zero pose
    wx = vx * math.cos(alpha) - vz * math.sin(alpha)
    wz = vx * math.sin(alpha) + vz * math.cos(alpha)
    out = []
    for reach in (math.sqrt(rho2), -math.sqrt(rho2)):  # forward, or back over the base
        pan = _wrap((math.atan2(dy, dx) - math.atan2(lateral, reach)) / arm.pan_sign)
        for lift, elbow, flex in _in_plane(arm, px + reach - wx, float(target[2]) - wz, pitch):
            out.append(np.array([pan, lift, elbow, flex, wrist_roll]))
    return out
