"""The studio's web server: the arm in 3D in a browser, a run's panel and its timeline.

:class:`Studio` starts a `viser <https://viser.studio>`_ server on ``host:port`` (nothing
listens beyond this machine unless ``host`` says so) and draws the model with `mjviser
<https://github.com/mujocolab/mjviser>`_ (the model's meshes and colours, the scene's objects);
the browser renders it (WebGL), so the server needs no display and no GPU. :meth:`Studio.show`
puts a state on the page (time, phase, commanded vs measured angles) and keeps it on the
run's timeline (:class:`Timeline`, at most :data:`MAX_FRAMES` frames, thinned beyond); after
:meth:`Studio.finish` the page's play, pause and restart buttons and its timeline slider
replay and scrub the run. :meth:`Studio.close` stops the server and its threads.

viser and mjviser are an optional extra: :func:`require_viser` raises :class:`StudioError`
naming ``pip install "so101sim[web]"`` when they are missing. Where it listens and who may
connect: :mod:`.net`; the timeline: :mod:`.timeline`; the page's floor, lights, camera and
panel: :mod:`.look`.
"""

from __future__ import annotations

import contextlib
import copy
import logging
import threading
import time
from collections.abc import Sequence
from typing import Any

import mujoco
import numpy as np

from ..errors import SettingError
from ..model import arm_index, arm_units
from ..validation import check_range
from .look import dress
from .net import (
    DEFAULT_HOST,
    DEFAULT_PORT,
    OriginGuard,
    StudioError,
    check_host,
    check_port,
    ensure_free,
    exposure_warning,
    listen_addresses,
    page_url,
    port_in_use_message,
    quiet_handshakes,
    quiet_viser,
)
from .ready import ReadySignal
from .timeline import FRAME_RATE, MAX_FRAMES, Frame, Timeline, angles_table

log = logging.getLogger(__name__)

INSTALL_HINT = 'pip install "so101sim[web]"'


def require_viser() -> tuple[Any, Any]:
    """``(viser, mjviser.ViserMujocoScene)``, or :class:`StudioError` naming the extra."""
    try:
        # viser and mjviser: the optional web extra (StudioError names it)
        import viser
        from mjviser import ViserMujocoScene
    except ImportError as exc:
        raise StudioError(
            f"the web studio needs viser and mjviser ({exc.name} is not installed); "
            f"expected them installed: {INSTALL_HINT}"
        ) from None
    return viser, ViserMujocoScene


