"""Forward kinematics: where the gripper's tip is, for a pose in the arm's units.

The tip is the model's ``gripperframe`` site (between the jaws' fingertips); positions and
rotations are given in the frame of the ``baseframe`` site (on the floor under the base, 3.9 cm
behind the pan axis): **x forward** (where the arm points at ``shoulder_pan = 0``), **y to the
arm's left**, **z up**, in metres. In the shipped model the base frame is the world frame.

The tool's own axes are the columns of :attr:`TipPose.rotation`: x is the **approach** axis
(from the wrist out through the fingertips), y the jaws' sideways axis, z completes the frame.
Because this arm has five body joints, the approach axis always lies in the arm's vertical
plane, so two angles describe it and the jaw's turn about it:

* ``pitch``: the approach axis' angle above the horizontal, in that plane (degrees, -180..180):
  0 pointing straight forward, -90 straight down, 90 straight up, ±180 back at the base;
* ``roll``: the jaws' turn about the approach axis, in the same sense as a positive
  ``wrist_roll``; 0 when the jaws' y axis is horizontal (in the shipped model ``roll =
  wrist_roll - 2.79°``: at ``wrist_roll = 0`` the gripper sits 2.79° off level);
* ``yaw``: the heading of the arm's plane (degrees, counter-clockwise seen from above; a
  positive ``shoulder_pan`` turns the arm clockwise, so ``yaw = -shoulder_pan``).
"""

from __future__ import annotations

import math
import threading
import weakref
from collections.abc import Mapping
from dataclasses import dataclass

import mujoco
import numpy as np

from ..errors import JointLimitError, JointValueError, ModelError
from ..model.load import ArmIndex, arm_index, arm_units, load_model
from ..units import BODY_JOINTS, JOINT_NAMES, ArmUnits, Pose

TIP_SITE = "gripperframe"
"""The model's site that marks the tip: between the fingertips, x along the approach axis."""
BASE_SITE = "baseframe"
"""The model's site whose frame positions and rotations are given in."""
N_BODY = len(BODY_JOINTS)
"""The joints that move the tip: all but the gripper (its jaw does not carry the tip frame)."""


@dataclass(frozen=True, eq=False)
class TipPose:
    """Where the tip is and which way it points, in the base frame (see the module's text)."""

    position: np.ndarray  # (3,) metres: x forward, y left, z up
    rotation: np.ndarray  # (3, 3): columns are the tool's x (approach), y (jaw side), z axes
    pitch: float  # degrees above the horizontal, -180..180 (-90: pointing straight down)
    roll: float  # degrees about the approach axis, in wrist_roll's sense
    yaw: float  # degrees, heading of the arm's vertical plane (counter-clockwise from +x)

    @property
    def approach(self) -> np.ndarray:
        """The unit vector the tool points along (the rotation's first column)."""
        return self.rotation[:, 0]

    @property
    def transform(self) -> np.ndarray:
        """The tool frame as a 4x4 homogeneous transform (rotation and position), as
        LeRobot's end-effector pipeline and placo use."""
        t = np.eye(4)
        t[:3, :3], t[:3, 3] = self.rotation, self.position
        return t

    def format(self, digits: int = 3) -> str:
        """One line: ``x=0.391 y=-0.000 z=0.226 m, pitch=0.0°, roll=-2.8°``."""
        x, y, z = (round(float(v), digits) + 0.0 for v in self.position)
        return (
            f"x={x:.{digits}f} y={y:.{digits}f} z={z:.{digits}f} m, "
            f"pitch={round(self.pitch, 1) + 0.0:.1f}°, roll={round(self.roll, 1) + 0.0:.1f}°"
        )


class Frame:
    """The tip's frame and the arm plane's axes, in the base frame (radians for angles).

    ``normal`` is the shoulder_lift axis (normal to the arm's vertical plane), ``heading`` the
    horizontal forward direction in that plane (normal × up). A plain class with slots: IK
    builds one per iteration.
    """

    __slots__ = ("heading", "normal", "pitch", "position", "roll", "rotation")

    def __init__(self, position: np.ndarray, rotation: np.ndarray, normal: np.ndarray) -> None:
        self.position = position
        self.rotation = rotation
        self.normal = normal
        (ax, sx, _), (ay, sy, _), (az, sz, _) = rotation.tolist()
        nx, ny, nz = normal.tolist()
        norm = math.hypot(nx, ny)
        hx, hy = ny / norm, -nx / norm
        self.heading = np.array([hx, hy, 0.0])
        self.pitch = math.atan2(az, ax * hx + ay * hy)
        # roll: from the normal to the jaw's side axis, about -approach (wrist_roll's sense)
        c = nx * sx + ny * sy + nz * sz
        s = -((ny * sz - nz * sy) * ax + (nz * sx - nx * sz) * ay + (nx * sy - ny * sx) * az)
        self.roll = math.atan2(s, c)

    def tip_pose(self) -> TipPose:
        h = self.heading
        return TipPose(
            position=self.position.copy(),
            rotation=self.rotation.copy(),
            pitch=math.degrees(self.pitch),
            roll=math.degrees(self.roll),
            yaw=math.degrees(math.atan2(h[1], h[0])),
        )


