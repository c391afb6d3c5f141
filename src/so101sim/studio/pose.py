"""The pose finder in the browser: one slider per joint, in the arm's units.

:class:`PoseStudio` serves the arm with one slider per joint (degrees; the gripper 0-100),
each between the joint's limits. Physics is off while posing: a slider sets the joint and the
arm is drawn where the sliders say (forward kinematics only, nothing falls). The page shows
the tip's position and pitch (:mod:`so101sim.kinematics`) and has "copy as Python dict" and
"copy as TOML pose" buttons. A pose that puts the tip or a part of the arm below the floor or
into the table is flagged on the page, in red above the sliders
(:func:`~so101sim.viewer.clearance.pose_warnings`). :meth:`PoseStudio.poses` yields each pose
the arm is left in (:class:`~so101sim.viewer.posefinder.PoseChange`, with its warnings, as the
desktop pose finder does); the library prints nothing, the command prints them.
"""

from __future__ import annotations

import html
import threading
import time
from collections.abc import Iterator
from dataclasses import replace
from pathlib import Path

import mujoco
import numpy as np

from ..errors import ModelError
from ..kinematics import TipPose, for_model
from ..model import arm_index, arm_units
from ..units import GRIPPER, JOINT_NAMES, STARTING_POSE, Pose
from ..viewer.clearance import pose_warnings
from ..viewer.posefinder import PoseChange, PoseWatcher, format_python, format_toml, pose_scene
from .server import DEFAULT_HOST, DEFAULT_PORT, Studio


def _copy_button(label: str, text: str) -> str:
    """An HTML button that puts ``text`` on the clipboard (the browser's, not the server's)."""
    quoted = html.escape(text, quote=True)
    return (
        f'<button type="button" data-copy="{quoted}" '
        'onclick="navigator.clipboard.writeText(this.dataset.copy);'
        "this.textContent='copied';\" "
        'style="width:100%;padding:6px;margin:2px 0;border-radius:4px;border:1px solid #888;'
        f'background:#f4f4f4;cursor:pointer">{html.escape(label)}</button>'
    )


class PoseStudio:
    """Pose the arm in a browser at :attr:`url`; :meth:`poses` yields the poses it is left in.
    ``shadows``: as for :class:`~so101sim.studio.Studio`.

    Raises:
        StudioError: viser/mjviser are missing, or ``host:port`` is in use.
    """

    def __init__(
        self,
        model: mujoco.MjModel | str | Path | None = None,
        *,
        host: str = DEFAULT_HOST,
        port: int = DEFAULT_PORT,
        start: Pose = STARTING_POSE,
        digits: int = 1,
        shadows: bool = True,
    ) -> None:
        self.model, self.data = pose_scene(model, start)
        self.units = arm_units(self.model)
        self._qadr = arm_index(self.model).qpos
        self.digits = digits
        self._lock = threading.RLock()
        self.values = self.units.pose_to_array(start).astype(float)
        self.warnings: tuple[str, ...] = ()  # where the pose puts the arm into the scene
        try:
            self._kin = for_model(self.model)
        except ModelError:
            self._kin = None
        self.studio = Studio(
            self.model,
            host=host,
            port=port,
            title="so101sim pose finder",
            controls=False,
            shadows=shadows,
        )
        try:
            self._build()
            self._apply()
        except BaseException:
            self.studio.close()
            raise

    @property
    def url(self) -> str:
        return self.studio.url

    def _repr_html_(self) -> str:
        return self.studio._repr_html_()

    def _build(self) -> None:
        gui = self.studio.server.gui
        limits = self.units.limits_dict()
        self.sliders = {}
        self.warning_text = gui.add_html("")
        with gui.add_folder("Joints (degrees; gripper 0-100)"):
            for i, name in enumerate(JOINT_NAMES):
                lo, hi = limits[name]
                label = f"{name} (0-100)" if name == GRIPPER else f"{name} (°)"
                slider = gui.add_slider(
                    label,
                    min=round(float(lo), 1),
                    max=round(float(hi), 1),
                    step=0.1,
                    initial_value=round(float(np.clip(self.values[i], lo, hi)), 1),
                )
                slider.on_update(lambda _, i=i, s=slider: self._slid(i, float(s.value)))
                self.sliders[name] = slider
        self.tip_text = gui.add_markdown("")
        with gui.add_folder("Copy"):
            self.copy_python = gui.add_html("")
            self.copy_toml = gui.add_html("")
            self.text = gui.add_markdown("")

    def _slid(self, i: int, value: float) -> None:
        with self._lock:
            self.values[i] = value
            self._apply()

    def _apply(self) -> None:
        """Draw the arm at :attr:`values` and refresh the tip and the copy buttons."""
        with self._lock:
            self.data.qpos[self._qadr] = self.units.to_radians(self.values)
            self.data.qvel[:] = 0.0
            mujoco.mj_forward(self.model, self.data)
            self.studio.show(self.data, "posing", self.values, keep=False)
            pose = self.pose
            tip = self.tip()
            self.warnings = pose_warnings(self.model, self.data)
            self.warning_text.content = "".join(
                f'<div class="so101sim-warning" style="color:#c62828;font-weight:600">'
                f"⚠ {html.escape(w)}</div>"
                for w in self.warnings
            )
            self.tip_text.content = (
                "**tip** " + tip.format().replace(", pitch", "  \n**pitch** ").replace("=", " = ")
                if tip is not None
                else ""
            )
            py, toml = format_python(pose), format_toml("my_pose", pose)
            self.copy_python.content = _copy_button("copy as Python dict", py)
            self.copy_toml.content = _copy_button("copy as TOML pose", toml)
            self.text.content = f"```\n{py}\n{toml}\n```"

    @property
    def pose(self) -> dict[str, float]:
        """The sliders' pose, rounded to ``digits``."""
        with self._lock:
            return {
                n: round(float(v), self.digits) + 0.0
                for n, v in zip(JOINT_NAMES, self.values, strict=True)
            }

    def tip(self) -> TipPose | None:
        """Where the tip is at the sliders' pose (None for a model without the SO-101's tip)."""
        if self._kin is None:
            return None
        with self._lock:
            return self._kin.tip_array(self.values.copy())

    def set_pose(self, pose: Pose) -> None:
        """Move the arm (and the sliders) to ``pose``, within the limits."""
        values = self.units.pose_to_array({**self.pose, **pose}, clip=True)
        with self._lock:
            self.values = values.astype(float)
            for name, v in zip(JOINT_NAMES, self.values, strict=True):
                self.sliders[name].value = round(float(v), 1)
            self._apply()

    def poses(
        self, *, period: float = 1.0 / 15.0, watcher: PoseWatcher | None = None
    ) -> Iterator[PoseChange]:
        """Each pose the arm is left in (the first at once), until :meth:`close`; reads the
        sliders ``1/period`` times a second (wall clock: nothing is simulated); ends too at
        the studio's :meth:`~.server.Studio.interrupt`."""
        watcher = watcher if watcher is not None else PoseWatcher(self.units)
        t0 = time.monotonic()
        while not (self.studio.closed or self.studio.stopping):
            with self._lock:
                q = self.units.to_radians(self.values)
                warnings = self.warnings
            change = watcher.update(q, time.monotonic() - t0)
            if change is not None:
                tip = (
                    self._kin.tip_array(np.array(list(change.pose.values()))) if self._kin else None
                )
                yield replace(change, tip=tip, warnings=warnings)
            self.studio._closed.wait(period)

    def close(self) -> None:
        self.studio.close()

    def __enter__(self) -> PoseStudio:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
