"""Perturbed arms: the ranges a real SO-101 may differ from the model by, sampling them, and
writing one sample into a copy of the compiled model.

A *variant* is the shipped arm with:

* a **payload** at the gripper (a point mass at the ``gripperframe`` site, folded into the
  gripper body's mass, centre of mass and inertia);
* its position servos' **kp** (the stiffness: ``-biasprm[1]``, and ``gainprm[0]`` for a plain
  position actuator; MuJoCo 4's PID actuator of the slew-limited STS3215 keeps it in the bias
  alone), **kv** and **force limit** (the profile's torque limit) scaled;
* every joint's **damping**, **friction loss** and **armature** scaled;
* a **zero offset** per joint (a calibration error): the servo drives its *reading* to the
  target, so the true joint ends up ``offset`` away from where it is told to go.

The ranges are :class:`VariantRanges` (each field's comment says where its default comes from,
and where it is a judgement call); a motion file may override them in a ``[variants]`` table
(:func:`ranges_from_table`). :func:`sample_variants` draws every parameter of every variant up
front from ``numpy.random.default_rng(seed)``, so variant ``i`` is the same whatever the number
of threads or machines that later run it. :func:`apply_variant` writes one into a model copy;
the vendored model files are never touched.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass, field, fields
from typing import Any

import mujoco
import numpy as np

from ..errors import MotionFileError, SettingError
from ..model.load import arm_index
from ..units import JOINT_NAMES
from ..validation import check_count, check_range, is_real, shown

MAX_VARIANTS = 100_000
"""The most variants one check runs (``--variants``): 100 000 lab-motion variants are about
3·10⁸ physics steps, a few minutes on 16 cores."""

SCALES = (
    "kp_scale",
    "kv_scale",
    "force_scale",
    "damping_scale",
    "frictionloss_scale",
    "armature_scale",
)
"""The per-joint scale factors, in the order they are drawn."""

PAYLOAD_SITE = "gripperframe"
"""Where the payload sits: the gripper's frame site (between the jaws)."""


@dataclass(frozen=True)
class Bound:
    """The widest range a ``[variants]`` entry may ask for, and its unit."""

    low: float
    high: float
    unit: str = ""


# name -> (widest allowed range): every user range must lie inside it
BOUNDS: dict[str, Bound] = {
    "payload_kg": Bound(0.0, 2.0, " kg"),
    "kp_scale": Bound(0.1, 10.0),
    "kv_scale": Bound(0.1, 10.0),
    "force_scale": Bound(0.1, 10.0),
    "damping_scale": Bound(0.0, 10.0),
    "frictionloss_scale": Bound(0.0, 10.0),
    "armature_scale": Bound(0.1, 10.0),
    "zero_offset_deg": Bound(0.0, 10.0, "°"),
}


@dataclass(frozen=True)
class VariantRanges:
    """Each parameter is drawn uniformly from ``[low, high]``, as a scale of the arm profile's
    own value (the default profile ``sts3215``: docs/fidelity.md).

    Where the defaults come from. Two sources of doubt: the fit's uncertainty (the standard
    errors in ``sts3215.toml``: 0.2–0.4 % for the stiffness, torque limit, back-EMF and
    armature, 2–4 % for the Coulomb friction, 0.01 ms for the delay: the bench's 240 runs pin
    that one servo down) and the spread between real servos, which is far larger and which
    no data here measures (one servo was on the bench). So the ranges are set by the spread,
    from what makes two STS3215s differ, and each says so:

    * ``payload_kg`` (0–0.2 kg): the objects the SO-101 is used with (cubes, pens, LEGO bricks,
      the objects of LeRobot's SO-101 datasets) weigh tens of grams to about 200 g; the
      STS3215's torque leaves little room above that at full reach. A judgement call.
    * ``kp_scale`` (0.8–1.2): the firmware's P is exact (LeRobot writes 16), but the torque
      per unit of duty scales with the supply voltage (a 7.4 V servo on a pack between 6.0 and
      8.4 V: 0.81–1.14×) and with the motor's torque constant (a few percent between units).
      The fit's ±0.3 % is far inside.
    * ``kv_scale`` (0.8–1.2): the actuator's velocity gain; ``sts3215`` has none (its back-EMF
      is joint damping), ``official`` has 2.731. A judgement call.
    * ``force_scale`` (0.8–1.0): the stall torque at the nominal supply; a sagging supply
      (6 V on a 7.4 V servo is 0.81×) or a warm motor gives less, never more.
    * ``damping_scale`` (0.7–1.3): for ``sts3215`` nearly all of it is back-EMF, kt²/R: the
      winding's resistance rises 0.39 %/K (a motor 40 K warm brakes 0.86× as hard) and kt
      differs by some percent between units (its square by twice that). The fit's ±0.4 % is
      far inside. (Was 0.5–2.0 when the only damping was the vendored model's viscous guess.)
    * ``frictionloss_scale`` (0.5–2.0): gearbox grease, wear and temperature change Coulomb
      friction by a factor, not by percent (judgement call; the fit's ±2–4 % is inside).
    * ``armature_scale`` (0.8–1.2): the reflected rotor inertia is set by the gear ratio and
      varies little (the fit: ±0.2 %; judgement call).
    * ``zero_offset_deg`` (±1.5°, drawn from ``[-high, high]``; ``low`` must be 0): LeRobot's
      calibration has the user place the arm at mid-range by eye; a degree or two off is
      usual (the servo's own resolution, 4096 counts a turn, is 0.09°).

    The command delay (27 ms) is not varied: it is the bus and the firmware's loop, the same
    for every servo on the arm, and the fit pins it to 0.01 ms.
    """

    payload_kg: tuple[float, float] = (0.0, 0.2)
    kp_scale: tuple[float, float] = (0.8, 1.2)
    kv_scale: tuple[float, float] = (0.8, 1.2)
    force_scale: tuple[float, float] = (0.8, 1.0)
    damping_scale: tuple[float, float] = (0.7, 1.3)
    frictionloss_scale: tuple[float, float] = (0.5, 2.0)
    armature_scale: tuple[float, float] = (0.8, 1.2)
    zero_offset_deg: tuple[float, float] = (0.0, 1.5)

    def __post_init__(self) -> None:
        for f in fields(self):
            _check_pair(f.name, getattr(self, f.name))
        if self.zero_offset_deg[0] != 0.0:
            raise SettingError(
                f"zero_offset_deg = {list(self.zero_offset_deg)}: expected [0, high] (offsets "
                "are drawn from -high to +high)"
            )