def quat_yaw(quat: np.ndarray) -> np.ndarray:
    """The turn about the vertical (radians) of quaternions (w, x, y, z) along the last axis."""
    q = np.asarray(quat, dtype=np.float64)
    w, x, y, z = q[..., 0], q[..., 1], q[..., 2], q[..., 3]
    return np.arctan2(2 * (w * z + x * y), 1 - 2 * (y * y + z * z))


def cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """``a × b`` for 3-vectors (``np.cross`` costs ten times more on such small arrays)."""
    return np.array(
        [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]]
    )


def _site(model: mujoco.MjModel, name: str) -> int:
    sid = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_SITE, name)
    if sid < 0:
        raise ModelError(
            f"model has no site named {name!r}; kinematics needs the SO-101's "
            f"{TIP_SITE!r} (the tip) and {BASE_SITE!r} (the base frame) sites"
        )
    return sid


class Kinematics:
    """Forward kinematics and Jacobians of one model, on a private scratch ``MjData``.

    One instance per model is shared through :func:`for_model` while anything holds it; its
    methods hold a lock, so threads may share it. Joint values go in as arrays in
    :data:`~so101sim.units.JOINT_NAMES` order, radians for :meth:`frame_at`
    and arm units for :meth:`tip_array`.
    """

    def __init__(self, model: mujoco.MjModel) -> None:
        self.model = model
        self.data = mujoco.MjData(model)
        self.index: ArmIndex = arm_index(model)
        self.units: ArmUnits = arm_units(model)
        self.tip_site = _site(model, TIP_SITE)
        self.base_site = _site(model, BASE_SITE)
        self.lift_joint = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, JOINT_NAMES[1])
        self.lower = self.index.lower[:N_BODY].copy()
        self.upper = self.index.upper[:N_BODY].copy()
        self.lock = threading.RLock()
        self._dofs = self.index.dof[:N_BODY]
        self._jacp = np.zeros((3, model.nv))
        self._jacr = np.zeros((3, model.nv))
        qpos = self.index.qpos[:N_BODY]
        contiguous = bool(np.all(np.diff(qpos) == 1))
        self._qpos = slice(int(qpos[0]), int(qpos[-1]) + 1) if contiguous else qpos
        mujoco.mj_kinematics(model, self.data)
        fixed = model.body_weldid[model.site_bodyid[self.base_site]] == 0  # welded to the world
        self._base_is_world = bool(
            fixed
            and np.allclose(self.data.site_xpos[self.base_site], 0.0, atol=1e-12)
            and np.allclose(self.data.site_xmat[self.base_site], np.eye(3).ravel(), atol=1e-12)
        )
        self.roll_at_zero = self.frame_at(np.zeros(N_BODY)).roll
        """The tip's roll (radians) at wrist_roll = 0: roll = wrist_roll + roll_at_zero."""

    def frame_at(self, q: np.ndarray, *, jacobians: bool = False) -> Frame:
        """The tip's frame for body-joint angles ``q`` (radians, the first five joints).

        With ``jacobians``, MuJoCo's Jacobians are computed too (:meth:`jacobians` reads them).
        Call with :attr:`lock` held when you go on to read the Jacobians.
        """
        d = self.data
        d.qpos[self._qpos] = q[:N_BODY]
        mujoco.mj_kinematics(self.model, d)
        if jacobians:
            mujoco.mj_comPos(self.model, d)
        pos = d.site_xpos[self.tip_site]
        rot = d.site_xmat[self.tip_site].reshape(3, 3)
        normal = d.xaxis[self.lift_joint]
        if self._base_is_world:
            return Frame(pos.copy(), rot.copy(), normal.copy())
        rb = d.site_xmat[self.base_site].reshape(3, 3)
        return Frame(rb.T @ (pos - d.site_xpos[self.base_site]), rb.T @ rot, rb.T @ normal)

    def jacobians(self) -> tuple[np.ndarray, np.ndarray]:
        """``(Jp, Jr)``, each ``(3, 5)``: the tip's linear (m/rad) and angular (rad/rad)
        velocity per body joint, in the base frame, at the last :meth:`frame_at` with
        ``jacobians=True``."""
        mujoco.mj_jacSite(self.model, self.data, self._jacp, self._jacr, self.tip_site)
        jp, jr = self._jacp[:, self._dofs], self._jacr[:, self._dofs]
        if self._base_is_world:
            return jp, jr
        rb = self.data.site_xmat[self.base_site].reshape(3, 3)
        return rb.T @ jp, rb.T @ jr

    def tip_array(self, values: np.ndarray) -> TipPose:
        """The tip for joint values in arm units (an array of 5 or 6, gripper ignored)."""
        v = np.asarray(values, dtype=float)
        q = np.radians(v[:N_BODY])  # body joints: the arm's degrees are the model's radians
        with self.lock:
            return self.frame_at(q).tip_pose()

    def tip_positions(self, values: np.ndarray) -> np.ndarray:
        """Tip positions ``(n, 3)`` in metres for ``(n, 6)`` (or ``(n, 5)``) arm-unit rows."""
        rows = np.radians(np.atleast_2d(np.asarray(values, dtype=float))[:, :N_BODY])
        out = np.empty((len(rows), 3))
        with self.lock:
            if not self._base_is_world or not isinstance(self._qpos, slice):
                for i, q in enumerate(rows):
                    out[i] = self.frame_at(q).position
                return out
            # frame_at's position without the rest of the frame: a long move's rows (the
            # preflight's line check) cost one mj_kinematics each
            m, d, kinematics = self.model, self.data, mujoco.mj_kinematics
            qpos, tip = d.qpos[self._qpos], d.site_xpos[self.tip_site]  # views, made once
            for i, q in enumerate(rows):
                qpos[:] = q
                kinematics(m, d)
                out[i] = tip
        return out

    def pose_values(self, pose: Pose | np.ndarray, *, base: np.ndarray | None = None) -> np.ndarray:
        """A pose dict (joint names or LeRobot keys; missing joints from ``base``) or an array
        of six, checked against the limits, as an array in arm units.

        Raises:
            JointLimitError: a joint outside its limits (the advice fits kinematics: there is
                no ``clip`` here).
        """
        try:
            return self._pose_values(pose, base)
        except JointLimitError as exc:
            raise JointLimitError(
                exc.what,
                "kinematics takes poses the arm can reach: give a value inside the limits",
                joint=exc.joint,
                value=exc.value,
                lower=exc.lower,
                upper=exc.upper,
            ) from None

    def _pose_values(self, pose: Pose | np.ndarray, base: np.ndarray | None) -> np.ndarray:
        if isinstance(pose, Mapping):
            return self.units.pose_to_array(pose, base=base)
        arr = np.asarray(pose, dtype=float)
        if arr.shape != (len(JOINT_NAMES),):
            raise JointValueError(
                f"joint values of shape {arr.shape}; expected a pose dict, or six numbers in "
                f"{', '.join(JOINT_NAMES)} order (arm units)"
            )
        bad = np.flatnonzero(~np.isfinite(arr))
        if bad.size:
            name = JOINT_NAMES[int(bad[0])]
            raise JointValueError(f"{name} = {arr[bad[0]]} is not finite; expected a finite number")
        return self.units.check_limits(arr)

    def zero_frame_axes(self) -> list[tuple[str, np.ndarray, np.ndarray]]:
        """``(joint, point, axis)`` of each body joint at the zero pose, in the base frame."""
        with self.lock:
            self.frame_at(np.zeros(N_BODY))
            d = self.data
            rb = d.site_xmat[self.base_site].reshape(3, 3)
            ob = d.site_xpos[self.base_site]
            out = []
            for name in BODY_JOINTS:
                j = mujoco.mj_name2id(self.model, mujoco.mjtObj.mjOBJ_JOINT, name)
                out.append((name, rb.T @ (d.xanchor[j] - ob), rb.T @ d.xaxis[j]))
            return out


