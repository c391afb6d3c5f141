"""An episode's start does not depend on the episodes before it (a randomised environment's
reset gives the model, state and observation a new environment gives), and ``expert_frames``
keeps its environment between clean episodes (a dataset worker makes it once) with the same
episodes as a new environment."""

from __future__ import annotations

import numpy as np

from so101sim.envs import expert_frames, make
from so101sim.envs import run as envs_run

KW = {"control": "joint", "object_state": True, "terminate_on_success": False}


def test_a_reset_after_a_randomised_episode_starts_as_a_new_environment_does() -> None:
    used = make("pick_cube", randomize="full", **KW)
    new = make("pick_cube", randomize="full", **KW)
    try:
        used.reset(seed=3)
        for _ in range(20):
            used.step(used.action_space.sample())
        obs_used, _ = used.reset(seed=4)
        obs_new, _ = new.reset(seed=4)
        for key in obs_new:
            np.testing.assert_array_equal(obs_used[key], obs_new[key], err_msg=key)
        a, b = used.unwrapped, new.unwrapped
        for name in ("geom_size", "body_mass", "geom_friction", "actuator_biasprm",
                     "actuator_forcerange", "dof_frictionloss"):  # fmt: skip
            np.testing.assert_array_equal(getattr(a.model, name), getattr(b.model, name), name)
        np.testing.assert_array_equal(a.sim.data.qpos, b.sim.data.qpos)
    finally:
        used.close()
        new.close()


def test_expert_frames_on_a_kept_environment_equal_a_new_one() -> None:
    kw = {"cameras": ("wrist",), "image_size": (32, 32)}
    kept = [expert_frames("pick_cube", s, **kw) for s in (5, 6)]  # the second on a kept env
    envs_run._close_kept()
    new = expert_frames("pick_cube", 6, **kw)
    assert kept[1].success_frame == new.success_frame
    np.testing.assert_array_equal(kept[1].actions, new.actions)
    np.testing.assert_array_equal(kept[1].states, new.states)
    np.testing.assert_array_equal(kept[1].images["wrist"], new.images["wrist"])
    envs_run._close_kept()
    assert "env" not in envs_run._KEPT
