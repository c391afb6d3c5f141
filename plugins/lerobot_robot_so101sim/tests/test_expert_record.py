"""``lerobot-record`` with the scripted expert (``--teleop.type=so101_sim_expert``): five
takes recorded in LeRobot's wall-clock loop, each from a new placement, whose recorded actions
pick the cube up when replayed in ``so101sim/PickCube-v0`` from the same seeds. In a file of its
own: it waits on LeRobot's clock for 40 s, so another worker runs the other tests meanwhile."""

from __future__ import annotations

import json
import re

import numpy as np
from test_cli import QUIET, run, tool
from test_expert import EPISODE_S, EPISODES, FPS, FRAMES, REPO_ID, START

from so101sim.envs import PickCubeEnv


def test_lerobot_record_with_the_expert_records_five_pick_demonstrations(tmp_path):
    from lerobot.datasets import LeRobotDataset

    root = tmp_path / "expert"
    out = run(
        [
            tool("lerobot-record"), "--robot.type=so101_sim", "--robot.mode=lockstep",
            "--robot.scene=pick_cube", "--teleop.type=so101_sim_expert",
            "--teleop.task=pick_cube", f"--teleop.episode_time_s={EPISODE_S}",
            f"--dataset.repo_id={REPO_ID}", f"--dataset.root={root}",
            "--dataset.single_task=Pick up the red cube.",
            f"--dataset.num_episodes={EPISODES}", f"--dataset.episode_time_s={EPISODE_S}",
            "--dataset.reset_time_s=0", f"--dataset.fps={FPS}", "--dataset.push_to_hub=false",
            "--display_data=false", *QUIET,
        ],
        tmp_path / "record.log",
    )  # fmt: skip
    info = json.loads((root / "meta" / "info.json").read_text())
    assert info["total_episodes"] == EPISODES and info["robot_type"] == "so101_sim"
    ds = LeRobotDataset(REPO_ID, root=root)
    data = ds.hf_dataset.with_format("numpy")
    episode = np.asarray(data["episode_index"])
    states = np.stack(data["observation.state"])
    actions = np.stack(data["action"])
    counts = np.bincount(episode, minlength=EPISODES)
    # frames follow LeRobot's wall clock: a loop that keeps up records every one of them
    assert len(counts) == EPISODES and all(0 < c <= FRAMES for c in counts), counts
    logged = re.findall(r"take (\d+) \(seed (\d+)\): success at call (\d+)", out)
    assert [int(t) for t, _, _ in logged] == list(range(EPISODES)), out[-3000:]
    firsts = [actions[episode == e][:40] for e in range(EPISODES)]
    for e in range(EPISODES):
        ep_states = states[episode == e]
        np.testing.assert_allclose(ep_states[0], START, atol=0.5)  # a new take's start
        for other in range(e):  # another placement: another demonstration
            assert np.abs(firsts[e] - firsts[other]).max() > 2.0
        replay_succeeds(actions[episode == e], ep_states, seed=e)


def replay_succeeds(actions: np.ndarray, states: np.ndarray, seed: int) -> None:
    """The recorded actions, replayed from the take's seed in ``so101sim/PickCube-v0`` at the
    dataset's rate, lift the cube, through the recorded states."""
    env = PickCubeEnv(control_hz=FPS, terminate_on_success=False, episode_seconds=60)
    try:
        obs, _ = env.reset(seed=seed)
        success = False
        worst = 0.0
        for k, action in enumerate(actions):
            if k < len(states):
                worst = max(worst, float(np.abs(obs["agent_pos"] - states[k]).max()))
            obs, _, _, _, info = env.step(action.astype(np.float32))
            success = success or info["is_success"]
        assert success, f"episode {seed}: the cube rose {info['cube_rise_m'] * 1000:.1f} mm"
        assert worst < 0.05, f"episode {seed}: replayed states {worst:.3f} deg off the recorded"
    finally:
        env.close()