# Held weakly, by the model's id: a Kinematics holds its model (its MjData does), so a table
# keyed weakly by the model but holding the Kinematics strongly kept every model alive for
# ever (about 65 MB per Gymnasium environment, issue 23). Whoever uses a model for long holds
# its Kinematics (Simulation.kinematics, the environments' ActionMap); while one is held, its
# model is alive and its id cannot be reused.
_instances: weakref.WeakValueDictionary[int, Kinematics] = weakref.WeakValueDictionary()
_instances_lock = threading.Lock()


_default: list[Kinematics] = []


def for_model(model: mujoco.MjModel | None = None) -> Kinematics:
    """The shared :class:`Kinematics` of ``model`` (the shipped model if None).

    The table keeps none alive (nor its model): hold the result to reuse it; one nobody holds
    is made again (about half a millisecond).
    """
    if model is None:
        if not _default:  # load_model() checks the file each call: too slow for every IK
            _default.append(for_model(load_model()))
        return _default[0]
    m = model
    with _instances_lock:
        kin = _instances.get(id(m))
        if kin is None or kin.model is not m:
            kin = _instances[id(m)] = Kinematics(m)
    return kin


def tip_pose(pose: Pose | np.ndarray, model: mujoco.MjModel | None = None) -> TipPose:
    """Where the tip is for ``pose`` (a dict in the arm's units: degrees, gripper 0-100;
    LeRobot's ``"name.pos"`` keys too; or an array of six in that order).

    Raises:
        JointNameError, JointValueError, JointLimitError: the pose is not a valid pose.
        ModelError: the model lacks the ``gripperframe``/``baseframe`` sites.
    """
    kin = for_model(model)
    return kin.tip_array(kin.pose_values(pose))


def tip_positions(values: np.ndarray, model: mujoco.MjModel | None = None) -> np.ndarray:
    """Tip positions ``(n, 3)`` (metres, base frame) for ``(n, 6)`` joint values in arm units,
    e.g. a move's commanded targets or the measured joint angles of a run."""
    return for_model(model).tip_positions(values)
