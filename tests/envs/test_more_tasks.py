"""The tasks push, stack, look_at and lift_mesh: registered, their success tests, the scenes'
mark (touches nothing, stays put) and mesh object (made at load time, drawn by the draft
preset), and each scripted expert on two seeds (100 of 100 over seeds 0-99, docs/tasks.md)."""

import gymnasium as gym
import mujoco
import numpy as np
import pytest

from so101sim.envs import (
    SIM_TASKS,
    TASKS,
    LiftMeshEnv,
    LookAtEnv,
    PushEnv,
    StackEnv,
    evaluate_expert,
    expert_for,
    make,
)
from so101sim.envs.look_at import LOOK_SUCCESS
from so101sim.envs.push import PUSH_SUCCESS_M
from so101sim.scenes import place_object


@pytest.mark.parametrize(
    ("task", "cls", "env_id", "figure"),
    [
        ("push", PushEnv, "so101sim/Push-v0", "cube_to_mark_m"),
        ("stack", StackEnv, "so101sim/Stack-v0", "cube_to_block_m"),
        ("look_at", LookAtEnv, "so101sim/LookAt-v0", "image_offset"),
        ("lift_mesh", LiftMeshEnv, "so101sim/LiftMesh-v0", "object_rise_m"),
    ],
)
def test_task_registered_and_its_expert_succeeds(task, cls, env_id, figure):
    assert TASKS[task] == env_id
    env = gym.make(env_id)
    assert isinstance(env.unwrapped, cls)
    _, info = env.reset(seed=0)
    assert not info["is_success"] and figure in info
    env.close()
    score = evaluate_expert(task, range(2))
    assert score.success_rate == 1.0, score.failed_seeds
    assert (task in SIM_TASKS) == (task != "look_at")  # look_at's scene is pick_cube's


def test_push_success_test_and_the_mark_touches_nothing():
    env = make("push", terminate_on_success=False)
    inner = env.unwrapped
    _, info = env.reset(seed=1)
    mark = inner.object_pose("mark")
    assert info["cube_to_mark_m"] > 0.08 and not info["is_success"]
    gid = mujoco.mj_name2id(inner.model, mujoco.mjtObj.mjOBJ_GEOM, "mark")
    assert inner.model.geom_contype[gid] == 0 and inner.model.geom_conaffinity[gid] == 0
    # the cube put on the mark: success; the mark floats where it was put, step after step
    x, y = mark[:2]
    _, info = env.reset(seed=1, options={"placements": {"cube": (x + 0.01, y, 0.0)}})
    assert info["is_success"] and info["cube_to_mark_m"] < PUSH_SUCCESS_M
    for _ in range(10):
        _, reward, _, _, info = env.step(np.asarray(inner.sim.commanded_array(), np.float32))
    assert info["is_success"] and reward == 1.0
    assert np.allclose(inner.object_pose("mark")[:3], mark[:3], atol=1e-9)
    env.close()


def test_stack_is_judged_on_the_block_and_let_go():
    env = make("stack")
    inner = env.unwrapped
    _, info = env.reset(seed=2)
    assert info["on_block"] == 0.0 and info["cube_to_block_m"] > 0.05
    # the cube put on the block's top by hand, at rest: success
    block = inner.object_pose("block")
    top = block[2] + inner.half_height("block") + inner.half_height("cube")
    place_object(inner.model, inner.sim.data, "cube", block[0], block[1], 0.0, z=top)
    mujoco.mj_forward(inner.model, inner.sim.data)
    ev = inner.evaluate()
    assert ev.success and ev.details["on_block"] == 1.0
    env.close()


def test_look_at_projection_is_where_the_wrist_image_shows_the_cube():
    env = make("look_at", cameras=["wrist"], image_size=(96, 128), terminate_on_success=False)
    expert = expert_for(env)
    obs, info = env.reset(seed=3)
    expert.reset()
    assert info["image_offset"] > LOOK_SUCCESS
    for _ in range(40):
        obs, _, _, _, info = env.step(expert.act(obs))
    assert info["is_success"]
    u, v = obs["environment_state"][-2:]
    assert np.hypot(u, v) <= LOOK_SUCCESS
    image = obs["pixels"]["wrist"].astype(int)
    red = (image[..., 0] > 120) & (image[..., 1] < 80) & (image[..., 2] < 80)
    rows, cols = np.nonzero(red)
    assert len(rows) > 10  # the cube is in the picture...
    h, w = red.shape
    centre = ((cols.mean() - w / 2) / (h / 2), -(rows.mean() - h / 2) / (h / 2))
    assert np.hypot(*centre) < 0.2  # ...at its centre (its top face shows a little higher)
    env.close()


def test_lift_mesh_object_is_a_mesh_and_drawn_in_draft_quality():
    env = make("lift_mesh", render_mode="rgb_array", render_size=(64, 96))
    inner = env.unwrapped
    env.reset(seed=0)
    gid = mujoco.mj_name2id(inner.model, mujoco.mjtObj.mjOBJ_GEOM, "object")
    assert inner.model.geom_type[gid] == mujoco.mjtGeom.mjGEOM_MESH
    mesh = inner.model.geom_dataid[gid]
    assert inner.model.mesh_vertnum[mesh] == 24  # three rings of the octagon
    assert inner.model.body_mass[inner.model.geom_bodyid[gid]] == pytest.approx(0.03)
    frame = env.render()  # the draft preset keeps a scene's own (drawn) mesh objects
    assert frame.shape == (64, 96, 3) and frame.std() > 0
    env.close()
