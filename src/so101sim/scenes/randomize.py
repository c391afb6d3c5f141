"""Domain randomisation of a table-top scene, seeded, per episode.

:class:`Randomization` says how much each family varies; :data:`PRESETS` names three
(``none``, ``light``, ``full``; :func:`randomization` turns a name or a dict into one). The
families:

- ``lighting``: each light's brightness scaled by up to ±this share, moved by up to
  ``lighting`` × 0.5 m;
- ``colors``: the table's and each object's red, green and blue shifted by up to ±this;
- ``camera_m``, ``camera_fovy_deg``: each camera moved by up to ±metres, its vertical field
  of view changed by up to ±degrees;
- ``object_size``: box objects' edge lengths scaled by up to ±this share (the object raised or
  lowered so it rests on the table);
- ``object_mass``, ``friction``: each object's mass (and inertia) and sliding friction scaled
  by up to ±this share;
- ``distractors``: up to this many small boxes (:data:`DISTRACTOR_PREFIX` ``0``, ``1``, …,
  added with ``MjSpec`` when the scene is built: :func:`add_distractors`) put on the table at
  random, clear of the task's objects; the ones not used wait off the table;
- ``textures``: the chance (0 to 1) that the table and each object are drawn with one of
  :data:`TEXTURES` (checker, gradient, speckle: built into the scene with ``MjSpec`` by
  :func:`add_textures`, tinted by the surface's own colour, the ``colors`` family on top)
  instead of their plain colour; only the images change;
- ``actuators``: each arm joint's position gain (kp), damping, friction loss and armature
  scaled by up to ±this share, around the model's values;
- ``actuator_sigmas``: each arm joint's servo drawn from the arm profile's ``[uncertainty]``
  (:func:`so101sim.model.arm.draw_servo_deltas`: normal draws of this many standard
  deviations, cut at 3): gain, torque limit, back-EMF and viscous damping, both frictions,
  armature, command delay, the firmware's goal speed and calibration offset, those the
  profile gives a standard deviation for (the shipped ``sts3215``: its fit's standard errors
  and the spread between fits on each trajectory family of the servo bench). A profile with no
  table (``official``) draws nothing here.

:class:`SceneRandomizer` applies one draw to a compiled scene (its physics model and the render
models its images are drawn with), always from the models' original values, so draws never
pile up; it draws from the generator it is given (the environment's ``np_random``, after the
objects' start poses), so the same seed gives the same scene, and the start poses are those
drawn without randomisation. It changes what its families say and nothing else: the arm's
joints, their order and units, the timestep and the control rate stay.
"""

from __future__ import annotations

from typing import Any

import mujoco
import numpy as np

from ..errors import SettingError
from ..model import arm_index
from ..model.arm import ArmProfile, draw_servo_deltas
from .cameras import PRESET_CAMERAS
from .randomization import (
    DISTRACTOR_PREFIX,
    MAX_DISTRACTORS,
    PARKED_M,
    PRESETS,
    TEXTURE_PREFIX,
    TEXTURES,
    Randomization,
    add_distractors,
    add_textures,
    describe,
    parse_spec,
    randomization,
    scene_additions,
)

MAX_LIGHTS = 8
"""Light draws are made for this many lights whatever the model has (the same draws for the
same seed in models that differ in their cameras or lights: an environment and a follower)."""
DISTRACTOR_SIZE_M = (0.012, 0.02)
"""Half edge lengths of a distractor box are drawn from this range (metres)."""
CLEARANCE_M = 0.07
"""A distractor's centre stays at least this far from each object's and each other's."""
TABLE_PATCH = ((0.10, 0.28), (-0.16, 0.16))
"""Where distractors may go on the table (x, y ranges, metres, in front of the arm)."""


SNAPSHOT = (
    "geom_rgba",
    "light_diffuse",
    "light_pos",
    "cam_pos",
    "cam_fovy",
    "geom_size",
    "geom_rbound",
    "geom_aabb",
    "body_mass",
    "body_inertia",
    "geom_friction",
    "actuator_gainprm",
    "actuator_biasprm",
    "dof_damping",
    "dof_frictionloss",
    "dof_armature",
    "actuator_forcerange",
    "actuator_dynprm",
    "actuator_delay",
)
"""The model arrays a draw may change (restored before each draw)."""
SNAPSHOT = (*SNAPSHOT, "geom_matid")


def _ids(model: mujoco.MjModel, kind: mujoco.mjtObj, names: list[str]) -> list[int]:
    return [i for i in (mujoco.mj_name2id(model, kind, n) for n in names) if i >= 0]


