from pathlib import Path

import mujoco
import pytest

from so101sim.lab import handin, hold_position, move_to_pose, set_initial_pose
from so101sim.model import scene_path
from so101sim.units import STARTING_POSE, ZERO_POSE

SCRIPT = Path(__file__).parents[1] / "data" / "wallclock_lab.py"


def _frames(path):
    import imageio.v3 as iio

    return sum(1 for _ in iio.imiter(path))


@pytest.mark.slow
def test_an_unchanged_wall_clock_script_records_six_simulated_seconds(tmp_path, capsys):
    out = tmp_path / "lab.mp4"
    run = handin.run_script(SCRIPT, [str(scene_path())], out, width=320, height=240)
    assert run.exit_status == 0 and run.outputs["video"] == out
    assert run.simulated_seconds == pytest.approx(6.0, abs=0.01)
    assert "done at t = 6.0" in capsys.readouterr().out  # the script's own print
    assert abs(_frames(out) - 181) <= 1  # 30 frames per simulated second


@pytest.mark.slow
def test_the_lab_helpers_with_record_give_the_same_frames(tmp_path):
    m = mujoco.MjModel.from_xml_path(str(scene_path()))
    d = mujoco.MjData(m)
    set_initial_pose(d, STARTING_POSE)
    out = tmp_path / "lab.mp4"
    with handin.record(m, d, out, width=320, height=240, title="Lab 2 - Ada") as viewer:
        move_to_pose(m, d, viewer, ZERO_POSE, 2.0)
        hold_position(m, d, viewer, 2.0)
        move_to_pose(m, d, viewer, STARTING_POSE, 2.0)
    assert viewer.outputs["video"] == out
    assert _frames(out) == 181
    assert d.time == pytest.approx(6.0)


def test_a_raw_loop_with_record_and_the_csv_log(tmp_path):
    m = mujoco.MjModel.from_xml_path(str(scene_path()))
    d = mujoco.MjData(m)
    steps = 0
    with handin.record(m, d, tmp_path / "a.mp4", log=tmp_path / "a.csv", width=64, height=48) as v:
        while v.is_running() and steps < 500:
            steps += 1
            with v.lock():
                v.opt.flags[mujoco.mjtVisFlag.mjVIS_CONTACTPOINT] = 1
            mujoco.mj_step(m, d)
            v.sync()
    rows = (tmp_path / "a.csv").read_text().splitlines()
    assert len(rows) == 1 + 500  # a header, then one row per step
    assert 30 <= _frames(tmp_path / "a.mp4") <= 31  # t = 0, 1/30, ... up to 1 s
    assert not v.is_running()


@pytest.mark.slow
def test_the_shipped_lab_example_records_without_a_display(tmp_path, monkeypatch, capsys):
    # it opens so101sim's viewer only when there is a display: under record there is one
    from so101sim import viewer
    from so101sim.lab import starter

    monkeypatch.delenv("DISPLAY", raising=False)
    monkeypatch.delenv("WAYLAND_DISPLAY", raising=False)
    out = tmp_path / "lab.mp4"
    script = starter.examples_dir() / "lab_motion.py"
    run = handin.run_script(script, [], out, width=64, height=48)
    assert run.exit_status == 0 and run.simulated_seconds == pytest.approx(6.0, abs=0.01)
    assert abs(_frames(out) - 181) <= 1
    assert "t = 6.000 s" in capsys.readouterr().out
    assert not viewer.has_display()  # put back after the run


def test_a_script_that_opens_no_viewer_says_so(tmp_path):
    script = tmp_path / "s.py"
    script.write_text("print('hello')\n")
    with pytest.raises(handin.NothingRecordedError, match="launch_passive"):
        handin.run_script(script, [], tmp_path / "x.mp4")
    assert not (tmp_path / "x.mp4").exists()


def test_the_scripts_exit_status_and_exceptions_pass_through(tmp_path):
    ok = tmp_path / "exit3.py"
    ok.write_text(
        "import sys, mujoco, mujoco.viewer\n"
        f"m = mujoco.MjModel.from_xml_path({str(scene_path())!r}); d = mujoco.MjData(m)\n"
        "v = mujoco.viewer.launch_passive(m, d)\n"
        "for _ in range(20):\n    mujoco.mj_step(m, d); v.sync()\n"
        "sys.exit(3)\n"
    )
    run = handin.run_script(ok, [], tmp_path / "e.mp4", width=64, height=48)
    assert run.exit_status == 3 and (tmp_path / "e.mp4").is_file()
    bad = tmp_path / "boom.py"
    bad.write_text(ok.read_text().replace("sys.exit(3)", "raise RuntimeError('boom')"))
    with pytest.raises(RuntimeError, match="boom"):
        handin.run_script(bad, [], tmp_path / "b.mp4", width=64, height=48)
    assert (tmp_path / "b.mp4").is_file()  # the frames so far are kept
    import time

    assert time.time() > 1e9  # the real clock is back


def test_waiting_for_ffmpeg_does_not_move_a_scripts_simulated_clock():
    # ffmpeg behind on a busy machine: the recorder waits for it on the script's thread, while
    # the script's time.sleep is the simulated clock's (which moves at once): before, each
    # look at the queue moved the script's clock on, and a 6 s script's loops ended early.
    import time

    from so101sim.lab.simclock import SimClock, simulated_time
    from so101sim.recording import encoder

    clock = SimClock()
    with simulated_time(clock):
        t0 = time.monotonic()
        for _ in range(10):
            encoder._pause(0.001)
        assert time.monotonic() == t0  # the script's clock did not move
        time.sleep(0.5)  # the script's own sleep still does
    assert clock.elapsed() == 0.5