def _check_pair(name: str, value: object) -> tuple[float, float]:
    b = BOUNDS[name]
    if (
        not isinstance(value, (tuple, list))
        or len(value) != 2
        or not all(is_real(v) for v in value)
    ):
        raise SettingError(
            f"{name} = {shown(value)}; expected [low, high], two numbers within "
            f"{b.low:g}..{b.high:g}{b.unit}"
        )
    low = check_range(value[0], f"{name} low", low=b.low, high=b.high, unit=b.unit)
    high = check_range(value[1], f"{name} high", low=b.low, high=b.high, unit=b.unit)
    if low > high:
        raise SettingError(f"{name} = [{low:g}, {high:g}]: expected low <= high")
    return low, high


def ranges_from_table(
    table: object, *, path: str, line_of: Callable[[tuple[Any, ...]], int]
) -> VariantRanges:
    """The ranges of a motion file's ``[variants]`` table (the defaults for what it leaves out).

    Raises:
        MotionFileError: not a table, an unknown key, or a range that is not ``[low, high]``
            inside its bounds (:data:`BOUNDS`), with the file and line.
    """
    if not isinstance(table, Mapping):
        raise MotionFileError(
            path, line_of(("variants",)), "variants must be a table of name = [low, high]"
        )
    values: dict[str, tuple[float, float]] = {}
    for key, value in table.items():
        if key not in BOUNDS:
            raise MotionFileError(
                path,
                line_of(("variants", key)),
                f"unknown key {shown(key)} in [variants]; expected {', '.join(BOUNDS)}",
            )
        try:
            values[key] = _check_pair(key, value)
        except SettingError as exc:
            raise MotionFileError(path, line_of(("variants", key)), str(exc)) from None
    try:
        return VariantRanges(**values)
    except SettingError as exc:
        raise MotionFileError(path, line_of(("variants",)), str(exc)) from None


@dataclass(frozen=True)
class Variant:
    """One perturbed arm. Scales are per joint, in :data:`JOINT_NAMES` order."""

    index: int
    payload_kg: float
    kp_scale: np.ndarray
    kv_scale: np.ndarray
    force_scale: np.ndarray
    damping_scale: np.ndarray
    frictionloss_scale: np.ndarray
    armature_scale: np.ndarray
    zero_offset_deg: np.ndarray = field(default_factory=lambda: np.zeros(len(JOINT_NAMES)))

    def to_dict(self) -> dict[str, Any]:
        """Plain data: scales and offsets as ``{joint: value}``."""
        out: dict[str, Any] = {"index": self.index, "payload_kg": self.payload_kg}
        for f in fields(self)[2:]:
            values = getattr(self, f.name)
            out[f.name] = {n: float(v) for n, v in zip(JOINT_NAMES, values, strict=True)}
        return out


def nominal_variant(index: int = 0) -> Variant:
    """The unperturbed arm (no payload, every scale 1, no offset)."""
    one = np.ones(len(JOINT_NAMES))
    return Variant(index, 0.0, one, one, one, one, one, one, np.zeros(len(JOINT_NAMES)))


def check_variant_count(n: object) -> int:
    """``--variants``: an integer from 1 to :data:`MAX_VARIANTS`."""
    return check_count(n, "variants", minimum=1, maximum=MAX_VARIANTS)


