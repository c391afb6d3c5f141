"""``expert_frames``: one scripted-expert episode as a dataset holds it (``so101sim dataset``'s
workers run it): frame t is the observation before action t; the same seed gives the same
episode; success ends it ``after_success_s`` later."""

from __future__ import annotations

import numpy as np
import pytest

from so101sim.envs import episode_steps_limit, expert_frames, make
from so101sim.errors import SettingError
from so101sim.units import STARTING_POSE


def test_expert_frames_are_one_deterministic_successful_take():
    a = expert_frames("pick_cube", 3, fps=30, after_success_s=0.5)
    b = expert_frames("pick_cube", 3, fps=30, after_success_s=0.5)
    assert a.success and a.success_frame is not None
    assert len(a.actions) == a.success_frame + 15  # 0.5 s at 30 fps after success
    assert a.states.shape == a.actions.shape == (len(a.actions), 6)
    assert a.environment_state.shape == (len(a.actions), 7) and a.states.dtype == np.float32
    np.testing.assert_allclose(a.states[0], list(STARTING_POSE.values()), atol=0.5)
    np.testing.assert_array_equal(a.states, b.states)
    np.testing.assert_array_equal(a.actions, b.actions)
    # the cube rose by the end: the state of the objects is the real one
    assert a.environment_state[-1, 2] - a.environment_state[0, 2] > 0.03
    assert a.randomization == {}
    c = expert_frames("pick_cube", 4, randomize="light", after_success_s=0.0)
    assert c.randomization and c.success


def test_episode_steps_limit_is_the_environments_own_limit():
    """The most frames an episode can have (a dataset writer sizes its queues with it)."""
    env = make("push", control_hz=7)
    try:
        assert episode_steps_limit("push", 7) == env.unwrapped.max_episode_steps == 70
    finally:
        env.close()
    assert episode_steps_limit("pick_cube", 30) == 240  # 8 s at 30 Hz
    assert episode_steps_limit("so101sim/Stack-v0", 25.0) == 300  # 12 s at 25 Hz
    with pytest.raises(SettingError, match="hz"):
        episode_steps_limit("pick_cube", 0)
    with pytest.raises(SettingError, match="unknown task"):
        episode_steps_limit("juggle", 30)