class SceneRandomizer:
    """Applies :class:`Randomization` draws to a compiled scene (see the module's text)."""

    def __init__(
        self,
        model: mujoco.MjModel,
        objects: list[str],
        options: Randomization,
        render_models: list[mujoco.MjModel] | None = None,
        profile: ArmProfile | None = None,
    ) -> None:
        self.options = options.validated()
        self.profile = profile
        self.model = model
        self.render_models = list(render_models or [])
        self.objects = list(objects)
        body = mujoco.mjtObj.mjOBJ_BODY
        self._distractors = [
            i for i in range(MAX_DISTRACTORS)
            if mujoco.mj_name2id(model, body, f"{DISTRACTOR_PREFIX}{i}") >= 0
        ]  # fmt: skip
        if self.options.distractors > len(self._distractors):
            raise SettingError(
                f"randomize distractors = {self.options.distractors} but the scene was built "
                f"with {len(self._distractors)}; expected the scene built with "
                f"add_distractors(spec, {self.options.distractors})"
            )
        if self.options.textures and self._materials(model) is None:
            raise SettingError(
                f"randomize textures = {self.options.textures} but the scene was built without "
                "them; expected the scene built with add_textures(spec) (scene_additions)"
            )
        self._base = {m: self._snapshot(m) for m in [model, *self.render_models]}

    @staticmethod
    def _materials(m: mujoco.MjModel) -> list[int] | None:
        ids = [mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_MATERIAL, f"{TEXTURE_PREFIX}{k}")
               for k in TEXTURES]  # fmt: skip
        return ids if min(ids) >= 0 else None

    def add_render_model(self, model: mujoco.MjModel) -> None:
        """Also give the visual families' draws to ``model`` (a render model of the scene)."""
        if model not in self._base:
            self.render_models.append(model)
            self._base[model] = self._snapshot(model)

    @staticmethod
    def _snapshot(m: mujoco.MjModel) -> dict[str, np.ndarray]:
        names = SNAPSHOT
        return {n: getattr(m, n).copy() for n in names}

    def _object_geoms(self, m: mujoco.MjModel, name: str) -> np.ndarray:
        bid = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, name)
        return np.flatnonzero(m.geom_bodyid == bid) if bid >= 0 else np.zeros(0, dtype=int)

    def apply(self, rng: np.random.Generator, data: mujoco.MjData) -> dict[str, Any]:
        """Draw a scene from ``rng`` and give it to the models (and ``data``: the resized
        objects' heights, the distractors' poses; then ``mj_forward``). Call it after the
        objects were placed. Returns what was drawn (plain numbers, for a dataset's
        metadata)."""
        o = self.options
        m = self.model
        drawn: dict[str, Any] = {}
        for mm, base in self._base.items():
            for key, value in base.items():
                getattr(mm, key)[:] = value
        u = rng.uniform
        # -- the look (every model)
        scale = u(1 - o.lighting, 1 + o.lighting, MAX_LIGHTS)
        move = u(-0.5 * o.lighting, 0.5 * o.lighting, (MAX_LIGHTS, 3))
        shift = {n: u(-o.colors, o.colors, 3) for n in [*self.objects, "table"]}
        # the preset cameras, by name (other cameras of a model stay where they are)
        cams = {n: (u(-o.camera_m, o.camera_m, 3), float(u(-1, 1)) * o.camera_fovy_deg)
                for n in PRESET_CAMERAS}  # fmt: skip
        for mm, base in self._base.items():
            n = min(mm.nlight, MAX_LIGHTS)
            if n:
                lit = base["light_diffuse"][:n] * scale[:n, None]
                mm.light_diffuse[:n] = np.clip(lit, 0, 1)
                mm.light_pos[:n] = base["light_pos"][:n] + move[:n]
            for name, sh in shift.items():
                ids = self._object_geoms(mm, name)
                mm.geom_rgba[ids, :3] = np.clip(base["geom_rgba"][ids, :3] + sh, 0, 1)
            for name, (dp, df) in cams.items():
                cid = mujoco.mj_name2id(mm, mujoco.mjtObj.mjOBJ_CAMERA, name)
                if cid >= 0:
                    mm.cam_pos[cid] = base["cam_pos"][cid] + dp
                    mm.cam_fovy[cid] = base["cam_fovy"][cid] + df
        cam = np.array([c[0] for c in cams.values()])
        fovy = np.array([c[1] for c in cams.values()])
        drawn["lighting"] = {"scale": scale.tolist(), "move_m": move.tolist()}
        drawn["colors"] = {k: v.tolist() for k, v in shift.items()}
        drawn["cameras"] = {
            n: {"move_m": cam[i].tolist(), "fovy_deg": float(fovy[i])} for i, n in enumerate(cams)
        }
        # -- the objects (sizes in every model; mass and friction in the physics model)
        sizes, masses, frictions = {}, {}, {}
        for name in self.objects:
            k_size = float(u(1 - o.object_size, 1 + o.object_size))
            k_mass = float(u(1 - o.object_mass, 1 + o.object_mass))
            k_fric = float(u(1 - o.friction, 1 + o.friction))
            ids = self._object_geoms(m, name)
            is_box = len(ids) == 1 and m.geom_type[ids[0]] == mujoco.mjtGeom.mjGEOM_BOX
            if is_box and o.object_size:
                for mm, base in self._base.items():
                    gid = self._object_geoms(mm, name)
                    mm.geom_size[gid] = base["geom_size"][gid] * k_size
                    mm.geom_rbound[gid] = base["geom_rbound"][gid] * k_size
                    mm.geom_aabb[gid] = base["geom_aabb"][gid] * k_size
                jid = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_JOINT, f"{name}_joint")
                if jid >= 0:  # rest on the table: the centre moves with the half height
                    adr = m.jnt_qposadr[jid]
                    data.qpos[adr + 2] += (k_size - 1) * self._base[m]["geom_size"][ids[0], 2]
                sizes[name] = k_size
            else:
                k_size = 1.0
            bid = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, name)
            if bid >= 0:
                m.body_mass[bid] = self._base[m]["body_mass"][bid] * k_mass * k_size**3
                m.body_inertia[bid] = self._base[m]["body_inertia"][bid] * k_mass * k_size**5
            m.geom_friction[ids, 0] = self._base[m]["geom_friction"][ids, 0] * k_fric
            masses[name], frictions[name] = k_mass, k_fric
        drawn["objects"] = {"size": sizes, "mass": masses, "friction": frictions}
        # -- the arm's actuators (physics model)
        idx = arm_index(m)
        k_act = u(1 - o.actuators, 1 + o.actuators, (len(idx.actuator), 4))
        for j, (act, dof) in enumerate(zip(idx.actuator, idx.dof, strict=True)):
            base = self._base[m]
            m.actuator_gainprm[act, 0] = base["actuator_gainprm"][act, 0] * k_act[j, 0]
            m.actuator_biasprm[act, 1] = base["actuator_biasprm"][act, 1] * k_act[j, 0]
            m.dof_damping[dof] = base["dof_damping"][dof] * k_act[j, 1]
            m.dof_frictionloss[dof] = base["dof_frictionloss"][dof] * k_act[j, 2]
            m.dof_armature[dof] = base["dof_armature"][dof] * k_act[j, 3]
        drawn["actuators"] = {"kp": k_act[:, 0].tolist(), "damping": k_act[:, 1].tolist(),
                              "frictionloss": k_act[:, 2].tolist(),
                              "armature": k_act[:, 3].tolist()}  # fmt: skip
        drawn["distractors"] = self._place_distractors(rng, data)
        drawn["servos"] = self._draw_servos(rng)
        drawn["textures"] = self._draw_textures(rng)
        mujoco.mj_forward(m, data)
        return drawn

    def _draw_textures(self, rng: np.random.Generator) -> dict[str, str]:
        """The ``textures`` family: which surfaces wear which texture (every model that was
        built with them; a render model without them keeps plain colours)."""
        if not self.options.textures:
            return {}
        chosen: dict[str, str] = {}
        for name in ["table", *self.objects]:
            hit = float(rng.uniform()) < self.options.textures
            kind = TEXTURES[int(rng.integers(len(TEXTURES)))]
            if hit:
                chosen[name] = kind
        for mm in self._base:
            mats = self._materials(mm)
            if mats is None:
                continue
            for name, kind in chosen.items():
                mm.geom_matid[self._object_geoms(mm, name)] = mats[TEXTURES.index(kind)]
        return chosen

    def _draw_servos(self, rng: np.random.Generator) -> dict[str, dict[str, float]]:
        """The ``actuator_sigmas`` family: each joint's servo drawn from the profile's
        uncertainty, written over the values the share family left (changes, not values, so the
        gripper's torque fraction and the share's draw stay). The delay stays within the
        history the model was built with (up to the next whole timestep above the profile's
        delay): what is recorded is what was applied."""
        if self.profile is None or not self.options.actuator_sigmas:
            return {}
        m = self.model
        idx = arm_index(m)
        deltas = draw_servo_deltas(self.profile, rng, self.options.actuator_sigmas)
        for (joint, d), act, dof in zip(deltas.items(), idx.actuator, idx.dof, strict=True):
            kp = -float(m.actuator_biasprm[act, 1])
            nominal = self.profile.joint(joint)
            if "kp_per_p" in d and nominal.kp > 0 and kp > 0:
                ratio = 1.0 + d["kp_per_p"] * nominal.firmware_p / nominal.kp
                m.actuator_biasprm[act, :2] *= ratio
                m.actuator_gainprm[act, 0] *= ratio
                kp *= ratio
            if "torque_limit" in d and nominal.torque_limit > 0:
                m.actuator_forcerange[act] *= 1.0 + d["torque_limit"] / nominal.torque_limit
            m.dof_damping[dof] = max(0.0, m.dof_damping[dof] + d.get("damping", 0.0)
                                     + d.get("viscous", 0.0))  # fmt: skip
            m.dof_frictionloss[dof] = max(0.0, m.dof_frictionloss[dof] + d.get("frictionloss", 0.0)
                                          + d.get("drive_frictionloss", 0.0))  # fmt: skip
            m.dof_armature[dof] = max(0.0, m.dof_armature[dof] + d.get("armature", 0.0))
            if "delay_s" in d:
                reach = max(int(m.actuator_history[act, 0]) - 2, 0) * m.opt.timestep
                before = float(m.actuator_delay[act])
                m.actuator_delay[act] = float(np.clip(before + d["delay_s"], 0.0, reach))
                d["delay_s"] = float(m.actuator_delay[act]) - before  # what the history allows
            slewing = int(m.actuator_dyntype[act]) == int(mujoco.mjtDyn.mjDYN_PID)
            if "max_velocity" in d and slewing:
                m.actuator_dynprm[act, 1] = max(1e-6, m.actuator_dynprm[act, 1] + d["max_velocity"])
            if "offset" in d:
                m.actuator_biasprm[act, 0] -= kp * d["offset"]
        return deltas

    def _place_distractors(self, rng: np.random.Generator, data: mujoco.MjData) -> list[Any]:
        m = self.model
        used = int(rng.integers(0, self.options.distractors + 1)) if self.options.distractors else 0
        taken = []
        for name in self.objects:
            jid = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_JOINT, f"{name}_joint")
            if jid >= 0:
                taken.append(np.array(data.qpos[m.jnt_qposadr[jid] : m.jnt_qposadr[jid] + 2]))
        placed = []
        for k, i in enumerate(self._distractors):
            jid = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_JOINT, f"{DISTRACTOR_PREFIX}{i}_joint")
            gid = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_GEOM, f"{DISTRACTOR_PREFIX}{i}_geom")
            adr = m.jnt_qposadr[jid]
            half = self._base[m]["geom_size"][gid, 2]
            pose = [PARKED_M[0] + 0.1 * i, PARKED_M[1], half, 1.0, 0.0, 0.0, 0.0]
            if k < used:
                half = float(rng.uniform(*DISTRACTOR_SIZE_M))
                for _ in range(50):
                    xy = np.array([rng.uniform(*TABLE_PATCH[0]), rng.uniform(*TABLE_PATCH[1])])
                    if all(np.linalg.norm(xy - t) >= CLEARANCE_M for t in taken):
                        break
                else:
                    xy = None  # no room: stays parked
                if xy is not None:
                    taken.append(xy)
                    yaw = float(rng.uniform(-np.pi, np.pi))
                    top = _table_top(m)
                    pose = [xy[0], xy[1], top + half, np.cos(yaw / 2), 0.0, 0.0, np.sin(yaw / 2)]
                    placed.append({"x": float(xy[0]), "y": float(xy[1]), "half_m": half})
                    for mm in self._base:
                        g = mujoco.mj_name2id(mm, mujoco.mjtObj.mjOBJ_GEOM, m.geom(gid).name)
                        if g >= 0:
                            mm.geom_size[g] = half
                            mm.geom_rbound[g] = half * np.sqrt(3)
                            mm.geom_aabb[g, 3:] = half
            data.qpos[adr : adr + 7] = pose
            data.qvel[m.jnt_dofadr[jid] : m.jnt_dofadr[jid] + 6] = 0.0
        return placed


def _table_top(model: mujoco.MjModel) -> float:
    """The table top's height (the scenes put it at z = 0; the floor lies below)."""
    gid = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_GEOM, "table_top")
    if gid < 0:
        return 0.0
    body = model.geom_bodyid[gid]
    return float(model.body_pos[body, 2] + model.geom_pos[gid, 2] + model.geom_size[gid, 2])


__all__ = [
    "DISTRACTOR_PREFIX",
    "MAX_DISTRACTORS",
    "PRESETS",
    "TEXTURES",
    "Randomization",
    "SceneRandomizer",
    "add_distractors",
    "add_textures",
    "describe",
    "parse_spec",
    "randomization",
    "scene_additions",
]
