"""The lift tasks (a cylinder, a ball): registered, the pick test on another shape, and the
scripted expert lifting each on a few seeds (100 of 100 over seeds 0-99, docs/tasks.md)."""

import gymnasium as gym
import pytest

from so101sim.envs import SIM_TASKS, TASKS, LiftCylinderEnv, LiftSphereEnv, evaluate_expert


@pytest.mark.parametrize(
    ("task", "cls", "shape"),
    [("lift_cylinder", LiftCylinderEnv, "cylinder"), ("lift_sphere", LiftSphereEnv, "sphere")],
)
def test_lift_task_registered_and_its_expert_lifts(task, cls, shape):
    env = gym.make(TASKS[task])
    inner = env.unwrapped
    assert isinstance(inner, cls) and task in SIM_TASKS
    assert inner.scene.object("object").shape == shape
    _, info = env.reset(seed=0)
    assert not info["is_success"] and info["object_rise_m"] == 0.0
    env.close()
    score = evaluate_expert(task, range(2))
    assert score.success_rate == 1.0
    assert all(e.figures["object_rise_m"] >= 0.03 for e in score.episodes)
