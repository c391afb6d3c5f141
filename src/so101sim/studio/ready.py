"""The page's own "ready" signal: a marker the page shows once its browser has drawn the arm.

A test (or a person on a slow machine) should wait for the scene to be drawn, not for a fixed
time. For each browser that connects, :class:`ReadySignal` asks it for a small render of what
it draws (viser's ``get_render``: the browser's WebGL, not the server) every half second until
the render holds the arm's own colour (the most common saturated colour of the model's moving
parts), then adds to that browser's panel an element ``<span id="so101sim-ready"
data-ready="1">`` ("the arm is drawn"). It gives up after :data:`READY_DEADLINE` seconds
(the page then has no marker; nothing else changes).
"""

from __future__ import annotations

import colorsys
import logging
import threading
import time
from typing import Any

import mujoco
import numpy as np

log = logging.getLogger(__name__)

READY_DEADLINE = 300.0  # seconds a browser gets to draw the arm (software WebGL, busy CPU)
READY_HTML = '<span id="so101sim-ready" data-ready="1">the arm is drawn</span>'
RENDER_SIZE = (120, 160)  # height, width of the probe render
MIN_PIXELS = 40  # pixels of the arm's colour in the probe render


def arm_colour(model: mujoco.MjModel) -> np.ndarray | None:
    """The RGB (0-1) most common among the saturated colours of the moving bodies' visible
    geoms (the SO-101's yellow), or None when they have no saturated colour."""
    colours: list[tuple[float, ...]] = []
    for g in range(model.ngeom):
        body = int(model.geom_bodyid[g])
        if body == 0 or model.body_weldid[body] == 0 or model.geom_group[g] > 2:
            continue
        matid = int(model.geom_matid[g])
        rgba = model.mat_rgba[matid] if matid >= 0 else model.geom_rgba[g]
        if rgba[3] > 0 and colorsys.rgb_to_hsv(*rgba[:3])[1] > 0.3:
            colours.append(tuple(np.round(rgba[:3], 3)))
    if not colours:
        return None
    values, counts = np.unique(np.array(colours), axis=0, return_counts=True)
    return values[int(np.argmax(counts))]


def shows_colour(image: np.ndarray, rgb: np.ndarray, tolerance: float = 0.06) -> int:
    """Pixels of ``image`` (H, W, 3+ uint8) with about the hue of ``rgb``, shaded (any
    brightness above 0.2, saturation above 0.3)."""
    img = np.asarray(image)[..., :3].astype(float) / 255.0
    hue = colorsys.rgb_to_hsv(*rgb)[0]
    mx, mn = img.max(axis=-1), img.min(axis=-1)
    d = np.maximum(mx - mn, 1e-9)
    r, g, b = img[..., 0], img[..., 1], img[..., 2]
    h = np.where(mx == r, ((g - b) / d) % 6, np.where(mx == g, (b - r) / d + 2, (r - g) / d + 4))
    near = np.minimum(np.abs(h / 6.0 - hue), 1 - np.abs(h / 6.0 - hue)) < tolerance
    sat = np.where(mx > 0, (mx - mn) / np.maximum(mx, 1e-9), 0)
    return int((near & (sat > 0.3) & (mx > 0.2)).sum())


class ReadySignal:
    """Marks each browser's page once it has drawn the arm (see the module's docstring)."""

    def __init__(self, server: Any, model: mujoco.MjModel, closed: threading.Event) -> None:
        self.server = server
        self.colour = arm_colour(model)
        self.closed = closed
        self.ready = threading.Event()  # some browser has drawn the arm
        server.on_client_connect(self._connected)

    def _connected(self, client: Any) -> None:
        threading.Thread(
            target=self._probe, args=(client,), name="so101sim-studio-ready", daemon=True
        ).start()

    def _drawn(self, client: Any) -> bool:
        if self.colour is None:  # nothing to look for: the first render is the signal
            return True
        height, width = RENDER_SIZE
        # a starved browser takes long to draw a frame: wait for it (a shorter wait would ask
        # again and again and never see one)
        image = client.get_render(height, width, transport_format="jpeg", timeout=READY_DEADLINE)
        return shows_colour(image, self.colour) >= MIN_PIXELS

    def _probe(self, client: Any) -> None:
        end = time.monotonic() + READY_DEADLINE
        while not self.closed.is_set() and time.monotonic() < end:
            try:
                if self._drawn(client):
                    client.gui.add_html(READY_HTML, order=-1)
                    self.ready.set()
                    log.debug("client %s drew the arm", client.client_id)
                    return
            except Exception as exc:  # the browser went away, or no frame in time
                log.debug("ready probe: %s", exc)
                if client.client_id not in self.server.get_clients():
                    return
            self.closed.wait(0.5)
