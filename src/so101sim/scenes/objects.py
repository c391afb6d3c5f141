"""What a table-top scene holds: the table (or the bare floor), objects (boxes, cylinders,
spheres, and a bowl or open box as a target), and the contact settings that let the SO-101's
gripper hold them.

Everything here is a frozen dataclass in metres, kilograms and degrees, validated with
:mod:`so101sim.validation` bounds before it sizes anything; :mod:`so101sim.scenes.build` adds
them to the model with ``mujoco.MjSpec`` (the vendored files are never edited).

Positions are in the arm's base frame (x forward, y to the arm's left, z up; the table top is
z = 0, where the arm's base stands). An object stands on the table at ``pos`` turned by ``yaw``
about the vertical; with ``x_range``/``y_range``/``yaw_range`` its start pose is drawn from a
seed instead (:func:`so101sim.scenes.sample_placements`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Literal, get_args

from ..errors import SettingError
from ..validation import check_choice, check_count, check_range

ObjectShape = Literal["box", "cylinder", "sphere", "bowl", "open_box", "mesh", "mark"]
"""Object shapes: solid ``box``, ``cylinder``, ``sphere``; containers ``bowl`` (round, with a
wall of flat segments) and ``open_box`` (a tray); ``mesh``, a convex mesh generated at load
time (an octagonal prism with a chamfered top, like a nut: :func:`so101sim.scenes.parts.
mesh_vertices`); ``mark``, a flat disc that only shows a place on the table (it touches
nothing and floats where it is put: a goal)."""
SHAPES: tuple[str, ...] = get_args(ObjectShape)
"""The object shapes (:data:`ObjectShape`), the list the objects are checked against."""
CONTAINERS = ("bowl", "open_box")
"""Shapes that are targets to put things in: a floor and walls, open at the top."""
Surface = Literal["table", "floor"]
"""What the arm and the objects stand on: a table (a box whose top is z = 0, the floor below
it) or the shipped floor plane itself."""
SURFACES: tuple[str, ...] = get_args(Surface)
MARKS = ("mark",)
"""Shapes that touch nothing (goals drawn on the table)."""
Cone = Literal["elliptic", "pyramidal"]
"""MuJoCo's friction cone for the scene's contacts."""
CONES: tuple[str, ...] = get_args(Cone)

MIN_SIZE_M, MAX_SIZE_M = 0.005, 0.5
MIN_MARK_M = 0.0005
"""A mark may be as thin as this (metres): it only shows a place."""
MIN_MASS_KG, MAX_MASS_KG = 0.001, 5.0
MAX_OBJECTS = 32
MAX_REACH_M = 1.0
"""Objects and tables are placed within this distance of the base (metres)."""


def _vector(value: object, what: str, n: tuple[int, ...]) -> tuple[float, ...]:
    """``value`` as a tuple of floats if it holds one of the lengths ``n``."""
    try:
        items = tuple(value)  # type: ignore[arg-type]
    except TypeError:
        items = None
    if items is None or len(items) not in n or isinstance(value, str):
        sizes = " or ".join(str(k) for k in n)
        raise SettingError(f"{what} = {value!r}; expected a list of {sizes} numbers")
    return tuple(check_range(x, what) for x in items)


def _range(value: tuple[float, float] | None, what: str, low: float, high: float):
    if value is None:
        return None
    lo, hi = _vector(value, what, (2,))
    for v in (lo, hi):
        check_range(v, what, low=low, high=high)
    if lo > hi:
        raise SettingError(f"{what} = {value!r} is invalid; expected [low, high] with low <= high")
    return (lo, hi)


def _rgba(value: object, what: str) -> tuple[float, float, float, float]:
    v = _vector(value, what, (3, 4))
    for x in v:
        check_range(x, what, low=0.0, high=1.0, expected="numbers from 0 to 1")
    return (*v, 1.0) if len(v) == 3 else v  # type: ignore[return-value]


@dataclass(frozen=True)
class SceneObject:
    """An object on the table: a free body the arm can push, grasp and carry.

    ``size`` in metres: ``box`` and ``open_box`` (x, y, z) edge lengths (one number: a cube);
    ``cylinder``, ``bowl`` and ``mark`` (diameter, height); ``sphere`` (diameter,); ``mesh``
    (width across the octagon's flats, height). ``mass`` in kg,
    ``rgba`` its colour, ``friction`` its sliding friction coefficient (the contact with the
    gripper's pads or the table uses the larger of the two). ``wall`` is a container's wall and
    floor thickness."""

    name: str
    shape: ObjectShape = "box"
    size: tuple[float, ...] = (0.025, 0.025, 0.025)
    mass: float = 0.03
    rgba: tuple[float, ...] = (0.85, 0.15, 0.1, 1.0)
    friction: float = 1.0
    pos: tuple[float, float] = (0.25, 0.0)
    yaw: float = 0.0
    x_range: tuple[float, float] | None = None
    y_range: tuple[float, float] | None = None
    yaw_range: tuple[float, float] | None = None
    wall: float = 0.004

    def validated(self) -> SceneObject:
        """A copy with every field checked and normalised (sizes as full tuples), or a
        SettingError saying what to use."""
        name = self.name
        if not isinstance(name, str) or not name.isidentifier():
            raise SettingError(
                f"object name {name!r} is not valid; expected letters, digits and underscores, "
                "such as 'cube'"
            )
        w = f"object {name!r}"
        shape = check_choice(self.shape, f"{w} shape", SHAPES)
        size = _size(shape, self.size, f"{w} size")
        mass = check_range(self.mass, f"{w} mass", low=MIN_MASS_KG, high=MAX_MASS_KG, unit=" kg")
        wall = check_range(self.wall, f"{w} wall", low=0.001, high=0.05, unit=" m")
        if shape in CONTAINERS and 2 * wall >= min(size[:-1]) - 0.005:
            raise SettingError(
                f"{w}: wall = {wall} m leaves no room inside; expected a thinner wall"
            )
        pos = _vector(self.pos, f"{w} pos", (2,))
        for v in pos:
            check_range(v, f"{w} pos", low=-MAX_REACH_M, high=MAX_REACH_M, unit=" m")
        return SceneObject(
            name=name,
            shape=shape,
            size=size,
            mass=mass,
            rgba=_rgba(self.rgba, f"{w} rgba"),
            friction=check_range(self.friction, f"{w} friction", low=0.05, high=5.0),
            pos=pos,  # type: ignore[arg-type]
            yaw=check_range(self.yaw, f"{w} yaw", low=-360, high=360, unit="°"),
            x_range=_range(self.x_range, f"{w} x_range", -MAX_REACH_M, MAX_REACH_M),
            y_range=_range(self.y_range, f"{w} y_range", -MAX_REACH_M, MAX_REACH_M),
            yaw_range=_range(self.yaw_range, f"{w} yaw_range", -360, 360),
            wall=wall,
        )

    @property
    def height(self) -> float:
        """How tall it stands on the table (metres)."""
        return self.size[-1]

    @property
    def radius(self) -> float:
        """The radius of the smallest vertical cylinder around it (metres): how far apart two
        objects' centres must be so that they cannot overlap."""
        if self.shape in ("box", "open_box"):
            return math.hypot(self.size[0], self.size[1]) / 2
        if self.shape == "mesh":  # across the octagon's corners
            return self.size[0] / 2 / math.cos(math.pi / 8)
        return self.size[0] / 2


def _size(shape: str, value: object, what: str) -> tuple[float, ...]:
    n = {
        "box": (1, 3),
        "open_box": (1, 3),
        "cylinder": (2,),
        "bowl": (2,),
        "sphere": (1,),
        "mesh": (2,),
        "mark": (2,),
    }[shape]
    if not isinstance(value, (list, tuple)) and n[0] == 1:
        value = (value,)
    v = _vector(value, what, n)
    low = MIN_MARK_M if shape in MARKS else MIN_SIZE_M
    for x in v:
        check_range(x, what, low=low, high=MAX_SIZE_M, unit=" m")
    return (v[0], v[0], v[0]) if shape in ("box", "open_box") and len(v) == 1 else v


@dataclass(frozen=True)
class Table:
    """What the arm stands on. ``surface="table"``: a table top ``size`` (x, y metres) centred
    at ``center``, its top at z = 0 (the base's height), ``height`` above the floor (which is
    moved down to meet its legs' end); ``"floor"``: the shipped floor plane, nothing added."""

    surface: Surface = "table"
    size: tuple[float, float] = (0.7, 0.9)
    center: tuple[float, float] = (0.2, 0.0)
    height: float = 0.75
    rgba: tuple[float, ...] = (0.62, 0.5, 0.38, 1.0)
    friction: float = 0.8

    def validated(self) -> Table:
        """A copy with every field checked, or a SettingError saying what to use."""
        surface = check_choice(self.surface, "table surface", SURFACES)
        size = _vector(self.size, "table size", (2,))
        for v in size:
            check_range(v, "table size", low=0.2, high=2 * MAX_REACH_M, unit=" m")
        center = _vector(self.center, "table center", (2,))
        for v in center:
            check_range(v, "table center", low=-MAX_REACH_M, high=MAX_REACH_M, unit=" m")
        return Table(
            surface=surface,
            size=size,  # type: ignore[arg-type]
            center=center,  # type: ignore[arg-type]
            height=check_range(self.height, "table height", low=0.05, high=1.5, unit=" m"),
            rgba=_rgba(self.rgba, "table rgba"),
            friction=check_range(self.friction, "table friction", low=0.05, high=5.0),
        )


@dataclass(frozen=True)
class ContactSettings:
    """How objects touch the gripper, the table and each other (see docs/tasks.md for how
    these were chosen and what they give).

    * ``condim`` 4: sliding friction plus torsional friction about the contact normal, so an
      object pinched by the jaws does not spin about the pinch axis;
    * ``solref`` (time constant s, damping ratio) and ``solimp``: stiff, well-damped contacts
      (the time constant at least twice the 2 ms timestep);
    * ``cone`` elliptic with ``impratio`` > 1: friction enforced more firmly than the normal
      force, which stops slow creep in a held grasp;
    * ``pad_friction``: the jaw pads' sliding friction (rubbery printed fingertips);
    * ``torsional``/``rolling``: the secondary friction coefficients (metres).

    They apply only to objects, the table and the jaw pads, and the cone and impratio only in
    scenes that have objects: the arm alone moves exactly as in the shipped scene.
    """

    condim: int = 4
    solref: tuple[float, float] = (0.004, 1.0)
    solimp: tuple[float, ...] = (0.99, 0.999, 0.001, 0.5, 2.0)
    cone: Cone = "elliptic"
    impratio: float = 10.0
    pad_friction: float = 1.5
    torsional: float = 0.01
    rolling: float = 0.0001
    noslip_iterations: int = 0

    def validated(self) -> ContactSettings:
        """A copy with every field checked, or a SettingError saying what to use."""
        condim = check_count(self.condim, "contact condim", minimum=1, maximum=6)
        if condim not in (1, 3, 4, 6):
            raise SettingError(f"contact condim = {condim} is invalid; expected 1, 3, 4 or 6")
        ref = _vector(self.solref, "contact solref", (2,))
        check_range(ref[0], "contact solref time constant", low=0.001, high=1.0, unit=" s")
        check_range(ref[1], "contact solref damping ratio", low=0.1, high=10.0)
        imp = _vector(self.solimp, "contact solimp", (3, 5))
        for v in imp[:2]:
            check_range(v, "contact solimp", low=0.0001, high=0.9999)
        return ContactSettings(
            condim=condim,
            solref=ref,  # type: ignore[arg-type]
            solimp=imp,
            cone=check_choice(self.cone, "contact cone", CONES),
            impratio=check_range(self.impratio, "contact impratio", low=1.0, high=1000.0),
            pad_friction=check_range(self.pad_friction, "pad friction", low=0.05, high=5.0),
            torsional=check_range(self.torsional, "torsional friction", low=0.0, high=0.1),
            rolling=check_range(self.rolling, "rolling friction", low=0.0, high=0.1),
            noslip_iterations=check_count(self.noslip_iterations, "noslip_iterations", maximum=100),
        )
