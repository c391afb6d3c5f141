"""The web studio (so101sim.studio, ``--web``): in a real browser, Debian's chromium driven by
selenium through chromedriver (headless, software WebGL), and its command-line behaviour.

The browser tests skip (with the reason) only where chromium or chromedriver is not installed
(.ci/run installs them: ``apt-get install -y chromium chromium-driver``). Every server runs on
127.0.0.1 on a free port and is stopped at the end of its test.
"""

from __future__ import annotations

import colorsys
import io
import os
import queue
import shutil
import signal
import socket
import subprocess
import sys
import threading
import time
import urllib.request
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("viser", reason="the web extra is not installed: pip install 'so101sim[web]'")
pytest.importorskip("mjviser", reason="the web extra is not installed: pip install 'so101sim[web]'")

from so101sim import Simulation
from so101sim.studio import Studio, StudioError
from so101sim.studio.live import StudioObserver
from so101sim.studio.server import Frame, Timeline
from so101sim.units import STARTING_POSE

SRC = str(Path(__file__).resolve().parents[2] / "src")
CHROMIUM = shutil.which("chromium") or shutil.which("chromium-browser")
CHROMEDRIVER = shutil.which("chromedriver")
BROWSER_WAIT = 120.0  # seconds: software WebGL beside other jobs on a 2-core machine


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def cli(*args: str) -> list[str]:
    return [sys.executable, "-m", "so101sim", *args]


def env() -> dict[str, str]:
    return {**os.environ, "PYTHONPATH": SRC + os.pathsep + os.environ.get("PYTHONPATH", "")}


class Lines:
    """A subprocess's stdout, read line by line in a thread (never blocks the test)."""

    def __init__(self, proc: subprocess.Popen) -> None:
        self.queue: queue.Queue[str] = queue.Queue()
        self.seen: list[str] = []
        self.thread = threading.Thread(target=self._read, args=(proc.stdout,), daemon=True)
        self.thread.start()

    def _read(self, stream) -> None:
        for line in stream:
            self.queue.put(line)

    def wait_for(self, predicate, timeout: float) -> str:
        end = time.monotonic() + timeout
        while time.monotonic() < end:
            try:
                line = self.queue.get(timeout=0.2)
            except queue.Empty:
                continue
            self.seen.append(line)
            if predicate(line):
                return line
        raise AssertionError(f"no such line within {timeout} s; got:\n{''.join(self.seen)}")


def start(*args: str) -> tuple[subprocess.Popen, Lines]:
    proc = subprocess.Popen(
        cli(*args),
        stdout=subprocess.PIPE,
        stderr=subprocess.STDOUT,
        text=True,
        env=env(),
        start_new_session=True,  # its own process group: the test checks none is left
    )
    return proc, Lines(proc)


def stop(proc: subprocess.Popen) -> int:
    if proc.poll() is None:
        proc.send_signal(signal.SIGINT)
        try:
            return proc.wait(timeout=30)
        except subprocess.TimeoutExpired:
            os.killpg(proc.pid, signal.SIGKILL)
            proc.wait()
    return proc.returncode


@pytest.fixture
def browser(tmp_path):
    """Headless chromium (software WebGL through SwiftShader) driven by selenium."""
    if CHROMIUM is None or CHROMEDRIVER is None:
        pytest.skip(
            "chromium and chromedriver are not installed "
            "(apt-get install -y chromium chromium-driver)"
        )
    webdriver = pytest.importorskip("selenium.webdriver", reason="selenium is not installed")
    from selenium.webdriver.chrome.service import Service

    options = webdriver.ChromeOptions()
    options.binary_location = CHROMIUM
    for flag in (
        "--headless=new",
        "--no-sandbox",
        "--use-angle=swiftshader",
        "--enable-unsafe-swiftshader",
        "--no-first-run",
        "--disable-background-networking",
        "--disable-component-update",
        "--disable-sync",
        "--disable-dev-shm-usage",
        "--window-size=1280,800",
        f"--user-data-dir={tmp_path / 'chromium-profile'}",
    ):
        options.add_argument(flag)
    driver = webdriver.Chrome(service=Service(CHROMEDRIVER), options=options)
    driver.set_page_load_timeout(60)
    try:
        yield driver
    finally:
        driver.quit()


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


def coloured_pixels(png: bytes, hue: float, tolerance: float = 0.06) -> int:
    """Pixels of the screenshot with about ``hue`` (shaded: any brightness above 0.25)."""
    import imageio.v3 as iio

    img = iio.imread(io.BytesIO(png))[..., :3].astype(float) / 255.0
    mx, mn = img.max(axis=-1), img.min(axis=-1)
    sat = np.where(mx > 0, (mx - mn) / np.maximum(mx, 1e-9), 0)
    r, g, b = img[..., 0], img[..., 1], img[..., 2]
    d = np.maximum(mx - mn, 1e-9)
    h = (
        np.where(mx == r, ((g - b) / d) % 6, np.where(mx == g, (b - r) / d + 2, (r - g) / d + 4))
        / 6.0
    )
    near = np.minimum(np.abs(h - hue), 1 - np.abs(h - hue)) < tolerance
    return int((near & (sat > 0.3) & (mx > 0.25)).sum())


