"""LeRobot plugin for so101sim: its table-top tasks as LeRobot environments, for ``lerobot-eval``.

Installed, it is imported by LeRobot's ``register_third_party_plugins()`` (its distribution
name starts with ``lerobot_env_`` and equals this package's name), which registers:

- ``--env.type=so101sim_pick_cube``: :class:`SO101SimPickCubeEnv` (``so101sim/PickCube-v0``);
- ``--env.type=so101sim_cube_to_bowl``: :class:`SO101SimCubeToBowlEnv`
  (``so101sim/CubeToBowl-v0``);
- ``--env.type=so101sim_reach``: :class:`SO101SimReachEnv` (``so101sim/Reach-v0``).

Importing it also registers the Gymnasium environments (``import so101sim.envs``), so
``lerobot.envs.factory.make_env(config)`` finds them in every process.
"""

import so101sim.envs  # noqa: F401  (registers so101sim/PickCube-v0 and so101sim/CubeToBowl-v0)

from .configs import (
    ENV_MODULE,
    NAMESPACE,
    TASK_SCENES,
    SO101SimCubeToBowlEnv,
    SO101SimEnvConfig,
    SO101SimPickCubeEnv,
    SO101SimReachEnv,
)

__version__ = "0.1.0"

__all__ = [
    "ENV_MODULE",
    "NAMESPACE",
    "TASK_SCENES",
    "SO101SimCubeToBowlEnv",
    "SO101SimEnvConfig",
    "SO101SimPickCubeEnv",
    "SO101SimReachEnv",
]