class Studio:
    """A web page showing ``model``: open :attr:`url` in a browser.

    ``show(d, ...)`` puts a state on the page; ``finish()`` turns the page into a player of
    the run; ``close()`` (or leaving the ``with`` block) stops the server. Thread-safe: the
    page's buttons run in viser's threads, ``show`` in the caller's. ``shadows=False``: the
    page's lights cast no shadows (for a browser without a GPU: about 3× less work a frame).

    Raises:
        StudioError: viser/mjviser are missing, or ``host:port`` is in use.
        SettingError: a port outside 1-65535.
    """

    def __init__(
        self,
        model: mujoco.MjModel,
        *,
        host: str = DEFAULT_HOST,
        port: int = DEFAULT_PORT,
        title: str = "so101sim studio",
        controls: bool = True,
        shadows: bool = True,
    ) -> None:
        viser, scene_class = require_viser()
        host, port = check_host(host), check_port(port)
        ensure_free(host, port)
        self.host, self.port, self.title = host, port, title
        self.listening = tuple(listen_addresses(host, port))  # what the server binds
        self.warning = exposure_warning(host, port, list(self.listening))
        self.model = model
        self.units = arm_units(model)
        self._index = arm_index(model)
        self._lock = threading.RLock()
        self.timeline = Timeline()
        self.finished = False
        self.playing = True  # live: the run goes on; finished: the player plays
        self._play_time = 0.0
        self._slider_set = float("nan")  # the timeline's value the player last set
        self._closed = threading.Event()
        self.stopping = False  # set by interrupt(): a signal handler's way to stop a wait
        self._player: threading.Thread | None = None
        self._scratch = mujoco.MjData(model)
        quiet_handshakes()
        self.guard = OriginGuard(host)
        with quiet_viser():
            self.server = viser.ViserServer(host=host, port=port, label=title, verbose=False)
        try:
            self.guard.install(self.server)
            if self.server.get_port() != port:  # taken between the check and the start
                raise StudioError(port_in_use_message(host, port))
            # mjviser adjusts the model's visual settings: give it a copy
            self.scene = scene_class(self.server, copy.copy(model), num_envs=1)
            self.scene.camera_tracking_enabled = False
            self.lights = dress(self.server, model, shadows=shadows)  # viser's handles
            self.ready = ReadySignal(self.server, model, self._closed)
            self._build_panel(controls)
        except BaseException:
            with quiet_viser():
                self.server.stop()
            raise
        log.debug("studio serving %s", self.url)

    # ------------------------------------------------------------------ page
    @property
    def url(self) -> str:
        return page_url(self.host, self.port)

    def _repr_html_(self) -> str:  # Jupyter shows the studio as a link (and its warning)
        warning = f"<br><b>warning</b>: {self.warning}" if self.warning else ""
        return f'<a href="{self.url}" target="_blank">{self.title}: {self.url}</a>{warning}'

    def __repr__(self) -> str:
        return f"Studio({self.url})"

    def _build_panel(self, controls: bool) -> None:
        gui = self.server.gui
        self.status = gui.add_markdown("**t = 0.000 s**")
        # the pose finder's sliders say the angles already: its table starts folded
        with gui.add_folder(self.angles_title, expand_by_default=controls):
            self.angles = gui.add_markdown("")
        if not controls:
            self.play_button = self.pause_button = self.restart_button = None
            self.slider = None
            return
        with gui.add_folder("Playback"):
            self.play_button = gui.add_button("Play")
            self.pause_button = gui.add_button("Pause")
            self.restart_button = gui.add_button("Restart", disabled=True)
            self.slider = gui.add_slider(
                "Timeline (s)", min=0.0, max=1.0, step=0.001, initial_value=0.0, disabled=True
            )
        self.play_button.on_click(lambda _: self.play())
        self.pause_button.on_click(lambda _: self.pause())
        self.restart_button.on_click(lambda _: self.restart())
        self.slider.on_update(lambda _: self._scrubbed())

    # ------------------------------------------------------------------ live
    def frame_of(
        self,
        d: mujoco.MjData,
        phase: str = "",
        commanded: Sequence[float] | np.ndarray | None = None,
    ) -> Frame:
        """The state of ``d`` as a :class:`Frame` (``commanded`` in the arm's units)."""
        q = np.asarray(d.qpos[self._index.qpos], dtype=float)
        return Frame(
            float(d.time),
            phase,
            np.array(d.qpos, copy=True),
            np.array(d.mocap_pos, copy=True),
            np.array(d.mocap_quat, copy=True),
            None if commanded is None else np.asarray(commanded, dtype=float).copy(),
            self.units.from_radians(q),
        )

    def show(
        self,
        d: mujoco.MjData,
        phase: str = "",
        commanded: Sequence[float] | np.ndarray | None = None,
        *,
        keep: bool = True,
    ) -> None:
        """Put the state of ``d`` on the page (positions must be computed: after a step or
        ``mj_forward``) and, with ``keep``, on the timeline."""
        frame = self.frame_of(d, phase, commanded)
        with self._lock:
            if keep:
                self.timeline.add(frame)
            self._draw(frame, d)

    def _draw(self, frame: Frame, d: mujoco.MjData | None = None) -> None:
        if d is None:
            d = self._scratch
            d.qpos[:] = frame.qpos
            d.mocap_pos[:] = frame.mocap_pos
            d.mocap_quat[:] = frame.mocap_quat
            d.time = frame.time
            mujoco.mj_kinematics(self.model, d)
        self.scene.update_from_mjdata(d)
        self.status.content = self.status_text(frame)
        self.angles.content = self.angles_text(frame)

    def status_text(self, frame: Frame) -> str:
        """The page's status line for ``frame`` (markdown)."""
        phase = f" · phase **{frame.phase}**" if frame.phase else ""
        return f"**t = {frame.time:.3f} s**{phase}{self.player_state()}"

    def player_state(self) -> str:
        return "" if not self.finished else (" · playing" if self.playing else " · paused")

    def angles_text(self, frame: Frame) -> str:
        """The angles table for ``frame`` (markdown)."""
        return angles_table(frame)

    def wait_while_paused(self) -> bool:
        """For a live run: block while the page's Pause is on; True if it paused at all."""
        paused = False
        while not (self.playing or self.stopping or self.finished or self._closed.is_set()):
            paused = True
            time.sleep(0.02)
        return paused

    # ------------------------------------------------------------------ player
    def finish(self) -> None:
        """The run is over: the page's buttons and timeline now replay and scrub it."""
        with self._lock:
            if self.finished or self.slider is None:
                self.finished = True
                return
            self.finished = True
            self.playing = False
            frames = self.timeline.frames
            if frames:
                t0, t1 = frames[0].time, frames[-1].time
                self.slider.min, self.slider.max = t0, max(t1, t0 + 1e-3)
                self._slider_set = self.slider.value = t1
                self._play_time = t1
            self.slider.disabled = False
            if self.restart_button is not None:
                self.restart_button.disabled = False
        self._player = threading.Thread(target=self._play_loop, name="so101sim-studio-player")
        self._player.daemon = True
        self._player.start()

    def play(self) -> None:
        with self._lock:
            frames = self.timeline.frames
            if self.finished and frames and self._play_time >= frames[-1].time:
                self._play_time = frames[0].time
            self.playing = True

    def pause(self) -> None:
        with self._lock:
            self.playing = False

    def restart(self) -> None:
        with self._lock:
            if self.timeline.frames:
                self._play_time = self.timeline.frames[0].time
                self.playing = True

    def seek(self, t: float) -> Frame | None:
        """Show the finished run at simulated time ``t`` (pauses the player)."""
        with self._lock:
            if not self.timeline.frames:
                return None
            self.playing = False
            self._play_time = float(t)
            frame = self.timeline.at(self._play_time)
            self._draw(frame)
            return frame

    def _scrubbed(self) -> None:
        if not self.finished or self.slider is None:
            return
        with self._lock:
            t = float(self.slider.value)
            if t != self._slider_set:  # moved by the user, not by the player
                self.seek(t)

    def _play_loop(self, speed: float = 1.0) -> None:
        last = time.perf_counter()
        while not self._closed.wait(1.0 / FRAME_RATE):
            now = time.perf_counter()
            with self._lock:
                if not self.playing or not self.timeline.frames:
                    last = now
                    continue
                end = self.timeline.frames[-1].time
                self._play_time = min(end, self._play_time + (now - last) * self.speed)
                if self._play_time >= end:  # at the end: stopped before anything else reads it
                    self.playing = False
                last = now
                frame = self.timeline.at(self._play_time)
                self._draw(frame)
                if self.slider is not None:
                    self._slider_set = round(self._play_time, 3)
                    self.slider.value = self._slider_set

    speed = 1.0  # the player's speed (set to the run's --speed)
    angles_title = "Angles (commanded, measured)"  # the panel's folder of the angles table

    # ------------------------------------------------------------------ life
    @property
    def closed(self) -> bool:
        return self._closed.is_set()

    def interrupt(self) -> None:
        """Ask the waits of this studio (a paused run, the pose finder's poses) to end soon.
        Safe in a signal handler: it sets a flag, takes no lock and raises nothing."""
        self.stopping = True

    def close(self) -> None:
        """Stop the player and the server (waits for their threads)."""
        if self._closed.is_set():
            return
        self._closed.set()
        if self._player is not None and self._player is not threading.current_thread():
            self._player.join(timeout=5.0)
        with contextlib.suppress(Exception), quiet_viser():
            self.server.stop()
        log.debug("studio stopped")

    def __enter__(self) -> Studio:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def check_linger(seconds: float) -> float:
    """Seconds the studio stays up after a run: 0 to a day."""
    if seconds is None or seconds < 0:
        raise SettingError(f"linger = {seconds!r}; expected seconds from 0 to 86400")
    return float(check_range(seconds, "linger", low=0.0, high=86400.0))


__all__ = [
    "DEFAULT_HOST",
    "DEFAULT_PORT",
    "FRAME_RATE",
    "MAX_FRAMES",
    "Frame",
    "Studio",
    "StudioError",
    "Timeline",
    "check_linger",
    "check_port",
    "ensure_free",
    "port_in_use_message",
    "quiet_viser",
    "require_viser",
]