def wait_until(check, timeout: float, what: str):
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        value = check()
        if value:
            return value
        time.sleep(0.5)
    raise AssertionError(f"{what} did not happen within {timeout} s")


# ---------------------------------------------------------------------------- browser
def test_the_page_shows_the_arm_in_its_colour(browser, tmp_path):
    sim = Simulation()
    hue = arm_hue(sim.model)
    with Studio(sim.model, port=free_port()) as studio:
        sim.hold(0.1, observers=[StudioObserver(studio)])
        browser.get(studio.url)
        shots: list[bytes] = []

        def drawn() -> bool:
            shots.append(browser.get_screenshot_as_png())
            return coloured_pixels(shots[-1], hue) > 3000

        wait_until(drawn, BROWSER_WAIT, "the arm drawn in its colour")
        (tmp_path / "studio.png").write_bytes(shots[-1])
        # the panel: time, phase, commanded vs measured angles
        text = browser.find_element("tag name", "body").text
        assert "phase hold" in text and "shoulder_lift" in text and "-98.0°" in text


def test_dragging_a_pose_slider_changes_the_printed_pose(browser):
    from selenium.webdriver.common.action_chains import ActionChains

    port = free_port()
    proc, out = start("pose", "--web", "--port", str(port))
    try:
        out.wait_for(lambda s: f"http://127.0.0.1:{port}" in s, 60)
        out.wait_for(lambda s: s.startswith("python:") and '"shoulder_pan": 0.0' in s, 60)
        browser.get(f"http://127.0.0.1:{port}")
        thumbs = wait_until(
            lambda: browser.find_elements("css selector", "[role=slider]"),
            BROWSER_WAIT,
            "the joint sliders",
        )
        assert len(thumbs) >= 6
        pan = thumbs[0]
        assert float(pan.get_attribute("aria-valuenow")) == pytest.approx(0.0)
        ActionChains(browser).click_and_hold(pan).move_by_offset(60, 0).release().perform()
        line = out.wait_for(
            lambda s: s.startswith("python:") and '"shoulder_pan": 0.0' not in s, 60
        )
        moved = float(line.split('"shoulder_pan": ')[1].split(",")[0])
        assert moved > 5.0  # dragged to the right: a larger angle, within the limits
        assert moved == pytest.approx(float(pan.get_attribute("aria-valuenow")), abs=0.15)
        out.wait_for(lambda s: s.startswith("toml:") and "shoulder_pan = " in s, 10)
        tip = out.wait_for(lambda s: s.startswith("tip:"), 10)
        assert "pitch=" in tip
        # the page's copy buttons carry the same pose
        wait_until(
            lambda: (
                f"shoulder_pan = {moved}"
                in browser.find_element("tag name", "body").get_attribute("innerHTML")
            ),
            30,
            "the copy buttons showing the pose",
        )
    finally:
        assert stop(proc) == 0


def test_the_timeline_scrubs_a_finished_run(browser):
    from selenium.webdriver.common.keys import Keys

    sim = Simulation()
    with Studio(sim.model, port=free_port()) as studio:
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
        wait_until(lambda: studio._play_time < 0.01, 30, "scrubbing to the start")
        first = wait_until(
            lambda: "t = 0.0" in browser.find_element("tag name", "body").text and frames[0],
            30,
            "the page showing t = 0",
        )
        assert "-98.0°" in browser.find_element("tag name", "body").text  # the rest pose
        assert first.measured[1] == pytest.approx(-98.0, abs=0.5)
        # play replays it to the end
        button = [b for b in browser.find_elements("tag name", "button") if b.text == "Play"]
        button[0].click()
        wait_until(lambda: studio._play_time >= frames[-1].time - 1e-6, 60, "playing to the end")
        assert not studio.playing


# ---------------------------------------------------------------------------- the command
def test_ctrl_c_stops_the_server_and_leaves_no_process():
    port = free_port()
    proc, out = start("view", "--web", "--port", str(port))
    try:
        out.wait_for(lambda s: f"http://127.0.0.1:{port}" in s, 60)
        page = wait_until(lambda: _get(f"http://127.0.0.1:{port}"), 30, "the page being served")
        assert b"<html" in page.lower()
    finally:
        code = stop(proc)
    assert code == 0
    with pytest.raises(ProcessLookupError):  # nothing of its process group is left
        os.killpg(proc.pid, 0)
    with pytest.raises(OSError):
        urllib.request.urlopen(f"http://127.0.0.1:{port}", timeout=2)


def _get(url: str) -> bytes | None:
    try:
        with urllib.request.urlopen(url, timeout=2) as r:
            return r.read()
    except OSError:
        return None


