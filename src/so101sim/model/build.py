"""The one model builder: a :class:`ModelRecipe` says what model to make (its file, the arm
profile, what is added to it, physics-only or full) and :func:`build` makes it, once.

Everything in so101sim that compiles a model goes through :func:`build`: ``load_model``, the
scenes (a table, objects, cameras: one :class:`Addition`), the preflight's sensor model and the
contact twin (sensors: an :class:`Addition`), the fit's replayer (a profile), the recorder's
draft meshes (an :class:`Addition`, made each time: ``keep=False``) and the servo bench (a
model made by code, not read from a file: a :class:`MadeSpec`). The steps are always the same,
written once here:

    file (or MadeSpec) → MjSpec → arm profile (``apply_profile``) → additions → compile → caches

:func:`compile_spec` is the one call of MuJoCo's compiler in so101sim (the physics-only trim
gets it as an argument; ``tests/test_architecture.py`` fails on a compile anywhere else).

* **Caches.** A recipe whose additions all have a ``key`` is compiled once per process (the
  same :class:`mujoco.MjModel` is returned again: treat it as read-only) and once per content
  across processes (the disk cache, :mod:`so101sim.model.cache`). An addition with no key (a
  scene with randomised objects, an ``extra`` callback) is compiled each time.
* **No re-entrant lock.** The table of built models is guarded by one lock held only to read or
  write it; a model is compiled under its own recipe's lock, so a build that needs another
  model (none does today) cannot deadlock, and two threads asking for the same model compile
  it once.
* **What a model is.** :func:`recipe_of` gives the recipe a model was built from (its servo
  model included: :func:`servo_model` names it for every output), :func:`model_spec` the
  function making its MjSpec again.
"""

from __future__ import annotations

import logging
import threading
import weakref
from collections.abc import Callable
from dataclasses import dataclass, field, replace
from pathlib import Path

import mujoco
import numpy as np

from ..errors import ModelError, So101SimError
from ..validation import check_input_file
from .arm import OFFICIAL, ArmLike, ArmProfile, apply_profile, load_profile, profile_key
from .cache import load_or_compile
from .index import arm_index, scene_path

log = logging.getLogger(__name__)

SpecEdit = Callable[[mujoco.MjSpec], None]


@dataclass(frozen=True)
class Addition:
    """Something added to a model's MjSpec after its arm profile: a scene's table, objects and
    cameras, or sensors. ``key`` names it in the caches (same key, same addition); None: not
    cached (the model is compiled each time it is asked for)."""

    key: str | None
    edit: SpecEdit = field(compare=False, repr=False)


@dataclass(frozen=True)
class MadeSpec:
    """A model made by code rather than read from a file (the servo bench's pendulums):
    ``name`` says what it is in messages, ``make`` returns its MjSpec. Such a recipe is made
    each time it is built (never cached) and is not the SO-101 arm (its joints are not
    checked)."""

    name: str
    make: Callable[[], mujoco.MjSpec] = field(compare=False, repr=False)


@dataclass(frozen=True)
class ModelRecipe:
    """What model to make: ``file`` (an MJCF file, resolved; or a :class:`MadeSpec`, a model
    made by code: :func:`made_recipe`), the arm profile ``arm`` (the
    servos' actuator model; ``arm_key`` is ``""`` for the file's own actuators), the
    ``additions`` (scene, cameras, sensors) and whether it is the ``physics_only`` model (no
    visual geoms, convex collision meshes: :mod:`so101sim.model.trim`); ``keep=False``: made
    each time it is asked for, in neither cache (a one-off profile such as a fit's)."""

    file: Path | MadeSpec
    arm: ArmProfile = field(compare=False)
    arm_key: str = ""
    additions: tuple[Addition, ...] = ()
    physics_only: bool = False
    keep: bool = True  # False: a one-off model (a fit's profile), kept in neither cache

    @property
    def cacheable(self) -> bool:
        made = isinstance(self.file, MadeSpec)
        return self.keep and not made and all(a.key is not None for a in self.additions)

    @property
    def path(self) -> Path | None:
        """The MJCF file of this recipe; None for a model made by code (:class:`MadeSpec`)."""
        return self.file if isinstance(self.file, Path) else None

    @property
    def what(self) -> str:
        """This recipe's source in words, for messages."""
        if isinstance(self.file, MadeSpec):
            return f"the {self.file.name} model"
        return f"model file {str(self.file)!r}"

    def with_additions(self, *more: Addition) -> ModelRecipe:
        """This recipe with ``more`` added after its own additions."""
        return replace(self, additions=self.additions + more)

    def spec(self) -> mujoco.MjSpec:
        """A fresh MjSpec of this recipe (the file, the profile, the additions)."""
        try:
            if isinstance(self.file, MadeSpec):
                spec = self.file.make()
            else:
                spec = mujoco.MjSpec.from_file(str(self.file))
        except (ValueError, mujoco.FatalError) as exc:
            raise ModelError(f"{self.what} does not compile: {exc}") from exc
        if self.arm_key:  # "": the file's own actuators, as they are
            apply_profile(spec, self.arm)
        for addition in self.additions:
            addition.edit(spec)
        return spec