def sample_variants(n: int, seed: int, ranges: VariantRanges | None = None) -> list[Variant]:
    """``n`` variants drawn from ``numpy.random.default_rng(seed)``: every parameter of every
    variant at once, before anything runs (so the result does not depend on who runs them)."""
    n = check_variant_count(n)
    r = ranges if ranges is not None else VariantRanges()
    rng = np.random.default_rng(seed)
    j = len(JOINT_NAMES)

    def draw(pair: tuple[float, float], shape: tuple[int, ...]) -> np.ndarray:
        return rng.uniform(pair[0], pair[1], size=shape)

    payload = draw(r.payload_kg, (n,))
    per_joint = {name: draw(getattr(r, name), (n, j)) for name in SCALES}
    offsets = draw((-r.zero_offset_deg[1], r.zero_offset_deg[1]), (n, j))
    return [
        Variant(
            index=i,
            payload_kg=float(payload[i]),
            zero_offset_deg=offsets[i],
            **{name: values[i] for name, values in per_joint.items()},
        )
        for i in range(n)
    ]


# ---------------------------------------------------------------------------- applying one
_FIELDS = (
    "body_mass",
    "body_inertia",
    "body_ipos",
    "body_iquat",
    "actuator_gainprm",
    "actuator_biasprm",
    "actuator_forcerange",
    "dof_damping",
    "dof_frictionloss",
    "dof_armature",
)
"""The model arrays a variant writes; :func:`apply_variant` restores them from the base first."""


def apply_variant(
    m: mujoco.MjModel, base: mujoco.MjModel, v: Variant, d: mujoco.MjData
) -> mujoco.MjModel:
    """Make ``m`` (a copy of ``base``) the arm ``v``: restore the perturbed arrays from ``base``,
    scale them, add the payload, then recompute the model's derived constants
    (``mj_setConst``, with ``d`` as scratch). The zero offsets are not in the model: they shift
    the commanded targets (see :mod:`so101sim.preflight.rollout`). Returns ``m``."""
    for name in _FIELDS:
        getattr(m, name)[:] = getattr(base, name)
    idx = arm_index(base)
    act, dof = idx.actuator, idx.dof
    # The stiffness is -biasprm[1] for every position servo so101sim makes: a plain position
    # actuator also has it in gainprm[0] (kp·ctrl), MuJoCo 4's PID actuator (the slew-limited
    # STS3215) keeps gainprm[0] at 0 and drives through its bias alone. biasprm[0] is the
    # calibration offset times kp: it scales with kp.
    kp = -base.actuator_biasprm[act, 1] * v.kp_scale
    gain = base.actuator_gainprm[act, 0] != 0.0
    m.actuator_gainprm[act[gain], 0] = kp[gain]
    m.actuator_biasprm[act, 0] = base.actuator_biasprm[act, 0] * v.kp_scale
    m.actuator_biasprm[act, 1] = -kp
    m.actuator_biasprm[act, 2] = base.actuator_biasprm[act, 2] * v.kv_scale
    m.actuator_forcerange[act] = base.actuator_forcerange[act] * v.force_scale[:, None]
    m.dof_damping[dof] = base.dof_damping[dof] * v.damping_scale
    m.dof_frictionloss[dof] = base.dof_frictionloss[dof] * v.frictionloss_scale
    m.dof_armature[dof] = base.dof_armature[dof] * v.armature_scale
    if v.payload_kg > 0:
        _add_payload(m, base, v.payload_kg)
    mujoco.mj_setConst(m, d)
    return m


def _add_payload(m: mujoco.MjModel, base: mujoco.MjModel, mass: float) -> None:
    """Fold a point mass at :data:`PAYLOAD_SITE` into its body's mass, centre of mass and
    principal inertia (parallel-axis theorem, then diagonalised again)."""
    site = mujoco.mj_name2id(base, mujoco.mjtObj.mjOBJ_SITE, PAYLOAD_SITE)
    if site < 0:
        raise SettingError(f"the model has no site {PAYLOAD_SITE!r} to carry a payload")
    b = int(base.site_bodyid[site])
    m0, c0, p = float(base.body_mass[b]), base.body_ipos[b].copy(), base.site_pos[site].copy()
    rot = np.empty(9)
    mujoco.mju_quat2Mat(rot, base.body_iquat[b])
    rot = rot.reshape(3, 3)
    inertia = rot @ np.diag(base.body_inertia[b]) @ rot.T  # body frame, about c0
    total = m0 + mass
    c = (m0 * c0 + mass * p) / total

    def shift(mass_: float, r: np.ndarray) -> np.ndarray:  # parallel axis
        return mass_ * (np.dot(r, r) * np.eye(3) - np.outer(r, r))

    inertia = inertia + shift(m0, c0 - c) + shift(mass, p - c)
    principal, axes = np.linalg.eigh(inertia)
    if np.linalg.det(axes) < 0:
        axes[:, 0] = -axes[:, 0]
    quat = np.empty(4)
    mujoco.mju_mat2Quat(quat, axes.reshape(-1))
    m.body_mass[b] = total
    m.body_ipos[b] = c
    m.body_iquat[b] = quat
    m.body_inertia[b] = principal


__all__ = [
    "BOUNDS",
    "MAX_VARIANTS",
    "Variant",
    "VariantRanges",
    "apply_variant",
    "check_variant_count",
    "nominal_variant",
    "ranges_from_table",
    "sample_variants",
]
