"""``so101sim record --arm NAME``: the servo model for a script that compiles its own model.

The lab handout's scripts compile ``scene.xml`` themselves (``mujoco.MjModel.from_xml_path``):
that model has the file's own actuators (``official``), and MuJoCo's loader is not changed.
With ``--arm``, the script's model is recognised (:func:`so101sim.model.build.recognise`: the
shipped ``scene.xml``, or a model so101sim built) and its ``(m, d)`` follow a **shadow**: the
model builder's model of the same file with the profile, and its own data. The script keeps
its objects; what it sees is the shadow's physics:

* the lab helpers (``so101sim.lab``) and the recorder run on the shadow (:func:`attached`),
  taking the script's pose and targets before each call and writing the result back after it
  (``d.time``, ``qpos``, ``qvel``, ``ctrl``; then ``mj_forward`` on the script's model);
* a raw loop (``mj_step(m, d)``, then ``viewer.sync()``) is followed at each ``sync``: the
  shadow takes the same steps with the script's ``d.ctrl`` and its state is written back, so
  the next step of the script starts where the profile's servos put the arm (a pose the
  script writes into ``d.qpos`` between steps of such a loop is overwritten).

A model it cannot name (an edited file) runs with its own actuators, and a model the script
loaded through so101sim (``load_model``, ``Simulation``: the profile it asked for, by default
``sts3215``) keeps its profile; either is said once, as is each change of what the script would
get (``say``: the CLI prints it; else logged).
"""

from __future__ import annotations

import contextlib
import logging
import weakref
from collections.abc import Callable, Iterator
from contextvars import ContextVar
from dataclasses import replace

import mujoco
import numpy as np

from ..model.arm import ArmLike, fill_delay_history, load_profile, profile_key
from ..model.build import build, recipe_of, recognise, servo_model
from ..sim.simulation import Simulation
from ..sim.stepping import advance_unobserved

log = logging.getLogger(__name__)


class Shadow:
    """The profile's model of a script's ``(m, d)``, with its own data (see the module)."""

    def __init__(self, m: mujoco.MjModel, d: mujoco.MjData, model: mujoco.MjModel) -> None:
        self.m, self.d = m, d
        self.data = mujoco.MjData(model)
        self.sim = Simulation.attach(model, self.data)
        self._pushed: tuple[float, np.ndarray] | None = None
        self.pull()
        self.push()

    def _unchanged(self) -> bool:
        """Whether the script's data is as the shadow last wrote it (time and pose)."""
        p = self._pushed
        return p is not None and float(self.d.time) == p[0] and np.array_equal(self.d.qpos, p[1])

    def pull(self) -> None:
        """The script's targets, and its state where the script changed it (a pose it set),
        into the shadow."""
        d, d2, m2 = self.d, self.data, self.sim.model
        d2.ctrl[:] = d.ctrl
        if not self._unchanged():
            d2.time, d2.qpos[:], d2.qvel[:] = d.time, d.qpos, d.qvel
            fill_delay_history(m2, d2)  # the servos act on what is commanded now
        mujoco.mj_forward(m2, d2)

    def push(self) -> None:
        """The shadow's state into the script's data."""
        d, d2 = self.d, self.data
        d.time, d.qpos[:], d.qvel[:], d.ctrl[:] = d2.time, d2.qpos, d2.qvel, d2.ctrl
        mujoco.mj_forward(self.m, d)
        self._pushed = (float(d.time), d.qpos.copy())

    def follow(self) -> None:
        """At a raw loop's ``sync``: the script stepped its own model from the state last
        written; the shadow takes as many steps with the script's targets, and writes back."""
        p, d2 = self._pushed, self.data
        steps = 0
        if p is not None and float(d2.time) == p[0]:
            steps = round((float(self.d.time) - p[0]) / self.sim.model.opt.timestep)
        if steps > 0:
            d2.ctrl[:] = self.d.ctrl
            advance_unobserved(self.sim.model, d2, None, steps)
        else:  # nothing stepped, or the script set its state itself
            self.pull()
        self.push()


class ScriptArm:
    """The arm profile of one ``record --arm`` run and the shadows of the script's models."""

    def __init__(self, arm: ArmLike, say: Callable[[str], None] | None = None) -> None:
        self.profile = load_profile(arm)
        self.key = profile_key(self.profile)
        self.say = say
        self._shadows: weakref.WeakKeyDictionary[mujoco.MjData, Shadow | None] = (
            weakref.WeakKeyDictionary()
        )
        self.said: list[str] = []

    def note(self, text: str) -> None:
        """Say ``text`` once."""
        if text in self.said:
            return
        self.said.append(text)
        if self.say is not None:
            self.say(text)
        else:
            log.warning("%s", text)

    def shadow(self, m: mujoco.MjModel, d: mujoco.MjData) -> Shadow | None:
        """The shadow of ``(m, d)``, made on first use; None where the model already has the
        profile or cannot be named (said once)."""
        if d in self._shadows:
            return self._shadows[d]
        name = f"--arm {self.profile.name}"
        shadow = None
        own = recipe_of(m)
        r = recognise(m) if own is None else None
        if own is not None:  # loaded through so101sim: the profile the script asked for
            if own.arm_key != self.key:
                self.note(
                    f"{name} does not change a model the script loaded through so101sim "
                    f"(load_model, Simulation): it runs with {servo_model(m)}; pass arm= "
                    "there to choose"
                )
        elif r is None:
            self.note(
                f"{name} cannot apply to the script's model: it is not the shipped scene.xml "
                "nor one so101sim built; it runs with its own actuators"
            )
        elif r.arm_key != self.key:
            target = build(replace(r, arm=self.profile, arm_key=self.key))
            shadow = Shadow(m, d, target)
            self.note(
                f"{name}: the script's model ({r.file.name}, which it would run with "
                f"{servo_model(m)}) runs with the servo model {servo_model(target)}"
            )
        self._shadows[d] = shadow
        return shadow


_active: ContextVar[ScriptArm | None] = ContextVar("so101sim_script_arm", default=None)


@contextlib.contextmanager
def script_arm(arm: ArmLike, say: Callable[[str], None] | None = None) -> Iterator[None]:
    """While a script runs under ``record --arm``: its models follow the profile (None: the
    script's models as they are)."""
    if arm is None:
        yield
        return
    token = _active.set(ScriptArm(arm, say))
    try:
        yield
    finally:
        _active.reset(token)


def shadow_of(m: mujoco.MjModel, d: mujoco.MjData) -> Shadow | None:
    """The shadow of the script's ``(m, d)`` while ``record --arm`` runs, else None."""
    arm = _active.get()
    return arm.shadow(m, d) if arm is not None else None


@contextlib.contextmanager
def attached(m: mujoco.MjModel, d: mujoco.MjData) -> Iterator[Simulation]:
    """The :class:`Simulation` a lab helper drives for ``(m, d)``: ``Simulation.attach(m, d)``,
    or under ``record --arm`` the shadow's (the script's data updated when the block ends)."""
    shadow = shadow_of(m, d)
    if shadow is None:
        yield Simulation.attach(m, d)
        return
    shadow.pull()
    try:
        yield shadow.sim
    finally:
        shadow.push()


__all__ = ["ScriptArm", "Shadow", "attached", "script_arm", "shadow_of"]
