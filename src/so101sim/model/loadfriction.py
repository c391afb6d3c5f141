"""Load-dependent gearbox friction (Rhoban's BAM models M3-M6): a servo's Coulomb friction that
grows with the torque it transmits, ``frictionloss + load_friction × |servo torque|``.

MuJoCo has no friction that depends on a load, so the model carries it in parts, added at load
with ``MjSpec`` (:func:`add_load_friction`) when a profile gives a joint a ``load_friction``
above 0: a fixed tendon on the joint (``so101sim_load_friction_<joint>``) whose ``frictionloss``
is the load's share, a custom numeric of the same name holding the coefficient and where, in
``MjData.userdata``, the share in force is kept (so it goes with the data, and a model may
serve several datas one after another; ``userdata`` is not in a FULLPHYSICS state, so the
kernel keeps it beside the states it saves and restores). The joint keeps its
own ``frictionloss`` (anything that scales it, randomisation or the preflight's variants, still
acts on it). The stepping kernel (:mod:`so101sim.sim.stepping`) sets each share from the
servo's last torque every :func:`update_steps` physics steps (:data:`UPDATE_PERIOD_S`, at
simulated times that are multiples of it, so every path through the kernel steps the same
physics) and writes the data's shares into the model's tendons before it steps. A model with
load friction is written as it steps: one thread steps it at a time.
"""

from __future__ import annotations

import math
import weakref
from dataclasses import dataclass

import mujoco
import numpy as np

from ..errors import ProfileError
from ..units import JOINT_NAMES

PREFIX = "so101sim_load_friction_"
"""The names of a joint's load-friction tendon and numeric: this prefix and the joint's name."""

UPDATE_PERIOD_S = 0.01
"""How often the load's friction follows the servo's torque, s of simulated time (a servo's
torque changes over tens of milliseconds: its command delay and the arm's motion)."""


def add_load_friction(spec: mujoco.MjSpec, coefficients: dict[str, float]) -> None:
    """Add a load-friction tendon, coefficient and ``userdata`` slot for each joint of
    ``coefficients`` (joint name -> N·m of friction per N·m of servo torque) that has none yet
    (a joint that has one gets its coefficient written)."""
    have = {n.name: n for n in spec.numerics}
    for joint, k in coefficients.items():
        name = PREFIX + joint
        if name in have:
            have[name].data = [float(k), have[name].data[1]]
            continue
        tendon = spec.add_tendon(name=name)
        tendon.wrap_joint(joint, 1.0)
        slot = spec.nuserdata
        spec.nuserdata = slot + 1
        spec.add_numeric(name=name, data=[float(k), float(slot)])


def add_load_friction_slots(spec: mujoco.MjSpec) -> None:
    """:func:`add_load_friction` with a coefficient of 0 for every SO-101 joint ``spec`` has and
    that has none: a model whose coefficients are written later (a fit's)."""
    joints = {j.name for j in spec.joints}
    have = {n.name for n in spec.numerics}
    add_load_friction(spec, {j: 0.0 for j in JOINT_NAMES if j in joints and PREFIX + j not in have})


@dataclass(frozen=True)
class LoadFriction:
    """Where a compiled model keeps its load friction: per joint that has it, the tendon, the
    coefficient's address in ``numeric_data``, the share's slot in ``userdata``, the actuator
    driving the joint (its force is the load) and the joint's degree of freedom; ``stride``:
    :func:`update_steps` at the model's timestep."""

    tendons: np.ndarray
    numerics: np.ndarray
    slots: np.ndarray
    actuators: np.ndarray
    dofs: np.ndarray
    stride: int

    def active(self, m: mujoco.MjModel) -> bool:
        """Whether any coefficient is above 0 (else the model steps as one without it)."""
        return bool(np.any(m.numeric_data[self.numerics] > 0.0))

    def update(self, m: mujoco.MjModel, d: mujoco.MjData) -> None:
        """Set each share from its servo's torque in ``d`` (that of the last step), in ``d``
        and in the model's tendons."""
        share = m.numeric_data[self.numerics] * np.abs(d.actuator_force[self.actuators])
        d.userdata[self.slots] = share
        m.tendon_frictionloss[self.tendons] = share

    def restore(self, m: mujoco.MjModel, d: mujoco.MjData) -> None:
        """Write ``d``'s shares into the model's tendons (before ``d`` steps)."""
        m.tendon_frictionloss[self.tendons] = d.userdata[self.slots]


_found: weakref.WeakKeyDictionary[mujoco.MjModel, LoadFriction | None] = weakref.WeakKeyDictionary()


def update_steps(timestep: float) -> int:
    """Physics steps between two updates of the load's friction at ``timestep``."""
    return max(1, round(UPDATE_PERIOD_S / timestep))


def load_friction(m: mujoco.MjModel) -> LoadFriction | None:
    """The load friction ``m`` carries (looked up once per model), or None."""
    if m in _found:
        return _found[m]
    tendons, numerics, slots, actuators, dofs = [], [], [], [], []
    if m.nnumeric and m.ntendon:
        for t in range(m.ntendon):
            name = mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_TENDON, t) or ""
            if not name.startswith(PREFIX):
                continue
            joint = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_JOINT, name[len(PREFIX) :])
            num = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_NUMERIC, name)
            on_joint = m.actuator_trntype == mujoco.mjtTrn.mjTRN_JOINT
            drives = np.flatnonzero(on_joint & (m.actuator_trnid[:, 0] == joint))
            if joint < 0 or num < 0 or not len(drives) or m.numeric_size[num] != 2:
                continue
            adr = int(m.numeric_adr[num])
            slot = int(m.numeric_data[adr + 1])
            if not 0 <= slot < m.nuserdata:
                continue
            tendons.append(t)
            numerics.append(adr)
            slots.append(slot)
            actuators.append(int(drives[0]))
            dofs.append(int(m.jnt_dofadr[joint]))
    found = None
    if tendons:
        found = LoadFriction(
            np.array(tendons), np.array(numerics), np.array(slots), np.array(actuators),
            np.array(dofs), update_steps(m.opt.timestep),
        )  # fmt: skip
    _found[m] = found
    return found


def active_load_friction(m: mujoco.MjModel) -> LoadFriction | None:
    """The load friction of ``m`` if any coefficient is above 0, else None."""
    found = load_friction(m)
    return found if found is not None and found.active(m) else None


def write_load_friction(m: mujoco.MjModel, dof: int, k: float) -> None:
    """Write the coefficient ``k`` of the joint with degree of freedom ``dof`` into ``m``.

    Raises:
        ProfileError: ``k`` > 0 on a model compiled without load friction on that joint.
    """
    found = load_friction(m)
    where = np.flatnonzero(found.dofs == dof) if found is not None else np.array([], int)
    if not len(where):
        if k > 0:
            joint = mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_JOINT, int(m.dof_jntid[dof]))
            raise ProfileError(
                f"load_friction = {k} needs a model compiled with load friction on joint "
                f"{joint!r}; expected the profile's load_friction (or a fit's) when the model "
                "was made"
            )
        return
    m.numeric_data[found.numerics[where[0]]] = k
    if k == 0:  # a joint without it steps unset: its share must not outlive it
        m.tendon_frictionloss[found.tendons[where[0]]] = 0.0


def step_index(time: float, timestep: float) -> int:
    """The number of the next step at simulated ``time``."""
    return math.floor(time / timestep + 0.5)
