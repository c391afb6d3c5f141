"""The pose finder: watching the viewer's pose and printing it as a dict and as TOML."""

from __future__ import annotations

import ast
import contextlib
import os
import subprocess
import sys
import time
import tomllib
from pathlib import Path

import mujoco
import numpy as np
import pytest

from so101sim import cli
from so101sim.errors import ViewerError
from so101sim.model import arm_index, arm_units, default_units
from so101sim.motion.file import parse_motion
from so101sim.sim.simulation import Pacer
from so101sim.units import JOINT_NAMES, STARTING_POSE
from so101sim.viewer import posefinder
from so101sim.viewer.posefinder import (
    PoseWatcher,
    format_python,
    format_toml,
    pose_scene,
    watch_poses,
)

SLIDER_POSE = {
    "shoulder_pan": 30.0,
    "shoulder_lift": -20.0,
    "elbow_flex": 45.5,
    "wrist_flex": 10.0,
    "wrist_roll": -90.0,
    "gripper": 35.0,
}


def _rad(pose):
    u = default_units()
    return u.to_radians(u.pose_to_array(pose))


class FakeViewer:
    """Stands in for MuJoCo's passive viewer: on chosen sync() calls it does what a person
    does with the joint sliders (sets qpos) or with a mouse drag (applies a force)."""

    def __init__(self, m, d, *, sliders=None, drag=None, syncs=40):
        self.m, self.d = m, d
        self.sliders = sliders or {}
        self.drag = drag or {}
        self.syncs = syncs
        self.calls = 0

    def is_running(self):
        return self.calls < self.syncs

    def sync(self):
        self.calls += 1
        if self.calls in self.sliders:
            self.d.qpos[arm_index(self.m).qpos] = _rad(self.sliders[self.calls])
        if self.calls in self.drag:
            body, force = self.drag[self.calls]
            self.d.xfrc_applied[:] = 0
            self.d.xfrc_applied[self.m.body(body).id, :3] = force

    @contextlib.contextmanager
    def lock(self):
        yield


def _fast_pacer():
    t = [0.0]
    return Pacer(clock=lambda: t[0], sleep=lambda s: t.__setitem__(0, t[0] + s))


def test_the_watcher_reports_the_first_pose_then_each_settled_change():
    w = PoseWatcher(default_units(), threshold=0.5, settle=3)
    rest, moved = _rad(STARTING_POSE), _rad(SLIDER_POSE)
    reads = [rest, rest + 1e-5, rest, moved * 0.5 + rest * 0.5, moved, moved, moved, moved]
    out = [w.update(q, t) for t, q in enumerate(reads)]
    reported = [(i, c.number) for i, c in enumerate(out) if c is not None]
    assert reported == [(0, 1), (6, 2)]  # the rest pose at once; the new one once still
    assert out[6].pose == pytest.approx(SLIDER_POSE, abs=0.05)


def test_the_watcher_ignores_jitter_below_the_threshold():
    w = PoseWatcher(default_units(), threshold=0.5)
    q = _rad(STARTING_POSE)
    assert w.update(q) is not None
    nudged = q + np.radians(0.3)
    assert all(w.update(nudged) is None for _ in range(10))


def test_the_formats_paste_back_as_the_same_pose():
    pose = {k: round(v, 1) for k, v in SLIDER_POSE.items()}
    assert ast.literal_eval(format_python(pose)) == pose
    assert tomllib.loads(format_toml("reach", pose))["reach"] == pose
    # and a motion file accepts the TOML line as is
    text = f"[poses]\n{format_toml('reach', pose)}\n[[steps]]\nmove = 'reach'\nduration = 1\n"
    assert parse_motion(text).steps[0].target == pose


def test_the_pose_scene_holds_still_without_gravity_or_actuators():
    m, d = pose_scene()
    units = arm_units(m)
    start = units.from_radians(d.qpos[arm_index(m).qpos])
    np.testing.assert_allclose(start, [STARTING_POSE[n] for n in JOINT_NAMES], atol=1e-9)
    viewer = FakeViewer(m, d, syncs=20)
    changes = list(watch_poses(viewer, m, d, pacer=_fast_pacer()))
    assert [c.number for c in changes] == [1]
    assert d.time > 1.0  # it did simulate: 20 reads at 15 Hz
    np.testing.assert_allclose(units.from_radians(d.qpos[arm_index(m).qpos]), start, atol=0.05)


def test_watch_poses_reports_slider_moves():
    m, d = pose_scene()
    viewer = FakeViewer(m, d, sliders={10: SLIDER_POSE}, syncs=30)
    changes = list(watch_poses(viewer, m, d, pacer=_fast_pacer()))
    assert [c.number for c in changes] == [1, 2]
    assert changes[0].pose == pytest.approx(STARTING_POSE, abs=0.05)
    assert changes[1].pose == pytest.approx(SLIDER_POSE, abs=0.05)


