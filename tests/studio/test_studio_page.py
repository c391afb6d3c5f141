"""The web studio's page (so101sim.studio) in a real browser: Debian's chromium driven by
selenium through chromedriver (headless, software WebGL): the arm drawn in its colour, a pose
slider dragged, a finished run's timeline scrubbed. Skips (with the reason) only where chromium
or chromedriver is not installed (.ci/run installs them: ``apt-get install -y chromium
chromium-driver``). Every server runs on 127.0.0.1 on a free port and is stopped at the end of
its test. (Its command-line behaviour: test_studio.py, a file of its own so that another worker
runs it beside these.)
"""

from __future__ import annotations

import colorsys
import io

import numpy as np
import pytest

pytest.importorskip("viser", reason="the web extra is not installed: pip install 'so101sim[web]'")
pytest.importorskip("mjviser", reason="the web extra is not installed: pip install 'so101sim[web]'")

from studio_helpers import (
    BROWSER_WAIT,
    free_port,
    page_ready,
    screenshot,
    start,
    stop,
    wait_until,
)

from so101sim import Simulation
from so101sim.studio import Studio
from so101sim.studio.live import StudioObserver
from so101sim.units import STARTING_POSE


def arm_hue(model) -> float:
    """The hue of the arm's most common (non-grey) visual colour in the model."""

    colours = []
    for g in range(model.ngeom):
        rgba = model.geom_rgba[g]
        if model.geom_matid[g] >= 0:
            rgba = model.mat_rgba[model.geom_matid[g]]
        if model.geom_group[g] != 3 and model.geom_bodyid[g] > 0:
            h, s, _ = colorsys.rgb_to_hsv(*rgba[:3])
            if s > 0.3:
                colours.append(h)
    assert colours, "the arm has no coloured geom"
    return float(np.median(colours))


def _image(png: bytes) -> np.ndarray:
    import imageio.v3 as iio

    return iio.imread(io.BytesIO(png))[..., :3].astype(float) / 255.0


def image_width(png: bytes) -> int:
    return _image(png).shape[1]


def image_area(png: bytes) -> int:
    h, w = _image(png).shape[:2]
    return h * w


def floor_pixels(png: bytes, model) -> int:
    """Pixels near one of the floor texture's two checker colours (a dark blue)."""
    from so101sim.studio.look import _texture

    floor = next(g for g in range(model.ngeom) if model.geom_type[g] == 0)
    tex = _texture(model, int(model.geom_matid[floor])).reshape(-1, 3).astype(float) / 255.0
    colours = np.unique(tex.round(2), axis=0)[:4]
    img = _image(png)
    near = np.zeros(img.shape[:2], bool)
    for c in colours:
        near |= np.abs(img - c).max(axis=-1) < 0.12
    return int(near.sum())


def arm_pixels(png: bytes, hue: float, tolerance: float = 0.06) -> tuple[np.ndarray, np.ndarray]:
    """(rows, columns) of the screenshot's pixels with about ``hue`` (shaded)."""
    return np.nonzero(_hue_mask(_image(png), hue, tolerance))


def coloured_pixels(png: bytes, hue: float, tolerance: float = 0.06) -> int:
    """Pixels of the screenshot with about ``hue`` (shaded: any brightness above 0.25)."""
    return int(_hue_mask(_image(png), hue, tolerance).sum())


def _hue_mask(img: np.ndarray, hue: float, tolerance: float) -> np.ndarray:
    mx, mn = img.max(axis=-1), img.min(axis=-1)
    sat = np.where(mx > 0, (mx - mn) / np.maximum(mx, 1e-9), 0)
    r, g, b = img[..., 0], img[..., 1], img[..., 2]
    d = np.maximum(mx - mn, 1e-9)
    h = (
        np.where(mx == r, ((g - b) / d) % 6, np.where(mx == g, (b - r) / d + 2, (r - g) / d + 4))
        / 6.0
    )
    near = np.minimum(np.abs(h - hue), 1 - np.abs(h - hue)) < tolerance
    return near & (sat > 0.3) & (mx > 0.25)


