"""Gymnasium environments for the SO-101: table-top tasks that LeRobot's ``lerobot-eval`` and
RL libraries can run, and a scripted expert per task.

Importing this package registers the environments with Gymnasium:

* ``so101sim/PickCube-v0`` (:class:`PickCubeEnv`): pick up a 2.5 cm cube;
* ``so101sim/CubeToBowl-v0`` (:class:`CubeToBowlEnv`): put the cube in a bowl;
* ``so101sim/Reach-v0`` (:class:`ReachEnv`): bring the tip to a target point;
* ``so101sim/LiftCylinder-v0``, ``so101sim/LiftSphere-v0``, ``so101sim/LiftMesh-v0``: lift a
  cylinder, a ball, an octagonal mesh made at load time;
* ``so101sim/Push-v0`` (:class:`PushEnv`): push the cube onto a mark on the table;
* ``so101sim/Stack-v0`` (:class:`StackEnv`): put the cube on a block;
* ``so101sim/LookAt-v0`` (:class:`LookAtEnv`): centre the cube in the wrist camera.

:func:`make_vec` makes N worlds of a task stepped together on every core (:mod:`.vector`).

>>> import gymnasium as gym, so101sim.envs
>>> env = gym.make("so101sim/PickCube-v0", cameras=["front"], render_mode="rgb_array")
>>> obs, info = env.reset(seed=0)

Actions are joint targets in the arm's units (absolute, or deltas), or end-effector deltas
(:mod:`.actions`); observations a dict whose keys map onto LeRobot's (:mod:`.base`); tasks,
success and rewards in :mod:`.tasks`; the experts in :mod:`.expert`, run by
:func:`run_expert` and :func:`evaluate_expert`. See docs/tasks.md.

May import: ``so101sim.robot`` (the gripper's torque), ``so101sim.preflight`` (joining a Ray
cluster: :mod:`.distributed`), ``so101sim.recording``,
``so101sim.viewer``, ``so101sim.scenes``, ``so101sim.motion``, ``so101sim.sim``,
``so101sim.kinematics``, ``so101sim.model``, ``so101sim.units`` and the base modules.
"""

import gymnasium as gym

from .actions import CONTROL_MODES, ActionMap, ControlSettings
from .base import REWARD_MODES, Evaluation, So101TaskEnv
from .distributed import expert_frames_on_ray
from .expert import CubeToBowlExpert, PickCubeExpert, ScriptedExpert, expert_for
from .look_at import LOOK_SUCCESS, LookAtEnv, LookAtExpert, LookAtTask
from .push import PUSH_SUCCESS_M, PushEnv, PushExpert, PushTask
from .reach import REACH_SUCCESS_M, ReachEnv, ReachExpert, ReachTask
from .run import (
    TASKS,
    EpisodeResult,
    ExpertFrames,
    ExpertScore,
    env_id,
    episode_steps_limit,
    evaluate_expert,
    expert_frames,
    make,
    run_episode,
    run_expert,
)
from .scene_state import SceneState, SimTask
from .stack import StackEnv, StackExpert, StackTask
from .tasks import (
    LIFT_SUCCESS_M,
    SIM_TASKS,
    CubeToBowlEnv,
    CubeToBowlTask,
    LiftCylinderEnv,
    LiftMeshEnv,
    LiftSphereEnv,
    PickCubeEnv,
    PickCubeTask,
    sim_task,
)
from .vector import BACKENDS, So101VectorEnv, make_vec

ENTRY_POINTS = {
    "so101sim/PickCube-v0": "so101sim.envs.tasks:PickCubeEnv",
    "so101sim/CubeToBowl-v0": "so101sim.envs.tasks:CubeToBowlEnv",
    "so101sim/Reach-v0": "so101sim.envs.reach:ReachEnv",
    "so101sim/LiftCylinder-v0": "so101sim.envs.tasks:LiftCylinderEnv",
    "so101sim/LiftSphere-v0": "so101sim.envs.tasks:LiftSphereEnv",
    "so101sim/LiftMesh-v0": "so101sim.envs.tasks:LiftMeshEnv",
    "so101sim/Push-v0": "so101sim.envs.push:PushEnv",
    "so101sim/Stack-v0": "so101sim.envs.stack:StackEnv",
    "so101sim/LookAt-v0": "so101sim.envs.look_at:LookAtEnv",
}


def register_envs() -> None:
    """Register the environments with Gymnasium (done on import; harmless to repeat)."""
    for env_name, entry in ENTRY_POINTS.items():
        if env_name not in gym.registry:
            gym.register(id=env_name, entry_point=entry)


register_envs()

__all__ = [
    "BACKENDS",
    "CONTROL_MODES",
    "ENTRY_POINTS",
    "LIFT_SUCCESS_M",
    "LOOK_SUCCESS",
    "PUSH_SUCCESS_M",
    "REACH_SUCCESS_M",
    "REWARD_MODES",
    "SIM_TASKS",
    "TASKS",
    "ActionMap",
    "ControlSettings",
    "CubeToBowlEnv",
    "CubeToBowlExpert",
    "CubeToBowlTask",
    "EpisodeResult",
    "Evaluation",
    "ExpertFrames",
    "ExpertScore",
    "LiftCylinderEnv",
    "LiftMeshEnv",
    "LiftSphereEnv",
    "LookAtEnv",
    "LookAtExpert",
    "LookAtTask",
    "PickCubeEnv",
    "PickCubeExpert",
    "PickCubeTask",
    "PushEnv",
    "PushExpert",
    "PushTask",
    "ReachEnv",
    "ReachExpert",
    "ReachTask",
    "SceneState",
    "ScriptedExpert",
    "SimTask",
    "So101TaskEnv",
    "So101VectorEnv",
    "StackEnv",
    "StackExpert",
    "StackTask",
    "env_id",
    "episode_steps_limit",
    "evaluate_expert",
    "expert_for",
    "expert_frames",
    "expert_frames_on_ray",
    "make",
    "make_vec",
    "register_envs",
    "run_episode",
    "run_expert",
    "sim_task",
]
