"""The simulated follower's table-top scene between takes, and where to find a follower.

**Finding a follower.** LeRobot gives a teleoperator no handle on the robot it drives, so a
teleoperator that must read the robot's simulation (the scripted expert of the LeRobot
plugin, ``--teleop.type=so101_sim_expert``) finds it here: every
:class:`~so101sim.robot.SO101SimFollower` is in this process-level registry from its
``connect()`` to its ``disconnect()`` (weakly: a dropped robot leaves it).
:func:`connected_followers` lists them, :func:`find_follower` picks the one with a given scene
preset, and :func:`when_connected` calls a function for each follower that connects later
(``lerobot-record`` connects the teleoperator before the robot).

**Resetting the scene.** :class:`RobotScene` (:func:`robot_scene` gives a follower's) puts
the arm back at its start pose (the follower's ``initial_pose``, at rest) and the scene's
objects at poses drawn from a seed, as :meth:`so101sim.envs.So101TaskEnv.reset` draws them for
the same seed (a NumPy generator seeded with it, :func:`so101sim.scenes.sample_placements`).
Simulated time goes on (it never goes back; the lockstep clock keeps counting).
:meth:`RobotScene.request_reset` asks for a reset that is made just before the follower's next
observation (the follower's ``get_observation`` calls :func:`before_observation`), so the
first frame of a take already shows its new start.
"""

from __future__ import annotations

import logging
import threading
import weakref
from collections.abc import Callable
from typing import Any

import numpy as np

from ..errors import DeviceNotConnectedError, RobotConfigError
from ..model.arm import load_profile
from ..scenes import (
    SCENE_PRESETS,
    Placement,
    SceneRandomizer,
    TableScene,
    object_qpos,
    place_objects,
    randomization,
    sample_placements,
    scene_of,
)
from ..validation import check_count

log = logging.getLogger(__name__)

MAX_SEED = 2**63 - 1
MAX_DISTANCE_M = 10.0
"""Object positions in :meth:`RobotScene.environment_state` are clipped to this (metres), as
the environments clip theirs."""

_lock = threading.Lock()
_connected: weakref.WeakSet[Any] = weakref.WeakSet()
_order: weakref.WeakKeyDictionary[Any, int] = weakref.WeakKeyDictionary()
_listeners: list[Callable[[Any], None]] = []
_scenes: weakref.WeakKeyDictionary[Any, RobotScene] = weakref.WeakKeyDictionary()
_count = 0


# ---------------------------------------------------------------------- the registry
def register(follower: Any) -> None:
    """``follower`` is connected (called by its ``connect()``): add it, tell the listeners."""
    global _count
    with _lock:
        _count += 1
        _connected.add(follower)
        _order[follower] = _count
        listeners = list(_listeners)
    for fn in listeners:
        try:
            fn(follower)
        except Exception:  # a listener's mistake must not fail the robot's connect()
            log.exception("so101sim: a listener of connecting followers failed")


def unregister(follower: Any) -> None:
    """``follower`` is disconnected (called by its ``disconnect()``)."""
    with _lock:
        _connected.discard(follower)


def connected_followers() -> list[Any]:
    """The followers connected now in this process, in the order they connected."""
    with _lock:
        return sorted(_connected, key=lambda f: _order.get(f, 0))


def when_connected(fn: Callable[[Any], None]) -> Callable[[], None]:
    """Call ``fn(follower)`` for each follower that connects from now on; returns the
    function that stops it."""
    with _lock:
        _listeners.append(fn)

    def stop() -> None:
        with _lock:
            if fn in _listeners:
                _listeners.remove(fn)

    return stop


def find_follower(scene: str, *, mode: str | None = None) -> Any:
    """The connected follower whose scene preset is ``scene`` (and whose mode is ``mode``, if
    given): the last one to connect if several.

    Raises:
        DeviceNotConnectedError: no connected follower has that scene (the message says which
            followers are connected and how to make one).
        RobotConfigError: the follower with that scene is not in ``mode``.
    """
    followers = connected_followers()
    found = [f for f in followers if f.config.scene == scene]
    if not found:
        have = ", ".join(f"{f} (scene {f.config.scene!r})" for f in followers) or "none"
        raise DeviceNotConnectedError(
            f"no connected so101sim follower has the scene {scene!r} (connected: {have}); "
            f"expected one made with scene={scene!r} (LeRobot: --robot.type=so101_sim "
            f"--robot.scene={scene}) and connected"
        )
    follower = found[-1]
    if mode is not None and follower.config.mode != mode:
        raise RobotConfigError(
            f"the follower with the scene {scene!r} is in {follower.config.mode!r} mode; "
            f"expected {mode!r} (LeRobot: --robot.mode={mode})"
        )
    return follower


def scene_resets(follower: Any) -> int:
    """How many times ``follower``'s scene has been reset (0: never, or no scene yet): a
    caller that keeps its own clock per take re-anchors it when this changes."""
    scene = _scenes.get(follower)
    return scene.resets if scene is not None else 0


def before_observation(follower: Any) -> None:
    """Make the reset asked for on ``follower``'s scene, if any (called by the follower's
    ``get_observation`` before it reads the state)."""
    scene = _scenes.get(follower)
    if scene is not None:
        if scene.observation_hook is not None:
            scene.observation_hook()  # e.g. a teleoperator that ends its take here
        scene.apply_pending()


