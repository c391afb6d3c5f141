"""``so101sim compare --web`` (issue 32, point 4): the sim's replay of a recording as the arm
and the real arm as a translucent ghost, the episodes on the studio's timeline, real, sim and
command per joint on the panel; served on 127.0.0.1 only by default, cross-origin websockets
refused, stopped by a signal. Without a browser: the page's objects are checked in Python."""

from __future__ import annotations

import base64
import os
import signal
import socket
import subprocess
import urllib.request

import mujoco
import numpy as np
import pytest

pytest.importorskip("viser", reason="the web extra is not installed: pip install 'so101sim[web]'")
pytest.importorskip("mjviser", reason="the web extra is not installed: pip install 'so101sim[web]'")
pytest.importorskip("pyarrow")

from fidelity_helpers import record, write_lerobot
from studio_helpers import (
    BROWSER_WAIT,
    cli,
    env,
    free_port,
    page_ready,
    screenshot,
    start,
    stop,
    wait_until,
)

from so101sim.fidelity.compare import compare
from so101sim.fidelity.logs import ArmLog, Episode
from so101sim.model import arm_index, arm_units, load_model
from so101sim.model.arm import load_profile
from so101sim.studio.compare import GAP_S, CompareFrame, CompareStudio, Window
from so101sim.studio.ghost import GHOST_OPACITY, arm_bodies

ELBOW_OFF = 12.0  # the real elbow, degrees beyond the sim's


@pytest.fixture(scope="module")
def episodes():
    """Two 1.5 s episodes of the sim's own arm; the real elbow ELBOW_OFF further all along."""
    eps = record(load_profile("sts3215"), [4, 5], seconds=1.5)
    out = []
    for ep in eps:
        meas = ep.measured.copy()
        meas[:, 2] += ELBOW_OFF
        out.append(Episode(ep.index, ep.times, ep.command, meas))
    return out


@pytest.fixture(scope="module")
def result(episodes):
    return compare(ArmLog(30.0, episodes, "synthetic", "csv"), keep_traces=True)


@pytest.fixture(scope="module")
def studio(result):
    windows = [Window(w.episode, w.t0, w.t1, f"ep {w.episode}", w.joint) for w in result.worst]
    # no shadows: the ghost's pixels are what is looked at (software WebGL draws 3x faster)
    with CompareStudio(
        load_model(), result.traces, windows=windows, port=free_port(), shadows=False
    ) as st:
        yield st


def _bodies_at(model, angles) -> np.ndarray:
    """Every body's position (world, m) with the arm at ``angles`` (arm units)."""
    d = mujoco.MjData(model)
    d.qpos[arm_index(model).qpos] = arm_units(model).to_radians(np.asarray(angles))
    mujoco.mj_kinematics(model, d)
    return d.xpos.copy()


def test_the_ghost_follows_the_real_arm_and_the_arm_the_sim(studio, result):
    model = studio.model
    moving = arm_bodies(model)
    assert len(moving) == 6 and set(studio.ghost.handles) <= set(moving)
    assert len(studio.ghost.handles) >= 5  # every moving part that has a visual mesh
    jaw = max(studio.ghost.handles)  # the last body of the chain: the moving jaw
    assert all(h.opacity == GHOST_OPACITY < 1 for h in studio.ghost.handles.values())
    for ep_i, (episode, t) in enumerate([(0, 0.4), (1, 1.0)]):
        tr = result.traces[ep_i]
        k = int(np.searchsorted(tr["t"], t))
        frame = studio.jump(studio.time_of(episode, tr["t"][k]))
        assert isinstance(frame, CompareFrame)
        assert frame.episode == episode and frame.episode_time == pytest.approx(tr["t"][k])
        # the ghost: the real recording's pose at that time; the arm: the sim's
        np.testing.assert_allclose(studio.ghost.angles, tr["real_pose"][k], atol=1e-9)
        real_at = _bodies_at(model, tr["real_pose"][k])
        for b, pos in studio.ghost.body_positions().items():
            np.testing.assert_allclose(pos, real_at[b], atol=1e-6)
        sim_at = _bodies_at(model, tr["sim_pose"][k])
        np.testing.assert_allclose(studio._scratch.xpos[jaw], sim_at[jaw], atol=1e-6)
        # the elbow 12 deg apart: the ghost's jaw is centimetres from the arm's
        assert np.linalg.norm(real_at[jaw] - sim_at[jaw]) > 0.02
        # the panel: the episode and its own time, and each joint's command, real, sim
        assert f"episode {episode} · t = {tr['t'][k]:.2f} s" in studio.status.content
        row = next(r for r in studio.angles.content.splitlines() if r.startswith("| elbow_flex"))
        cells = [c.strip().rstrip("°") for c in row.strip("|").split("|")]
        assert float(cells[2]) == pytest.approx(tr["real"][k, 2], abs=0.06)
        assert float(cells[3]) == pytest.approx(tr["sim"][k, 2], abs=0.06)
        assert float(cells[4]) == pytest.approx(-ELBOW_OFF, abs=0.11)


