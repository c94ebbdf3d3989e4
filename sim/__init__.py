"""The pybullet world and the simulated TurtleBot 2 that implements the robot contract.

``from homing.sim import load_world, SimRobot``: ``load_world("lab")`` (a
bundled world's name, a world YAML or a bare map_server YAML), then
``SimRobot(world, seed=1)``. Only this package imports pybullet, and only
when a :class:`SimRobot` is wanted (loading or drawing a world does not).
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

from homing.sim.faults import Fault
from homing.sim.tags import Tag
from homing.sim.world import Patch, World, load_world

if TYPE_CHECKING:
    from homing.sim.robot import SimRobot

__all__ = ["Fault", "Patch", "SimRobot", "Tag", "World", "load_world"]


def __getattr__(name: str) -> Any:
    if name == "SimRobot":
        from homing.sim.robot import SimRobot

        return SimRobot
    raise AttributeError(f"module 'homing.sim' has no attribute {name!r}")
