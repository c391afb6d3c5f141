"""The robot's per-call reads and writes of a :class:`~so101sim.sim.simulation.Simulation`:
plain floats, no NumPy arrays, bit for bit what :meth:`~Simulation.pose_array` and
:meth:`~Simulation.command_array` give (the LeRobot-style follower calls them every action)."""

from __future__ import annotations

from typing import Any

Simulation = Any  # a so101sim.sim.simulation.Simulation (not imported: it imports this module)


def pose_values(sim: Simulation) -> list[float]:
    """The measured pose as six plain floats in arm units (:meth:`Simulation.pose_array`)."""
    q = sim.data.qpos.tolist()
    return sim.units.values_from_radians([q[i] for i in sim._qpos_list])


def command_joints(sim: Simulation, indices: list[int], values: list[float]) -> None:
    """Set the targets of some joints (indices into :data:`~so101sim.units.JOINT_NAMES`) to
    ``values``: arm units, already checked and inside the limits."""
    to_radians, act = sim.units.joint_to_radians, sim._actuator_list
    with sim.lock:
        ctrl = sim.data.ctrl
        for i, v in zip(indices, values, strict=True):
            ctrl[act[i]] = to_radians(i, v)
        sim._state.commanded = True


__all__ = ["command_joints", "pose_values"]