# ---------------------------------------------------------------------- the scene
def draw_placements(scene: TableScene, seed: int) -> dict[str, Placement]:
    """The objects' start poses drawn from ``seed``: what
    :meth:`so101sim.envs.So101TaskEnv.reset` draws with ``reset(seed=seed)``."""
    seed = check_count(seed, "seed", maximum=MAX_SEED)
    return sample_placements(scene.objects, np.random.default_rng(seed), scene.keep_out)


class RobotScene:
    """A connected follower's scene preset, reset between takes (see the module's text)."""

    def __init__(self, follower: Any) -> None:
        name = follower.config.scene
        if name is None:
            raise RobotConfigError(
                f"{follower} has no scene; expected a follower made with a scene preset "
                f"({', '.join(SCENE_PRESETS)}), e.g. scene='pick_cube'"
            )
        # weakly: the table of scenes is keyed weakly by the follower, and a value holding its
        # key would keep every follower (and its model) alive for ever
        self._follower = weakref.ref(follower)
        model = follower.simulation.model
        self.scene: TableScene = scene_of(model) or SCENE_PRESETS[name]
        self.placements: dict[str, Placement] = {}
        """The objects' poses at the last reset (x, y metres; yaw degrees)."""
        self.resets = 0
        """How many resets were made."""
        self._pending: int | None = None
        self.randomization: dict[str, Any] = {}
        """What the last reset's domain randomisation drew (the follower's ``randomize``)."""
        self._randomizer: SceneRandomizer | None = None
        self.observation_hook: Callable[[], None] | None = None
        """Called before each of the follower's observations, before a pending reset is made
        (the expert teleoperator sees there that LeRobot began a new episode)."""

    @property
    def follower(self) -> Any:
        """The follower of this scene.

        Raises:
            RobotConfigError: the follower is gone (garbage-collected)."""
        follower = self._follower()
        if follower is None:
            raise RobotConfigError("this scene's follower is gone; expected a live follower")
        return follower

    @property
    def name(self) -> str:
        """The scene preset's name (``pick_cube``, ``cube_to_bowl``)."""
        return str(self.follower.config.scene)

    @property
    def state_size(self) -> int:
        """The length of :meth:`environment_state`: 7 per object."""
        return 7 * len(self.scene.objects)

    def environment_state(self) -> np.ndarray:
        """Each object's position (metres) and quaternion (w, x, y, z), in the scene's order
        (cube, then bowl), float32: what the environments give as ``environment_state``
        (LeRobot: ``observation.environment_state``)."""
        follower = self.follower
        with follower.lock:
            sim = follower.simulation
            parts = [sim.data.qpos[object_qpos(sim.model, o.name)] for o in self.scene.objects]
            state = np.concatenate(parts).astype(np.float32)
        bound = np.tile(np.r_[np.full(3, MAX_DISTANCE_M), np.ones(4)], len(self.scene.objects))
        return np.clip(state, -bound, bound).astype(np.float32)

    @property
    def pending(self) -> int | None:
        """The seed of the reset asked for and not yet made, or None."""
        return self._pending

    def reset(self, seed: int) -> dict[str, Placement]:
        """Now: the arm at its start pose at rest, the objects at poses drawn from ``seed``;
        simulated time goes on. Returns the poses.

        Raises:
            SettingError: ``seed`` is not a whole number from 0 to 2**63 - 1.
        """
        seed = check_count(seed, "seed", maximum=MAX_SEED)
        rng = np.random.default_rng(seed)
        poses = sample_placements(self.scene.objects, rng, self.scene.keep_out)
        follower = self.follower
        sim = follower.simulation
        options = randomization(getattr(follower.config, "randomize", "none"))
        with follower.lock:
            now = sim.data.time
            sim.reset()  # arm at its initial pose, commanded to stay there; objects nominal
            sim.data.time = now  # simulated time never goes back
            place_objects(sim.model, sim.data, poses)
            if options.active:  # drawn after the poses from the same generator, as envs do
                rig = getattr(follower, "_rig", None)
                renders = rig.render_models if rig is not None else []
                if self._randomizer is None:
                    objects = [o.name for o in self.scene.objects]
                    profile = load_profile(getattr(follower.config, "arm", None))
                    self._randomizer = SceneRandomizer(
                        sim.model, objects, options, renders, profile=profile
                    )
                for m in renders:
                    self._randomizer.add_render_model(m)
                self.randomization = self._randomizer.apply(rng, sim.data)
            self._pending = None
        self.placements = poses
        self.resets += 1
        log.debug("%s: scene %s reset from seed %d: %s", self.follower, self.name, seed, poses)
        return poses

    def request_reset(self, seed: int) -> None:
        """Reset from ``seed`` just before the follower's next observation (or at
        :meth:`apply_pending`)."""
        self._pending = check_count(seed, "seed", maximum=MAX_SEED)

    def apply_pending(self) -> bool:
        """Make the reset asked for, if any; whether one was made."""
        seed = self._pending
        if seed is None:
            return False
        self.reset(seed)
        return True


def robot_scene(follower: Any) -> RobotScene:
    """``follower``'s :class:`RobotScene` (one per follower, made on first use).

    Raises:
        RobotConfigError: the follower has no scene preset.
    """
    with _lock:
        scene = _scenes.get(follower)
    if scene is None:
        scene = RobotScene(follower)
        with _lock:
            scene = _scenes.setdefault(follower, scene)
    return scene


__all__ = [
    "MAX_SEED",
    "RobotScene",
    "before_observation",
    "connected_followers",
    "draw_placements",
    "find_follower",
    "register",
    "robot_scene",
    "scene_resets",
    "unregister",
    "when_connected",
]