def test_watch_poses_reports_where_a_drag_leaves_the_arm():
    m, d = pose_scene()
    drag = {5: ("gripper", [0.0, 0.0, 2.0]), 12: ("gripper", [0.0, 0.0, 0.0])}
    viewer = FakeViewer(m, d, drag=drag, syncs=80)
    changes = list(watch_poses(viewer, m, d, pacer=_fast_pacer()))
    assert len(changes) >= 2
    last = changes[-1].pose
    # the drag moved the arm, and the last report is where it came to rest
    assert max(abs(last[n] - STARTING_POSE[n]) for n in JOINT_NAMES) > 0.5
    final = arm_units(m).from_radians(d.qpos[arm_index(m).qpos])
    assert np.abs(final - [last[n] for n in JOINT_NAMES]).max() < 0.1


def test_cli_pose_prints_each_pose_as_a_dict_and_as_toml(monkeypatch, capsys):
    made = {}
    printed: list[str] = []
    original = print

    def keep(*args, **kwargs):
        printed.append(" ".join(map(str, args)))
        original(*args, **kwargs)

    def wait_for(text: str, timeout: float = 120.0) -> None:
        """The printed pose is the event (a busy machine is slow to read the arm)."""
        end = time.monotonic() + timeout
        while time.monotonic() < end and not any(text in s for s in printed):
            time.sleep(0.05)

    def fake_managed_viewer(m, d):
        """MuJoCo's managed viewer, paused, a person dragging the joint sliders: qpos set,
        left until the pose is printed (the watcher reads 15 times a second), then closed."""
        made["model"] = m
        wait_for("# pose 1")
        d.qpos[arm_index(m).qpos] = _rad(SLIDER_POSE)
        wait_for("# pose 2")

    monkeypatch.setattr("builtins.print", keep)
    monkeypatch.setattr("so101sim.viewer.view", fake_managed_viewer)
    monkeypatch.setattr("so101sim.viewer.has_display", lambda: True)
    assert cli.main(["pose"]) == 0
    assert made["model"].opt.disableflags & int(mujoco.mjtDisableBit.mjDSBL_GRAVITY)
    out = capsys.readouterr().out
    assert "Press Space" in out  # how to make the joint sliders editable
    dicts = [
        ast.literal_eval(line[len("python: ") :])
        for line in out.splitlines()
        if line.startswith("python: ")
    ]
    tomls = [
        tomllib.loads(line[len("toml:   ") :])
        for line in out.splitlines()
        if line.startswith("toml:   ")
    ]
    assert len(dicts) == len(tomls) == 2
    assert dicts[0] == pytest.approx(STARTING_POSE, abs=0.05)
    assert dicts[1] == pytest.approx(SLIDER_POSE, abs=0.05)
    assert tomls[1]["pose_2"] == dicts[1]
    from so101sim.kinematics import tip_pose

    tips = [line for line in out.splitlines() if line.startswith("tip:    ")]
    assert len(tips) == 2  # the tip next to each joint pose
    assert tips[0] == "tip:    " + tip_pose(dicts[0]).format()


def test_cli_pose_without_a_display_gives_only_the_error(monkeypatch, capsys):
    monkeypatch.delenv("DISPLAY", raising=False)
    monkeypatch.delenv("WAYLAND_DISPLAY", raising=False)
    assert cli.main(["pose"]) == 2
    captured = capsys.readouterr()
    assert "no display" in captured.err
    assert captured.out == ""  # no instructions for a window that never opened


def test_without_a_display_the_message_is_true_for_a_script_and_the_command(monkeypatch, capsys):
    monkeypatch.delenv("DISPLAY", raising=False)
    monkeypatch.delenv("WAYLAND_DISPLAY", raising=False)
    monkeypatch.setattr("sys.platform", "linux")
    m, d = posefinder.pose_scene()
    with pytest.raises(ViewerError) as caught:
        posefinder.open_pose_viewer(m, d)
    message = str(caught.value)
    assert "no display" in message and "--headless" not in message  # pose has no --headless
    assert cli.main(["pose"]) == 2
    err = capsys.readouterr().err.strip()
    assert err == f"so101sim: error: {message}" and len(err.splitlines()) == 1


