"""The web studio's command-line behaviour (``--web``): servers that start, stop on Ctrl-C,
refuse a port in use, play runs live and at speed. Every server runs on 127.0.0.1 on a free port
and is stopped at the end of its test. (The page in a real browser: test_studio_page.py.)
"""

from __future__ import annotations

import os
import socket
import subprocess
import sys
import time
import urllib.request
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("viser", reason="the web extra is not installed: pip install 'so101sim[web]'")
pytest.importorskip("mjviser", reason="the web extra is not installed: pip install 'so101sim[web]'")

from studio_helpers import (
    cli,
    env,
    free_port,
    start,
    stop,
    wait_until,
)

from so101sim import Simulation
from so101sim.studio import Studio, StudioError
from so101sim.studio.live import StudioObserver
from so101sim.studio.timeline import Frame, Timeline


# ---------------------------------------------------------------------------- the command
def test_ctrl_c_stops_the_server_and_leaves_no_process():
    port = free_port()
    proc, out = start("view", "--web", "--port", str(port))
    try:
        out.wait_for(lambda s: f"http://127.0.0.1:{port}" in s)
        page = wait_until(lambda: _get(f"http://127.0.0.1:{port}"), 60, "the page being served")
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
            timeout=300,
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
        timeout=300,
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


def test_no_shadows_turns_off_every_lights_shadow_and_the_default_keeps_the_models():
    """``shadows=False`` (``--no-shadows``): no light of the page casts a shadow (a browser
    without a GPU skips the shadow map every frame); by default the model's light casts one,
    as its ``castshadow`` says."""
    from so101sim.cli.main import build_parser

    model = Simulation().model
    assert model.light_castshadow.any()
    with Studio(model, port=free_port(), controls=False) as studio:
        assert any(getattr(light, "cast_shadow", False) for light in studio.lights)
    with Studio(model, port=free_port(), controls=False, shadows=False) as studio:
        assert len(studio.lights) >= 2 + model.nlight
        assert not any(getattr(light, "cast_shadow", False) for light in studio.lights)
    parser = build_parser()
    for command in (["view"], ["pose"], ["run", "motion.toml"], ["compare", "data"]):
        assert parser.parse_args([*command, "--web"]).shadows is True
        assert parser.parse_args([*command, "--web", "--no-shadows"]).shadows is False


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


class _Clock:
    """A wall clock that sleeping moves exactly on (never behind), and that a test can jump."""

    def __init__(self):
        self.t = 100.0

    def __call__(self):
        return self.t

    def sleep(self, s):
        self.t += s


def test_a_page_that_falls_behind_real_time_is_said_once(caplog):
    """The page's observer says the first time it falls behind the wall clock (a logged
    warning with when and by how much), once; the script's own time between two runs, or
    between two frames of its own loop, is not a lag; ``warn_lag=False`` keeps it quiet."""
    from so101sim.sim.simulation import Pacer
    from so101sim.studio.live import StudioViewer

    sim = Simulation()
    with Studio(sim.model, port=free_port(), controls=False) as studio:
        clock = _Clock()
        shown = studio.show

        def stalling_show(*args, **kwargs):  # the 10th frame takes 2 s of the wall clock
            stalling_show.frames += 1
            if stalling_show.frames == 10:
                stalling_show.clock.t += 2.0
            return shown(*args, **kwargs)

        stalling_show.frames, stalling_show.clock = 0, clock
        studio.show = stalling_show
        observer = StudioObserver(studio, Pacer(clock=clock, sleep=clock.sleep))
        with caplog.at_level("WARNING", logger="so101sim"):
            sim.hold(1.0, observers=[observer])
            sim.hold(0.5, observers=[observer])
        said = [r.getMessage() for r in caplog.records if "fell behind real time" in r.message]
        assert len(said) == 1, said
        # the stall came in the 10th frame (t = 0.30 s at 30 frames a second): said at the
        # next frame, 1/30 s later (to the 2 ms step)
        assert said[0].startswith("the browser page fell behind real time at 0.3")
        assert float(said[0].split(" at ")[1].split()[0]) == pytest.approx(0.333, abs=0.01)
        assert "(1.97 s behind the wall clock)" in said[0]
        studio.show = shown

        caplog.clear()  # the script's own time between two runs: not a lag
        paused = Simulation()
        clock2 = _Clock()
        observer = StudioObserver(studio, Pacer(clock=clock2, sleep=clock2.sleep))
        with caplog.at_level("WARNING", logger="so101sim"):
            paused.hold(0.2, observers=[observer])
            clock2.t += 3.0
            paused.hold(0.2, observers=[observer])
        assert observer.pacer.lag_events == 0
        # the second hold paced in real time again (from its first frame: to 2 frames)
        assert clock2.t == pytest.approx(100.0 + 0.2 + 3.0 + 0.2, abs=0.07)
        # nor a pause in a script's own loop with its viewer (record SCRIPT --web)
        clock3 = _Clock()
        viewer = StudioViewer(
            studio, paused.model, paused.data, Pacer(clock=clock3, sleep=clock3.sleep)
        )
        for k in range(20):
            paused.data.time += 0.02
            viewer.sync()
            if k == 9:
                clock3.t += 3.0  # input() in the loop
        assert viewer.pacer.lag_events == 0
        assert not [r for r in caplog.records if "fell behind" in r.message]

        # told not to (so101sim run --web says it at the end instead), the same stall
        quiet_clock = _Clock()
        stalling_show.frames, stalling_show.clock = 0, quiet_clock
        studio.show = stalling_show
        quiet = StudioObserver(
            studio, Pacer(clock=quiet_clock, sleep=quiet_clock.sleep), warn_lag=False
        )
        with caplog.at_level("WARNING", logger="so101sim"):
            Simulation().hold(1.0, observers=[quiet])
        studio.show = shown
        assert quiet.pacer.lag_events == 1
        assert not [r for r in caplog.records if "fell behind" in r.message]


def test_record_web_shows_the_students_script_live_at_real_time(tmp_path):
    """record SCRIPT --web: the script's launch_passive viewer draws in the studio, paced to
    the wall clock (the handout's wall-clock loop then runs about its simulated seconds)."""
    from so101sim.model import scene_path

    script = Path(__file__).parents[1] / "data" / "wallclock_lab.py"
    port = free_port()
    r = subprocess.run(
        cli("record", str(script), "--web", "--port", str(port), "--linger", "0", "--",
            str(scene_path())),
        capture_output=True, text=True, env=env(), timeout=400,
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
        capture_output=True, text=True, env=env(), timeout=400,
    )  # fmt: skip
    assert r.returncode == 0, r.stderr
    assert f"http://127.0.0.1:{port}" in r.stdout and "pick_cube, seed 0: success" in r.stdout


def test_a_bad_linger_or_port_is_refused_before_anything_runs():
    r = subprocess.run(
        cli("run", "--web", "--linger", "-1"),
        capture_output=True,
        text=True,
        env=env(),
        timeout=180,
    )
    assert r.returncode == 2 and "linger" in r.stderr and len(r.stderr.strip().splitlines()) == 1
    r = subprocess.run(
        cli("view", "--web", "--port", "70000"), capture_output=True, text=True, env=env(),
        timeout=180,
    )  # fmt: skip
    assert r.returncode == 2 and "port" in r.stderr
