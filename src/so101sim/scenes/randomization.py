"""Domain randomisation's settings: the families (:class:`Randomization`), the presets
(``none``, ``light``, ``full``), and what a user writes for them (a preset, a dict, or a
command line's ``light,textures=0.5``: :func:`randomization`, :func:`parse_spec`). What a draw
does to a scene is :mod:`.randomize`'s job; what a family adds to a scene when it is built
(distractor boxes, textures: :func:`scene_additions`) is here.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import asdict, dataclass, fields, replace
from typing import Any

import mujoco

from ..errors import SettingError
from ..model.arm import MAX_SIGMAS
from ..validation import check_count, check_range

MAX_DISTRACTORS = 8
DISTRACTOR_PREFIX = "distractor_"
PARKED_M = (1.5, 1.5)
"""Where unused distractors wait (x, y metres on the floor, out of every camera's view)."""
TEXTURES = ("checker", "gradient", "speckle")
"""The textures the ``textures`` family draws from (materials named ``TEXTURE_PREFIX + kind``)."""
TEXTURE_PREFIX = "so101sim_texture_"


@dataclass(frozen=True)
class Randomization:
    """How much each family varies from episode to episode (see the module's text)."""

    lighting: float = 0.0
    colors: float = 0.0
    camera_m: float = 0.0
    camera_fovy_deg: float = 0.0
    object_size: float = 0.0
    object_mass: float = 0.0
    friction: float = 0.0
    distractors: int = 0
    textures: float = 0.0
    actuators: float = 0.0
    actuator_sigmas: float = 0.0

    def validated(self) -> Randomization:
        """A checked copy, or a SettingError naming the family and its bounds."""
        share = {"low": 0.0, "high": 0.5}
        return Randomization(
            lighting=check_range(self.lighting, "randomize lighting", low=0.0, high=0.9),
            colors=check_range(self.colors, "randomize colors", low=0.0, high=1.0),
            camera_m=check_range(self.camera_m, "randomize camera_m", low=0.0, high=0.1),
            camera_fovy_deg=check_range(
                self.camera_fovy_deg, "randomize camera_fovy_deg", low=0.0, high=20.0
            ),
            object_size=check_range(self.object_size, "randomize object_size", **share),
            object_mass=check_range(self.object_mass, "randomize object_mass", **share),
            friction=check_range(self.friction, "randomize friction", **share),
            distractors=int(
                check_count(self.distractors, "randomize distractors", maximum=MAX_DISTRACTORS)
            ),
            textures=check_range(self.textures, "randomize textures", low=0.0, high=1.0),
            actuators=check_range(self.actuators, "randomize actuators", **share),
            actuator_sigmas=check_range(
                self.actuator_sigmas, "randomize actuator_sigmas", low=0.0, high=MAX_SIGMAS
            ),
        )

    @property
    def active(self) -> bool:
        return any(bool(getattr(self, f.name)) for f in fields(self))


PRESETS: dict[str, Randomization] = {
    "none": Randomization(),
    "light": Randomization(
        lighting=0.2,
        colors=0.08,
        camera_m=0.01,
        camera_fovy_deg=2.0,
        object_size=0.08,
        object_mass=0.2,
        friction=0.1,
        distractors=0,
        actuators=0.05,
        actuator_sigmas=0.5,
    ),
    "full": Randomization(
        lighting=0.5,
        colors=0.25,
        camera_m=0.03,
        camera_fovy_deg=5.0,
        object_size=0.2,
        object_mass=0.5,
        friction=0.3,
        distractors=3,
        textures=0.5,
        actuators=0.15,
        actuator_sigmas=1.0,
    ),
}
"""The named presets (``--randomize none|light|full``)."""


def randomization(value: str | Randomization | Mapping[str, Any] | None) -> Randomization:
    """A preset's name, a :class:`Randomization`, or a dict of families (over ``none``, or
    over a preset named by its ``preset`` key) as a checked :class:`Randomization`.

    Raises:
        SettingError: an unknown preset or family, or a value out of its bounds.
    """
    if value is None:
        return PRESETS["none"]
    if isinstance(value, Randomization):
        return value.validated()
    if isinstance(value, str):
        value = value.strip()
        if "=" in value or "," in value:
            return randomization(parse_spec(value))
        if value not in PRESETS:
            raise SettingError(
                f"randomize = {value!r}; expected one of {', '.join(PRESETS)}, a preset with "
                "families changed ('light,textures=0.5,distractors=2') or a dict of families "
                f"({', '.join(f.name for f in fields(Randomization))})"
            )
        return PRESETS[value]
    if isinstance(value, Mapping):
        items = dict(value)
        base = randomization(items.pop("preset", "none"))
        known = {f.name for f in fields(Randomization)}
        unknown = sorted(set(items) - known)
        if unknown:
            raise SettingError(
                f"randomize has no family {unknown[0]!r}; expected {', '.join(sorted(known))}"
            )
        return replace(base, **items).validated()
    raise SettingError(f"randomize = {value!r}; expected none, light, full or a dict of families")


def parse_spec(text: str) -> dict[str, Any]:
    """``"light,textures=0.5,distractors=2"`` (a preset, then families; or families alone, over
    ``none``) as the dict :func:`randomization` takes: what ``--randomize`` accepts on the
    command lines (``so101sim dataset``/``eval``, ``--robot.randomize``, ``--env.randomize``).

    Raises:
        SettingError: a part that is neither a preset nor ``family=number``.
    """
    out: dict[str, Any] = {}
    for i, part in enumerate(p.strip() for p in text.split(",")):
        if "=" not in part:
            if i == 0 and part in PRESETS:
                out["preset"] = part
                continue
            raise SettingError(
                f"randomize {text!r}: {part!r} is not family=number; expected a preset "
                f"({', '.join(PRESETS)}) first, then family=number parts, e.g. "
                "'light,textures=0.5,distractors=2'"
            )
        key, _, raw = (x.strip() for x in part.partition("="))
        try:
            number = float(raw)
        except ValueError:
            raise SettingError(
                f"randomize {text!r}: {key} = {raw!r} is not a number; expected e.g. {key}=0.2"
            ) from None
        if key in out:
            raise SettingError(f"randomize {text!r} gives {key} twice; expected each family once")
        out[key] = int(number) if key == "distractors" and number.is_integer() else number
    return out


def describe(options: Randomization) -> dict[str, Any]:
    """The options as plain numbers (a dataset's metadata)."""
    return asdict(options)


def add_distractors(spec: mujoco.MjSpec, count: int) -> None:
    """Add ``count`` distractor boxes (free bodies that touch the arm, the table, the floor and
    the objects, as objects do) to ``spec``, parked off the table."""
    for i in range(count):
        body = spec.worldbody.add_body(
            name=f"{DISTRACTOR_PREFIX}{i}", pos=[PARKED_M[0] + 0.1 * i, PARKED_M[1], 0.02]
        )
        body.add_freejoint(name=f"{DISTRACTOR_PREFIX}{i}_joint")
        body.add_geom(
            name=f"{DISTRACTOR_PREFIX}{i}_geom",
            type=mujoco.mjtGeom.mjGEOM_BOX,
            size=[0.015, 0.015, 0.015],
            mass=0.02,
            rgba=[0.2, 0.45, 0.8, 1.0],
            contype=2,
            conaffinity=3,
            condim=4,
        )


def add_textures(spec: mujoco.MjSpec) -> None:
    """Add the :data:`TEXTURES` (64×64 white and grey 2-D textures, twice across each face) and a
    material of each to ``spec``, for the ``textures`` family; no geom uses them until a draw."""
    builtin = {
        "checker": mujoco.mjtBuiltin.mjBUILTIN_CHECKER,
        "gradient": mujoco.mjtBuiltin.mjBUILTIN_GRADIENT,
        "speckle": mujoco.mjtBuiltin.mjBUILTIN_FLAT,
    }
    for kind in TEXTURES:
        name = f"{TEXTURE_PREFIX}{kind}"
        tex = spec.add_texture(name=name, type=mujoco.mjtTexture.mjTEXTURE_2D, width=64, height=64)
        tex.builtin = builtin[kind]
        tex.rgb1 = [1.0, 1.0, 1.0]
        tex.rgb2 = [0.55, 0.55, 0.55]
        if kind == "speckle":
            tex.mark = mujoco.mjtMark.mjMARK_RANDOM
            tex.random = 0.25
            tex.markrgb = [0.5, 0.5, 0.5]
        mat = spec.add_material(name=name, texrepeat=[2.0, 2.0])
        mat.textures[mujoco.mjtTextureRole.mjTEXROLE_RGB] = name


def scene_additions(options: Randomization) -> Callable[[mujoco.MjSpec], None] | None:
    """What a scene must be built with for ``options`` (the distractor boxes, the textures), as
    ``build_model``'s ``extra``; None when nothing."""
    o = options.validated()
    if not o.distractors and not o.textures:
        return None

    def extra(spec: mujoco.MjSpec) -> None:
        if o.distractors:
            add_distractors(spec, o.distractors)
        if o.textures:
            add_textures(spec)

    return extra


__all__ = [
    "DISTRACTOR_PREFIX",
    "MAX_DISTRACTORS",
    "PRESETS",
    "TEXTURES",
    "TEXTURE_PREFIX",
    "Randomization",
    "add_distractors",
    "add_textures",
    "describe",
    "parse_spec",
    "randomization",
    "scene_additions",
]
