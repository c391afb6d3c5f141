"""``so101sim demo <task>``: the scripted expert once, headless here, on video with --record."""

from __future__ import annotations

import re

import pytest
from recording_helpers import count_frames, no_partial_files

from so101sim.cli import main
from so101sim.cli.demo import format_figures
from so101sim.envs import make, run_episode


def test_demo_pick_cube_records_a_verified_video(tmp_path, capsys):
    path = tmp_path / "pick.mp4"
    argv = ["demo", "pick_cube", "--seed", "3", "--record", str(path), "--headless"]
    argv += ["--width", "96", "--height", "64", "--fps", "10", "--quality", "draft"]
    assert main(argv) == 0
    out = capsys.readouterr().out
    assert "pick_cube, seed 3: success at t = " in out
    rise = float(re.search(r"cube lifted ([\d.]+) mm", out).group(1))
    assert rise >= 30.0
    sim_time = float(re.search(r"([\d.]+) s of simulated time in all", out).group(1))
    frames = count_frames(path)
    # one frame at the start, then one every 1/10 s of simulated time
    assert abs(frames - (sim_time * 10 + 1)) <= 1.5
    assert f"wrote the video to {path} ({frames} frames)" in out
    assert no_partial_files(tmp_path)


@pytest.mark.parametrize("camera", ["wrist", "free"])
def test_demo_records_from_each_camera_its_help_names(tmp_path, capsys, camera):
    path = tmp_path / f"{camera}.mp4"
    argv = ["demo", "pick_cube", "--record", str(path), "--headless", "--camera", camera]
    assert main([*argv, "--width", "64", "--height", "48", "--fps", "5"]) == 0
    assert count_frames(path) > 10 and "success" in capsys.readouterr().out


def test_demo_refuses_to_overwrite_without_force(tmp_path, capsys):
    path = tmp_path / "pick.mp4"
    path.write_bytes(b"keep")
    assert main(["demo", "pick_cube", "--record", str(path), "--headless"]) == 2
    assert "--force" in capsys.readouterr().err
    assert path.read_bytes() == b"keep"


def test_demo_cube_to_bowl_headless(capsys):
    assert main(["demo", "cube_to_bowl", "--seed", "1", "--headless"]) == 0
    out = capsys.readouterr().out
    assert "cube_to_bowl, seed 1: success" in out
    assert "mm from the bowl's centre (in the bowl)" in out


def test_demo_unknown_task_lists_the_tasks(capsys):
    assert main(["demo", "juggle", "--headless"]) == 2
    err = capsys.readouterr().err
    assert "unknown task 'juggle'" in err and "pick_cube, cube_to_bowl" in err


@pytest.mark.parametrize("option", [["--fps", "0"], ["--width", "7"], ["--seed", "-1"]])
def test_demo_bad_numbers_exit_2_before_running(option, tmp_path, capsys):
    path = tmp_path / "x.mp4"
    assert main(["demo", "pick_cube", "--headless", "--record", str(path), *option]) == 2
    assert "so101sim: error:" in capsys.readouterr().err
    assert not path.exists()


def test_format_figures():
    assert format_figures({"cube_rise_m": 0.0459, "grasped": 1.0}) == (
        "cube lifted 45.9 mm, held in the gripper"
    )
    text = format_figures({"cube_to_bowl_m": 0.1, "in_bowl": 0.0, "grasped": 0.0})
    assert text == "cube 100.0 mm from the bowl's centre (not in the bowl), not held"


class _ClosedViewer:
    def is_running(self) -> bool:
        return False


def test_an_episode_ends_when_its_viewer_is_closed():
    env = make("pick_cube")
    try:
        env.unwrapped._viewer = _ClosedViewer()
        result = run_episode(env, 0)
        env.unwrapped._viewer = None
    finally:
        env.close()
    assert not result.completed and result.steps == 0 and not result.success