@pytest.mark.parametrize("command", [("view",), ("pose",), ("hold", "--duration", "1")])
def test_a_port_in_use_is_one_clear_error_line_and_status_2(command):
    with socket.socket() as busy:
        busy.bind(("127.0.0.1", 0))
        busy.listen()
        port = busy.getsockname()[1]
        r = subprocess.run(
            cli(*command, "--web", "--port", str(port)),
            capture_output=True,
            text=True,
            env=env(),
            timeout=120,
        )
    assert r.returncode == 2
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1, r.stderr
    assert f"port {port} on 127.0.0.1 is in use" in lines[0] and "--port" in lines[0]


def test_run_web_runs_the_motion_and_stops_after_linger():
    port = free_port()
    r = subprocess.run(
        cli("run", "--web", "--port", str(port), "--speed", "20", "--linger", "0"),
        capture_output=True,
        text=True,
        env=env(),
        timeout=120,
    )
    assert r.returncode == 0, r.stderr
    assert f"http://127.0.0.1:{port}" in r.stdout and "return [move" in r.stdout


# ---------------------------------------------------------------------------- library
def test_the_studio_refuses_a_port_in_use_and_a_bad_port():
    from so101sim.errors import SettingError

    with socket.socket() as busy:
        busy.bind(("127.0.0.1", 0))
        busy.listen()
        port = busy.getsockname()[1]
        with pytest.raises(StudioError, match=f"port {port} on 127.0.0.1 is in use"):
            Studio(Simulation().model, port=port)
    with pytest.raises(SettingError, match="port"):
        Studio(Simulation().model, port=70000)


def test_without_viser_the_error_names_the_extra(monkeypatch):
    from so101sim.studio.server import require_viser

    monkeypatch.setitem(sys.modules, "viser", None)
    with pytest.raises(StudioError, match=r'pip install "so101sim\[web\]"'):
        require_viser()


def test_the_timeline_is_bounded_and_thins_itself():
    tl = Timeline(rate=10.0, capacity=100)
    z = np.zeros(6)
    for i in range(10_000):  # 1000 s at 10 frames/s
        tl.add(Frame(i * 0.1, "", z, np.zeros((0, 3)), np.zeros((0, 4)), None, z))
    assert len(tl.frames) <= 100
    assert tl.frames[0].time == 0.0 and tl.frames[-1].time > 990.0
    assert tl.at(500.0).time <= 500.0
    tl.add(Frame(0.0, "", z, np.zeros((0, 3)), np.zeros((0, 4)), None, z))  # a reset
    assert len(tl.frames) == 1


def test_a_live_run_keeps_real_time_at_speed():
    """The observer paces the run to the wall clock: a 1 s hold at speed 4 takes about 0.25 s
    of wall time (a lower bound only: a busy machine may be slower, never faster)."""
    sim = Simulation()
    with Studio(sim.model, port=free_port(), controls=False) as studio:
        observer = StudioObserver(studio)
        observer.pacer.speed = 4.0
        t0 = time.perf_counter()
        sim.hold(1.0, observers=[observer])
        assert time.perf_counter() - t0 >= 0.24
        assert studio.timeline.frames[-1].time == pytest.approx(1.0, abs=0.04)


def test_record_web_shows_the_students_script_live_at_real_time(tmp_path):
    """record SCRIPT --web: the script's launch_passive viewer draws in the studio, paced to
    the wall clock (the handout's wall-clock loop then runs about its simulated seconds)."""
    from so101sim.model import scene_path

    script = Path(__file__).parents[1] / "data" / "wallclock_lab.py"
    port = free_port()
    r = subprocess.run(
        cli("record", str(script), "--web", "--port", str(port), "--linger", "0", "--",
            str(scene_path())),
        capture_output=True, text=True, env=env(), timeout=180,
    )  # fmt: skip
    assert r.returncode == 0, r.stderr
    assert f"http://127.0.0.1:{port}" in r.stdout
    simulated = float(r.stdout.split("s of simulated time")[0].split()[-1])
    # a 6 s wall-clock loop paced to real time: never more simulated seconds than wall seconds
    # (unpaced it steps as fast as it can: many times more); a slow machine only gives fewer
    assert 0.5 < simulated <= 6.5


def test_demo_web_runs_the_episode_in_the_studio():
    port = free_port()
    r = subprocess.run(
        cli("demo", "pick_cube", "--web", "--port", str(port), "--linger", "0"),
        capture_output=True, text=True, env=env(), timeout=180,
    )  # fmt: skip
    assert r.returncode == 0, r.stderr
    assert f"http://127.0.0.1:{port}" in r.stdout and "pick_cube, seed 0: success" in r.stdout


def test_a_bad_linger_or_port_is_refused_before_anything_runs():
    r = subprocess.run(
        cli("run", "--web", "--linger", "-1"), capture_output=True, text=True, env=env(), timeout=60
    )
    assert r.returncode == 2 and "linger" in r.stderr and len(r.stderr.strip().splitlines()) == 1
    r = subprocess.run(
        cli("view", "--web", "--port", "70000"), capture_output=True, text=True, env=env(),
        timeout=60,
    )  # fmt: skip
    assert r.returncode == 2 and "port" in r.stderr