@pytest.mark.viewer
def test_dragging_a_joint_slider_in_the_viewer_prints_the_pose(xvfb, tmp_path):
    """The real pose finder under Xvfb: a click on Pause pauses MuJoCo's viewer, one opens the
    right panel's Joint section, and dragging shoulder_pan's slider (xdotool) moves the arm:
    the command prints the new pose in degrees."""
    import shutil
    import threading

    if shutil.which("xdotool") is None:
        pytest.skip("xdotool is not installed (apt-get install -y xdotool)")
    env = {**os.environ, "DISPLAY": xvfb}
    env["PYTHONPATH"] = str(Path(__file__).resolve().parents[2] / "src")  # this checkout's
    proc = subprocess.Popen(
        [sys.executable, "-m", "so101sim", "pose"],
        stdout=subprocess.PIPE,
        stderr=subprocess.STDOUT,
        text=True,
        env=env,
    )
    lines: list[str] = []
    reader = threading.Thread(target=lambda: lines.extend(proc.stdout), daemon=True)
    reader.start()

    def xdo(*args: str) -> str:
        return subprocess.run(
            ["xdotool", *args], env=env, capture_output=True, text=True, timeout=30
        ).stdout

    def pans() -> list[float]:
        return [
            ast.literal_eval(line[len("python: ") :])["shoulder_pan"]
            for line in list(lines)
            if line.startswith("python: ")
        ]

    def wait_for(check, timeout: float) -> bool:
        """An event (a window, a printed pose) with a generous deadline: a loaded machine."""
        end = time.monotonic() + timeout
        while time.monotonic() < end:
            if check():
                return True
            time.sleep(0.25)
        return False

    try:
        window = ""

        def window_and_first_pose() -> bool:
            nonlocal window
            found = xdo("search", "--pid", str(proc.pid), "--name", "MuJoCo")
            window = found.split("\n")[0].strip()
            return bool(window and pans())

        # the window (software OpenGL beside other jobs: slow to open) and the first pose
        assert wait_for(window_and_first_pose, 240), "".join(lines)
        assert pans() == [0.0], "".join(lines)

        def pause() -> None:
            """The left panel's Simulation section, its "Pause" choice (a click, not the Space
            key: a key goes to whichever window has the focus); a radio choice: clicking it
            again keeps it (a click the busy viewer lost is made again)."""
            xdo("mousemove", "--window", window, "42", "427", "click", "1")
            time.sleep(0.7)  # the viewer draws a frame before the next input

        pause()
        pause()
        # the right panel's Joint section (collapsed at first): its sliders appear below it
        width = int(xdo("getwindowgeometry", "--shell", window).split("WIDTH=")[1].split()[0])
        header_x = width - 150
        xdo("mousemove", "--window", window, str(header_x), "21", "click", "1")
        time.sleep(1.0)
        x0, x1 = width - 80, width - 40  # shoulder_pan's slider, dragged to the right
        end = time.monotonic() + 300  # a drag the busy viewer did not see (it draws slowly
        attempt = 0  # on a loaded CPU: the section may not be drawn yet) is made again,
        while len(pans()) < 2 and time.monotonic() < end:  # more slowly, until the deadline
            attempt += 1
            if attempt > 1:
                pause()
            step_pause = min(0.3 * attempt, 2.0)  # the viewer draws a frame between the steps
            for x, y in ((x0, 51), (x0 + 10, 51), (x1, 51)):
                step = ["mousemove", "--window", window, str(x), str(y)]
                xdo(*step, *(["mousedown", "1"] if x == x0 else []))
                time.sleep(step_pause)
            xdo("mouseup", "1")
            # the printed pose: the event (a seen drag prints within a second or two; a lost one
            # is made again after 8 s rather than 30: the overall deadline stays 300 s)
            wait_for(lambda: len(pans()) >= 2, 8)
        if len(pans()) < 2:
            with contextlib.suppress(Exception):
                from PIL import ImageGrab

                ImageGrab.grab(xdisplay=xvfb).save(tmp_path / "screen.png")  # to look at
        assert len(pans()) >= 2 and pans()[-1] > 5.0, "".join(lines)
        assert any(line.startswith("toml:   pose_2 = { shoulder_pan = ") for line in lines)
    finally:
        # closed as a person closes it: the viewer's File > Quit (Ctrl+Q), asked again while
        # the busy viewer has not seen it (SIGTERM waits for the window: MuJoCo's viewer
        # holds the main thread in its C loop, where no Python signal handler runs)
        end = time.monotonic() + 120
        while window and proc.poll() is None and time.monotonic() < end:
            xdo("mousemove", "--window", window, "100", "100", "key", "--window", window, "ctrl+q")
            with contextlib.suppress(subprocess.TimeoutExpired):
                proc.wait(timeout=2)
        proc.terminate()
        try:
            proc.wait(timeout=20)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait()