def test_the_timeline_holds_both_episodes_one_after_the_other(studio, episodes, result):
    frames = studio.timeline.frames
    assert len(frames) == sum(len(ep.times) for ep in episodes)
    start1 = studio.starts[1]
    assert start1 == pytest.approx(episodes[0].times[-1] - episodes[0].times[0] + GAP_S)
    assert studio.slider.max == pytest.approx(start1 + episodes[1].times[-1])
    assert [f.episode for f in frames] == [0] * len(episodes[0].times) + [1] * len(
        episodes[1].times
    )
    # a button per worst window; the chart: command, real and sim of the worst window's
    # joint over the timeline (a break between the episodes), another joint when picked
    assert 1 <= len(studio.window_buttons) <= 3
    assert studio.chart_joint.value == "elbow_flex"
    x, command, real, sim = studio.chart.data
    gap = np.isnan(real)
    assert gap.sum() == 1 and start1 - GAP_S < x[gap][0] < start1
    ok = ~gap
    np.testing.assert_allclose(sim[ok], [f.measured[2] for f in frames])
    np.testing.assert_allclose(real[ok], [f.real[2] for f in frames])
    np.testing.assert_allclose(command[ok], [f.commanded[2] for f in frames])
    studio.chart_joint.value = "wrist_flex"  # as the page's picker sets it
    assert studio.chart.title.startswith("wrist_flex (deg)")
    np.testing.assert_allclose(studio.chart.data[3][ok], [f.measured[3] for f in frames])
    # the episode picker and a worst window's button put the player there (paused)
    studio.picker.value = "1"
    assert studio._play_time == pytest.approx(start1) and not studio.playing
    assert studio.slider.value == pytest.approx(start1, abs=1e-3)
    studio.picker.value = "0"
    assert studio._play_time == pytest.approx(0.0)
    w = next(w for w in result.worst if w.episode == 1)
    button = studio.window_buttons[result.worst.index(w)]
    button.value = True  # as the page's click does
    assert studio._play_time == pytest.approx(studio.time_of(1, w.t0))
    # the player plays on from where it was put, the ghost with it, and stops at the end
    studio.jump(start1)
    studio.speed = 4.0
    studio.play()
    wait_until(lambda: not studio.playing, 120, "playing to the end")
    last = frames[-1]
    assert studio._play_time == pytest.approx(last.time)
    np.testing.assert_allclose(studio.ghost.angles, last.ghost, atol=1e-9)