# ---------------------------------------------------------------------------- browser
def test_the_page_shows_the_arm_in_its_colour(browser, tmp_path):
    """The page's own ready signal (the browser drew the arm), then one screenshot: the arm in
    its colour, beside the panel (not under it), on the model's floor (not a white page)."""
    sim = Simulation()
    hue = arm_hue(sim.model)
    with Studio(sim.model, port=free_port()) as studio:
        sim.hold(0.1, observers=[StudioObserver(studio)])
        browser.get(studio.url)
        page_ready(browser)
        assert studio.ready.ready.is_set()
        png = screenshot(browser)
        (tmp_path / "studio.png").write_bytes(png)  # to look at
        pixels = arm_pixels(png, hue)
        assert len(pixels[0]) > 1500
        # the panel is docked at the right: the arm is drawn left of it, the view not under it
        panel_left = browser.execute_script(
            "const c = document.querySelector('canvas').getBoundingClientRect();return c.right;"
        )
        scale = image_width(png) / browser.execute_script("return window.innerWidth;")
        assert np.percentile(pixels[1], 99) < panel_left * scale
        assert panel_left < 0.85 * browser.execute_script("return window.innerWidth;")
        # the model's floor: its checker's blue, and no white page behind the arm
        floor = floor_pixels(png, sim.model)
        assert floor > 0.1 * image_area(png), floor
        # the panel: time, phase, commanded vs measured angles
        text = browser.find_element("tag name", "body").text
        assert "phase hold" in text and "shoulder_lift" in text and "-98.0°" in text


def test_dragging_a_pose_slider_changes_the_printed_pose(browser):
    from selenium.webdriver.common.action_chains import ActionChains

    port = free_port()
    # no shadows: the page only has to answer a drag (software WebGL draws it 3x faster)
    proc, out = start("pose", "--web", "--no-shadows", "--port", str(port))
    try:
        out.wait_for(lambda s: f"http://127.0.0.1:{port}" in s)
        out.wait_for(lambda s: s.startswith("python:") and '"shoulder_pan": 0.0' in s)
        browser.get(f"http://127.0.0.1:{port}")
        page_ready(browser)
        thumbs = wait_until(
            lambda: browser.find_elements("css selector", "[role=slider]"),
            BROWSER_WAIT,
            "the joint sliders",
        )
        assert len(thumbs) >= 6
        pan = thumbs[0]
        assert float(pan.get_attribute("aria-valuenow")) == pytest.approx(0.0)
        ActionChains(browser).click_and_hold(pan).move_by_offset(60, 0).release().perform()
        line = out.wait_for(lambda s: s.startswith("python:") and '"shoulder_pan": 0.0' not in s)
        moved = float(line.split('"shoulder_pan": ')[1].split(",")[0])
        assert moved > 5.0  # dragged to the right: a larger angle, within the limits
        assert moved == pytest.approx(float(pan.get_attribute("aria-valuenow")), abs=0.15)
        out.wait_for(lambda s: s.startswith("toml:") and "shoulder_pan = " in s)
        tip = out.wait_for(lambda s: s.startswith("tip:"))
        assert "pitch=" in tip
        # the page's copy buttons carry the same pose
        wait_until(
            lambda: (
                f"shoulder_pan = {moved}"
                in browser.find_element("tag name", "body").get_attribute("innerHTML")
            ),
            BROWSER_WAIT,
            "the copy buttons showing the pose",
        )
    finally:
        assert stop(proc) == 0


def test_the_timeline_scrubs_a_finished_run(browser):
    from selenium.webdriver.common.keys import Keys

    sim = Simulation()
    with Studio(sim.model, port=free_port(), shadows=False) as studio:  # faster in software
        observer = StudioObserver(studio)
        observer.pacer.speed = 50.0  # a quick run
        target = {**STARTING_POSE, "shoulder_lift": 0.0, "elbow_flex": 0.0}
        sim.move_to(target, 1.0, observers=[observer])
        studio.finish()
        frames = studio.timeline.frames
        assert len(frames) >= 25 and frames[-1].time == pytest.approx(1.0, abs=0.05)
        browser.get(studio.url)
        thumbs = wait_until(
            lambda: browser.find_elements("css selector", "[role=slider]"),
            BROWSER_WAIT,
            "the timeline",
        )
        timeline = thumbs[-1]
        timeline.send_keys(Keys.HOME)  # to the start of the run
        wait_until(lambda: studio._play_time < 0.01, BROWSER_WAIT, "scrubbing to the start")
        first = wait_until(
            lambda: "t = 0.0" in browser.find_element("tag name", "body").text and frames[0],
            BROWSER_WAIT,
            "the page showing t = 0",
        )
        assert "-98.0°" in browser.find_element("tag name", "body").text  # the rest pose
        assert first.measured[1] == pytest.approx(-98.0, abs=0.5)
        # play replays it to the end
        button = [b for b in browser.find_elements("tag name", "button") if b.text == "Play"]
        button[0].click()
        wait_until(
            lambda: studio._play_time >= frames[-1].time - 1e-6 and not studio.playing,
            BROWSER_WAIT,
            "playing to the end and stopping there",
        )
        assert studio._play_time == pytest.approx(frames[-1].time)  # it stops, no loop