def recipe(
    file: str | Path | None = None,
    *,
    arm: ArmLike = None,
    additions: tuple[Addition, ...] = (),
    physics_only: bool = False,
    keep: bool = True,
) -> ModelRecipe:
    """A checked :class:`ModelRecipe`: ``file`` (None: the shipped ``scene.xml``) must be a
    readable file and ``arm`` a profile (None: the default, ``sts3215``).

    Raises:
        ModelError: the file is missing, a folder, empty, ...
        ProfileError: ``arm`` names no profile or holds invalid values.
    """
    prof = load_profile(arm)
    if file is None:
        p = scene_path()
    else:  # empty, too long, missing, a folder, a device: one line saying so, no OSError
        expected = f"an MJCF file such as the shipped {str(scene_path())!r}"
        p = check_input_file(file, "model file", expected=expected, error=ModelError)
    key = profile_key(prof)
    return ModelRecipe(p.resolve(), prof, key, tuple(additions), physics_only, keep)


def made_recipe(
    name: str, make: Callable[[], mujoco.MjSpec], *, arm: ArmLike = OFFICIAL
) -> ModelRecipe:
    """The recipe of a model made by code (:class:`MadeSpec`): ``make`` builds its whole spec
    (``arm``: the profile its maker applied itself, for :func:`recipe_of`; the builder applies
    none); built each time, in no cache."""
    return ModelRecipe(MadeSpec(name, make), load_profile(arm), "", (), False, keep=False)


def compile_spec(spec: mujoco.MjSpec) -> mujoco.MjModel:
    """Compile ``spec``: the one call of MuJoCo's compiler in so101sim (every model is built
    by :func:`build`; the physics-only trim gets this function from it)."""
    return spec.compile()


_lock = threading.Lock()  # guards the tables below; never held while compiling
_built: dict[tuple[object, ...], mujoco.MjModel] = {}
_building: dict[tuple[object, ...], threading.Lock] = {}
_recipes: weakref.WeakKeyDictionary[mujoco.MjModel, ModelRecipe] = weakref.WeakKeyDictionary()


def _key(r: ModelRecipe) -> tuple[object, ...]:
    mtime = r.file.stat().st_mtime_ns
    return (str(r.file), mtime, r.physics_only, r.arm_key, tuple(a.key for a in r.additions))


def build(r: ModelRecipe) -> mujoco.MjModel:
    """The model of recipe ``r``: compiled once per process and content when it is cacheable
    (see the module), else compiled now.

    Raises:
        ModelError: the file does not compile or lacks the SO-101 joints.
        SettingError, CameraError: an addition refused the spec (e.g. a name taken).
    """
    if not r.cacheable:
        model = _compile(r)
        with _lock:
            _recipes[model] = r
        return model
    key = _key(r)
    with _lock:
        model = _built.get(key)
        if model is not None:
            return model
        gate = _building.setdefault(key, threading.Lock())
    with gate:  # one compile per recipe; other recipes compile meanwhile
        with _lock:
            model = _built.get(key)
        if model is None:
            model = _compile(r, cached=True)
            with _lock:
                _built[key] = model
                _recipes[model] = r
                _building.pop(key, None)
    return model