def _refused(port: int, origin: str) -> bool:
    """A websocket handshake from a page on ``origin``: True when the studio refuses it (HTTP
    403, or a close frame at once)."""
    import viser

    with socket.create_connection(("127.0.0.1", port), timeout=60) as s:
        key = base64.b64encode(os.urandom(16)).decode()
        s.sendall(
            (
                f"GET / HTTP/1.1\r\nHost: 127.0.0.1:{port}\r\nUpgrade: websocket\r\n"
                f"Connection: Upgrade\r\nSec-WebSocket-Key: {key}\r\nSec-WebSocket-Version: 13"
                f"\r\nSec-WebSocket-Protocol: viser-v{viser.__version__}\r\nOrigin: {origin}"
                "\r\n\r\n"
            ).encode()
        )
        data = b""
        while b"\r\n\r\n" not in data and (chunk := s.recv(4096)):
            data += chunk
        status = int(data.split(b" ")[1])
        if status == 403:
            return True
        rest = data.partition(b"\r\n\r\n")[2]
        while len(rest) < 1 and (chunk := s.recv(4096)):
            rest += chunk
        return status == 101 and (rest[0] & 0x0F) == 0x8  # a close frame first


def test_compare_web_serves_the_replay_here_only_and_stops_on_a_signal(episodes, tmp_path):
    root = write_lerobot(tmp_path / "ds", episodes)
    port = free_port()
    proc, out = start("compare", str(root), "--units", "degrees", "--web", "--port", str(port))
    try:
        out.wait_for(lambda s: s.startswith("body joints:"))
        line = out.wait_for(lambda s: f"http://127.0.0.1:{port}" in s)
        assert f"listening on 127.0.0.1:{port}, this machine only" in line
        page = wait_until(lambda: _get(port), 120, "the page being served")
        assert b"<html" in page.lower()
        assert _refused(port, "http://evil.example")
    finally:
        code = stop(proc, signal.SIGTERM, timeout=120)
    text = out.rest()
    assert code == 0, text
    assert "stopped" in text and "Traceback" not in text
    with pytest.raises(ProcessLookupError):  # nothing of its process group is left
        os.killpg(proc.pid, 0)
    assert _get(port) is None


def _get(port: int) -> bytes | None:
    try:
        with urllib.request.urlopen(f"http://127.0.0.1:{port}", timeout=10) as r:
            return r.read()
    except OSError:
        return None


def test_compare_web_refuses_json_and_a_port_in_use_before_replaying(episodes, tmp_path):
    root = write_lerobot(tmp_path / "ds", episodes)
    r = subprocess.run(
        cli("compare", str(root), "--units", "degrees", "--web", "--json"),
        capture_output=True, text=True, env=env(), timeout=300,
    )  # fmt: skip
    assert r.returncode == 2 and r.stdout == ""
    assert r.stderr.strip().count("\n") == 0 and "--json and --web" in r.stderr
    with socket.socket() as busy:
        busy.bind(("127.0.0.1", 0))
        busy.listen()
        port = busy.getsockname()[1]
        r = subprocess.run(
            cli("compare", str(root), "--units", "degrees", "--web", "--port", str(port)),
            capture_output=True, text=True, env=env(), timeout=300,
        )  # fmt: skip
    assert r.returncode == 2 and r.stdout == ""  # refused before anything was replayed
    assert f"port {port} on 127.0.0.1 is in use" in r.stderr


@pytest.mark.slow
def test_the_page_draws_the_ghost_beside_the_arm(studio, browser):
    """In chromium (software WebGL): the panel says the episode, its time and sim − real, and
    the ghost is drawn: hiding it changes thousands of pixels of the page."""
    import imageio.v3 as iio

    studio.jump(studio.time_of(0, 0.4))
    browser.get(studio.url)
    page_ready(browser)
    wait_until(
        lambda: "episode 0 · t = 0.40 s" in browser.find_element("tag name", "body").text,
        BROWSER_WAIT,
        "the panel showing the episode and its time",
    )
    assert "sim − real" in browser.find_element("tag name", "body").text
    pixels = lambda png: iio.imread(png)[..., :3].astype(float) / 255.0  # noqa: E731
    with_ghost = pixels(screenshot(browser))
    for handle in studio.ghost.handles.values():
        handle.visible = False
    try:
        changed = wait_until(
            lambda: (
                int((np.abs(pixels(screenshot(browser)) - with_ghost).max(-1) > 0.1).sum()) > 2000
            ),
            BROWSER_WAIT,
            "the page without the ghost",
        )
    finally:
        for handle in studio.ghost.handles.values():
            handle.visible = True
    assert changed
