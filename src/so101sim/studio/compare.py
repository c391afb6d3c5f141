"""``so101sim compare --web``: a real arm's recording and the sim's replay of it, in the studio.

:class:`CompareStudio` is a finished :class:`~.server.Studio` (its player: Play, Pause,
Restart and the timeline slider) whose timeline holds the compared episodes one after another
(each from its first frame, :data:`GAP_S` apart): the arm drawn as usual is the sim's replay,
and a translucent ghost (:class:`~.ghost.Ghost`) is the real arm, posed from the recording.
The panel shows, at the player's time, each joint's command, real and sim values and the
sim's error; an episode picker and one button per worst window jump the player there; and a
chart draws a joint's real, sim and command over the whole timeline (a picker chooses the
joint; the worst window's joint first).

It takes plain arrays, not a comparison: ``traces`` are mappings with the keys of
:attr:`so101sim.fidelity.compare.CompareResult.traces` (``episode``, ``t``, ``real``, ``sim``,
``command``, and optionally ``real_pose``/``sim_pose``, the poses as angles), so the studio
does not depend on the fidelity package.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping, Sequence
from typing import Any

import mujoco
import numpy as np

from ..units import GRIPPER, JOINT_NAMES
from .ghost import Ghost
from .server import Frame, Studio

GAP_S = 0.5  # seconds of timeline between two episodes
CHART_POINTS = 3000  # points per series at most in the chart (thinned beyond)
MAX_WINDOW_BUTTONS = 10


@dataclasses.dataclass(frozen=True)
class CompareFrame(Frame):
    """A frame of the comparison: ``measured`` is the sim's reading, ``real`` the real arm's,
    ``ghost`` the real arm's pose (angles), ``episode`` and ``episode_time`` where it is in
    the recording."""

    real: np.ndarray | None = None
    ghost: np.ndarray | None = None
    episode: int = 0
    episode_time: float = 0.0


@dataclasses.dataclass(frozen=True)
class Window:
    """A stretch to jump to: ``episode``, its times ``t0``-``t1`` (s) and a ``label``."""

    episode: int
    t0: float
    t1: float
    label: str
    joint: str = ""  # its worst joint (the chart shows the first window's first)


class CompareStudio(Studio):
    """The studio replaying ``traces`` (see the module): the sim's arm and the real arm's
    ghost. ``windows``: the worst windows, one button each. Served at once; ``close()`` it."""

    angles_title = "Joints (command, real, sim)"

    def __init__(
        self,
        model: mujoco.MjModel,
        traces: Sequence[Mapping[str, Any]],
        *,
        windows: Sequence[Window] = (),
        title: str = "so101sim compare",
        **kwargs: Any,
    ) -> None:
        if not traces:
            raise ValueError("compare(..., keep_traces=True) keeps what the studio replays")
        super().__init__(model, title=title, controls=True, **kwargs)
        try:
            self.ghost = Ghost(self.server, model)
            self.starts: dict[int, float] = {}  # episode -> its first frame's timeline time
            self._first_t: dict[int, float] = {}
            self._load(traces)
            self._build_compare_panel(traces, windows)
            self.finish()
            self.jump(self.timeline.frames[0].time)
        except BaseException:
            self.close()
            raise

    # ------------------------------------------------------------------ timeline
    def time_of(self, episode: int, t: float) -> float:
        """The timeline's time of ``episode``'s recording time ``t`` (s)."""
        return self.starts[episode] + (float(t) - self._first_t[episode])

    def _load(self, traces: Sequence[Mapping[str, Any]]) -> None:
        d = self._scratch
        offset = 0.0
        for tr in traces:
            ep, t = int(tr["episode"]), np.asarray(tr["t"], dtype=float)
            sim_pose = np.asarray(tr.get("sim_pose", tr["sim"]), dtype=float)
            real_pose = np.asarray(tr.get("real_pose", tr["real"]), dtype=float)
            lo, hi = self.units.limits
            q = self.units.to_radians(np.clip(sim_pose, lo, hi))
            self.starts[ep], self._first_t[ep] = offset, float(t[0])
            for k in range(len(t)):
                qpos = np.array(self.model.qpos0, copy=True)
                qpos[self._index.qpos] = q[k]
                frame = CompareFrame(
                    offset + float(t[k] - t[0]), f"episode {ep}", qpos,
                    np.array(d.mocap_pos, copy=True), np.array(d.mocap_quat, copy=True),
                    np.asarray(tr["command"][k], dtype=float), np.asarray(tr["sim"][k], float),
                    real=np.asarray(tr["real"][k], dtype=float), ghost=real_pose[k],
                    episode=ep, episode_time=float(t[k]),
                )  # fmt: skip
                self.timeline.add(frame, force=True)
            offset += float(t[-1] - t[0]) + GAP_S

    def jump(self, t: float) -> Frame | None:
        """Show the replay at timeline time ``t`` (paused) and put the slider there."""
        with self._lock:
            frame = self.seek(t)
            if self.slider is not None and frame is not None:
                self._slider_set = round(float(t), 3)
                self.slider.value = min(max(self._slider_set, self.slider.min), self.slider.max)
            return frame

    # ------------------------------------------------------------------ page
    def _draw(self, frame: Frame, d: mujoco.MjData | None = None) -> None:
        with self.server.atomic():
            super()._draw(frame, d)
            if isinstance(frame, CompareFrame) and frame.ghost is not None:
                self.ghost.pose(frame.ghost)

    def status_text(self, frame: Frame) -> str:
        if not isinstance(frame, CompareFrame):
            return super().status_text(frame)
        return (
            f"**episode {frame.episode} · t = {frame.episode_time:.2f} s**{self.player_state()}"
            " · the real arm: the light-blue ghost; the sim: the arm"
        )

    def angles_text(self, frame: Frame) -> str:
        if not isinstance(frame, CompareFrame) or frame.real is None:
            return super().angles_text(frame)
        rows = ["| joint | command | real | sim | sim − real |", "|---|---:|---:|---:|---:|"]
        for i, name in enumerate(JOINT_NAMES):
            u = "" if name == GRIPPER else "°"
            c = "–" if frame.commanded is None else f"{frame.commanded[i]:.1f}{u}"
            r, s = frame.real[i], frame.measured[i]
            rows.append(f"| {name} | {c} | {r:.1f}{u} | {s:.1f}{u} | {s - r:+.1f}{u} |")
        return "\n".join(rows)

    def _build_compare_panel(
        self, traces: Sequence[Mapping[str, Any]], windows: Sequence[Window]
    ) -> None:
        gui = self.server.gui
        episodes = [str(int(tr["episode"])) for tr in traces]
        picker = gui.add_dropdown("Episode", options=episodes, initial_value=episodes[0])
        picker.on_update(lambda _: self.jump(self.starts[int(picker.value)]))
        self.picker = picker
        self.window_buttons: list[Any] = []
        shown = [w for w in windows if w.episode in self.starts][:MAX_WINDOW_BUTTONS]
        x, series = _chart_data(self.timeline.frames)
        first = next((w.joint for w in shown if w.joint in JOINT_NAMES), JOINT_NAMES[2])
        with gui.add_folder("Real, sim, command over the timeline"):
            pick = gui.add_dropdown("Joint", options=list(JOINT_NAMES), initial_value=first)
            self.chart = gui.add_uplot(
                _joint_chart(x, series, first),
                (
                    {"label": "t (s)"},
                    {"label": "command", "stroke": "gray", "dash": [4, 4], "width": 1},
                    {"label": "real", "stroke": "#4a9ee8", "width": 1.5},
                    {"label": "sim", "stroke": "darkorange", "width": 1.5},
                ),
                title=_chart_title(first),
                scales={"x": {"time": False}},  # seconds of the timeline, not a date
                aspect=1.6,
            )
        self.chart_joint = pick

        def show_joint(_: Any) -> None:
            self.chart.data = _joint_chart(x, series, pick.value)
            self.chart.title = _chart_title(pick.value)

        pick.on_update(show_joint)
        if shown:
            with gui.add_folder("Worst windows (jump there)"):
                for w in shown:
                    button = gui.add_button(w.label)
                    button.on_click(lambda _, w=w: self.jump(self.time_of(w.episode, w.t0)))
                    self.window_buttons.append(button)


def _chart_title(joint: str) -> str:
    return f"{joint} ({'0-100' if joint == GRIPPER else 'deg'}); a break: the next episode"


def _joint_chart(x: np.ndarray, series: list[np.ndarray], joint: str) -> tuple[np.ndarray, ...]:
    j = JOINT_NAMES.index(joint)
    return (x, *(np.ascontiguousarray(s[:, j]) for s in series))


def _chart_data(frames: Sequence[Frame]) -> tuple[np.ndarray, list[np.ndarray]]:
    """(timeline times, [command, real, sim]) at most :data:`CHART_POINTS` points, a gap
    (NaN) between two episodes."""
    step = max(1, -(-len(frames) // CHART_POINTS))
    kept = list(frames[::step])
    x, rows = [], []
    nan = np.full((3, len(JOINT_NAMES)), np.nan)
    for k, f in enumerate(kept):
        if k and isinstance(f, CompareFrame) and f.episode != kept[k - 1].episode:  # type: ignore[attr-defined]
            x.append((kept[k - 1].time + f.time) / 2)
            rows.append(nan)
        cmd = f.commanded if f.commanded is not None else np.full(len(JOINT_NAMES), np.nan)
        real = getattr(f, "real", None)
        rows.append(np.stack([cmd, real if real is not None else f.measured, f.measured]))
        x.append(f.time)
    data = np.asarray(rows, dtype=float)
    return np.asarray(x, dtype=float), [data[:, 0], data[:, 1], data[:, 2]]


__all__ = ["GAP_S", "CompareFrame", "CompareStudio", "Window"]
