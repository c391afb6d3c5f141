"""``lerobot-eval`` itself on the so101sim environment, with a tiny ACT policy built and saved
locally (untrained: the test is that LeRobot's CLI runs the environment end to end)."""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest
from build_tiny_act import build
from lerobot_env_so101sim import SO101SimPickCubeEnv

pytestmark = pytest.mark.cli

STEPS = 20  # env steps per episode (30 Hz: 0.67 s of simulated time)


def _lerobot_eval() -> str:
    found = shutil.which("lerobot-eval") or str(Path(sys.executable).parent / "lerobot-eval")
    assert Path(found).exists(), "lerobot-eval is not installed beside this Python"
    return found


def test_lerobot_eval_runs_two_episodes_of_a_local_policy(tmp_path):
    """The policy sees only the front camera at 48x64: lerobot-eval's env takes its cameras
    and image size from --policy.path (none given on the command line)."""
    size = {"observation_height": 48, "observation_width": 64, "cameras": ["front"]}
    build(SO101SimPickCubeEnv(**size), tmp_path / "policy")
    out = tmp_path / "eval"
    args = [
        _lerobot_eval(),
        "--env.type=so101sim_pick_cube",
        "--env.visualization_height=96",
        "--env.visualization_width=128",
        f"--env.episode_length={STEPS}",
        f"--policy.path={tmp_path / 'policy'}",
        "--eval.n_episodes=2",
        "--eval.batch_size=1",
        f"--output_dir={out}",
    ]
    done = subprocess.run(
        args,
        stdout=subprocess.PIPE,
        stderr=subprocess.STDOUT,
        text=True,
        timeout=900,
        env={**os.environ, "HF_HUB_OFFLINE": "1"},
    )
    assert done.returncode == 0, done.stdout[-4000:]
    assert "Traceback" not in done.stdout, done.stdout[-4000:]
    assert "End of eval" in done.stdout
    info = json.loads((out / "eval_info.json").read_text())
    overall = info["overall"]
    assert overall["n_episodes"] == 2 and 0.0 <= overall["pc_success"] <= 100.0
    assert info["per_task"][0]["task_group"] == "so101sim_pick_cube"
    videos = [Path(p) for p in overall["video_paths"]]
    assert len(videos) == 2 and all(p.is_file() and p.stat().st_size > 0 for p in videos)


def test_so101sim_eval_refuses_bad_settings_in_one_line_before_any_work(tmp_path, capsys):
    """A bad --randomize, or an -o that holds an earlier evaluation: one error line, exit 2,
    no progress bar, nothing written."""
    from so101sim.cli.main import main

    policy = tmp_path / "policy"
    policy.mkdir()
    (policy / "config.json").write_text("{}")
    out = tmp_path / "eval"
    out.mkdir()
    (out / "eval.json").write_text("{}")
    for argv, word in (
        (["--randomize", "light,nosuch=1", "-o", str(tmp_path / "new")], "nosuch"),
        (["-o", str(out)], "earlier evaluation"),
    ):
        assert main(["eval", str(policy), "--episodes", "2", *argv]) == 2
        err = capsys.readouterr().err
        assert word in err and len(err.strip().splitlines()) == 1 and "episode" not in err
    assert not (tmp_path / "new").exists() and (out / "eval.json").read_text() == "{}"


def test_so101sim_eval_keeps_every_episodes_draws_past_the_last_failure_video(tmp_path):
    """``--randomize``: every episode's draws are in eval.json, also those of failures whose
    video ``--max-videos`` leaves out (an untrained policy fails all three)."""
    from so101sim.cli.main import main

    size = {"observation_height": 48, "observation_width": 64, "cameras": ["front"]}
    build(SO101SimPickCubeEnv(**size), tmp_path / "policy")
    out = tmp_path / "eval"
    argv = [
        "eval", str(tmp_path / "policy"), "--episodes", "3", "--episode-length", "6",
        "--randomize", "light", "--max-videos", "1", "--workers", "1", "-o", str(out),
    ]  # fmt: skip
    assert main(argv) == 0
    report = json.loads((out / "eval.json").read_text())
    episodes = report["per_episode"]
    assert [e["success"] for e in episodes] == [False] * 3
    assert [bool(e["video"]) for e in episodes] == [True, False, False]
    assert len(list((out / "videos").iterdir())) == 1
    draws = [e["randomization"] for e in episodes]
    assert all(d and "objects" in d and "lighting" in d for d in draws), draws
    sizes = {d["objects"]["size"]["cube"] for d in draws}
    assert len(sizes) == 3  # each episode its own draw
