"""An episode's start does not depend on the episodes before it (a randomised environment's
reset gives the model, state and observation a new environment gives), and ``expert_frames``
keeps its environment between episodes, clean or randomised (a dataset worker makes it once),
with the same episodes as a new environment."""

from __future__ import annotations

import numpy as np
import pytest

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


@pytest.mark.parametrize(
    "randomize", [None, "light,textures=0.5,distractors=2"], ids=["clean", "randomised"]
)
def test_expert_frames_on_a_kept_environment_equal_a_new_one(randomize) -> None:
    kw = {"cameras": ("wrist",), "image_size": (32, 32), "randomize": randomize}
    kept = [expert_frames("pick_cube", s, **kw) for s in (5, 6)]  # the second on a kept env
    assert "env" in envs_run._KEPT  # kept, randomised or not
    envs_run._close_kept()
    new = expert_frames("pick_cube", 6, **kw)
    assert kept[1].success and kept[1].success_frame == new.success_frame
    np.testing.assert_array_equal(kept[1].actions, new.actions)
    np.testing.assert_array_equal(kept[1].states, new.states)
    np.testing.assert_array_equal(kept[1].images["wrist"], new.images["wrist"])
    assert kept[1].randomization == new.randomization
    assert bool(new.randomization) is (randomize is not None)
    envs_run._close_kept()
    assert "env" not in envs_run._KEPT


def test_the_sag_aim_follows_the_servos_stiffness_as_it_is_now() -> None:
    """The experts aim through the sag with the stiffness the model has at each call (an
    environment's physical randomisation changes it at each reset), not the one it had when
    the expert was made: on a kept environment that was the previous episode's."""
    from so101sim.envs.planning import ThroughSag
    from so101sim.model.index import arm_index

    env = make("pick_cube", **KW)
    try:
        model = env.unwrapped.model
        aim = ThroughSag(model)
        target = np.array([0.0, -20.0, 30.0, 40.0, 0.0, 10.0])
        before = aim(target)
        act = arm_index(model).actuator
        model.actuator_biasprm[act, 1] *= 2.0  # twice as stiff: half the sag to aim through
        after = aim(target)
        np.testing.assert_allclose(after[:5] - target[:5], (before[:5] - target[:5]) / 2, atol=1e-9)
        np.testing.assert_allclose(after, ThroughSag(model)(target), atol=1e-12)
        assert np.abs(before[1:4] - target[1:4]).max() > 0.1  # there is a sag to aim through
    finally:
        env.close()