def _compile(r: ModelRecipe, *, cached: bool = False) -> mujoco.MjModel:
    plain = r.path is not None and not r.arm_key and not r.additions

    def compile_fn() -> mujoco.MjModel:
        if plain:  # the file exactly as MuJoCo's own loader compiles it
            return mujoco.MjModel.from_xml_path(str(r.file))
        return compile_spec(r.spec())

    variant = r.arm_key + "".join(f"+{a.key}" for a in r.additions)
    try:
        if cached:
            model = load_or_compile(
                r.file,  # type: ignore[arg-type]  # a cached recipe has a file (cacheable)
                compile_fn,
                variant=variant,
                physics_only=r.physics_only,
                spec_fn=r.spec,
                compile_spec=compile_spec,
            )
        else:
            model = compile_fn()
    except So101SimError:  # an addition's own error (a camera given twice) says it best
        raise
    except (ValueError, mujoco.FatalError) as exc:
        raise ModelError(f"{r.what} does not compile: {exc}") from exc
    if r.path is not None:  # the arm (a MadeSpec, the servo bench, is not)
        arm_index(model)  # fail now, not at the first command, if joints are missing
    log.debug("built %s with arm profile %s (nq=%d)", r.what, r.arm.name, model.nq)
    return model


def recipe_of(model: mujoco.MjModel) -> ModelRecipe | None:
    """The recipe :func:`build` made ``model`` from, or None (a model compiled another way,
    or a copy)."""
    with _lock:
        return _recipes.get(model)


def model_spec(model: mujoco.MjModel) -> Callable[[], mujoco.MjSpec] | None:
    """How ``model``'s MjSpec is made again (see :meth:`ModelRecipe.spec`), if :func:`build`
    made it; else None."""
    r = recipe_of(model)
    return r.spec if r is not None else None


def built_models() -> list[tuple[ModelRecipe, mujoco.MjModel]]:
    """``(recipe, model)`` for every cached full model built in this process."""
    with _lock:
        return [(_recipes[m], m) for m in _built.values() if m in _recipes]


_SAME = (
    "body_mass", "body_pos", "geom_size", "jnt_range", "dof_damping", "dof_armature",
    "actuator_gainprm", "actuator_biasprm", "actuator_forcerange", "actuator_dyntype",
)  # fmt: skip


def _equal(a: mujoco.MjModel, b: mujoco.MjModel) -> bool:
    sizes = ("nq", "nv", "nu", "na", "nbody", "ngeom", "nmesh", "nsensor")
    if any(getattr(a, n) != getattr(b, n) for n in sizes) or a.opt.timestep != b.opt.timestep:
        return False
    return all(np.array_equal(getattr(a, n), getattr(b, n)) for n in _SAME)


def recognise(model: mujoco.MjModel) -> ModelRecipe | None:
    """The recipe ``model`` was built from; for a model compiled elsewhere (the lab handout's
    ``mujoco.MjModel.from_xml_path(scene.xml)``, a copy), the recipe of a plain model the
    builder made that it equals (sizes, masses, geometry, joint ranges, actuators, timestep):
    the shipped ``scene.xml`` with its own actuators first. None: not one so101sim can name."""
    own = recipe_of(model)
    if own is not None:
        return own
    shipped = recipe(arm=OFFICIAL)
    candidates = [(shipped, build(shipped)), *built_models()]
    for r, built in candidates:
        if r.path is None:
            continue
        if not r.additions and not r.physics_only and _equal(model, built):
            return r
    return None


def servo_name(model: mujoco.MjModel) -> str:
    """The short name of ``model``'s servo model: its profile's name, ``"official"`` (the
    file's own actuators) or ``"unknown"`` (see :func:`servo_model`)."""
    r = recognise(model)
    if r is None:
        return "unknown"
    return r.arm.name if r.arm_key else OFFICIAL


def servo_model(model: mujoco.MjModel | None = None, arm: ArmLike = None) -> str:
    """The servo model a run used, in words, for every output to name, e.g. ``"sts3215
    (STS3215 fitted on a real servo bench ...)"`` or ``"official (the model file's own ideal
    position actuators)"`` (a model compiled elsewhere is named when :func:`recognise` knows
    it). ``arm``: the profile, when no model is at hand."""
    if model is not None:
        r = recognise(model)
        if r is None:
            return "unknown (a model so101sim cannot name: its own actuators)"
        prof, key = r.arm, r.arm_key
    else:
        prof = load_profile(arm)
        key = profile_key(prof)
    if not key:
        return f"{OFFICIAL} (the model file's own ideal position actuators)"
    return f"{prof.name} ({prof.description or 'an arm profile'})"


__all__ = [
    "Addition",
    "ArmLike",
    "MadeSpec",
    "ModelRecipe",
    "SpecEdit",
    "build",
    "built_models",
    "compile_spec",
    "made_recipe",
    "model_spec",
    "recipe",
    "recipe_of",
    "recognise",
    "servo_model",
    "servo_name",
]
