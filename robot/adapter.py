"""The adapter contract: what every robot, simulated or real, gives and takes.

The mission runner and every behaviour talk to the robot only through a
:class:`RobotAdapter`. Each step it gives one :class:`Observation` (odometry,
latest scan and image, bumpers, dock IR, batteries, time) and takes one
velocity command, clipped to :class:`RobotLimits`. Time comes from the
adapter's :class:`Clock` only, so a simulated day runs in minutes while a
timeout means the same thing in simulation and on hardware.

Ground truth is deliberately absent: the simulator knows where the robot
really is, but the robot may not (DESIGN.md, rules of the house).
"""

from __future__ import annotations

from typing import Protocol, runtime_checkable

from homing.robot.turtlebot import RobotLimits
from homing.robot.types import Observation, Twist2


@runtime_checkable
class Clock(Protocol):
    """The adapter's time [s]: simulated seconds in sim, monotonic seconds on hardware."""

    def now(self) -> float: ...


@runtime_checkable
class RobotAdapter(Protocol):
    """A robot the mission runner can drive.

    Lifecycle: construct, ``observe()``/``command()``/``step()`` in a loop,
    ``close()``. ``step(dt)`` is the only way time passes for the caller: the
    simulator advances its physics by ``dt`` under the last command; hardware
    sleeps until ``dt`` has elapsed on its clock. A command holds until
    replaced; hardware adapters also stop the base if none arrives for a
    while (kobuki's own watchdog does the same).
    """

    @property
    def clock(self) -> Clock:
        """The adapter's clock (read-only: an adapter keeps its own)."""
        ...

    @property
    def limits(self) -> RobotLimits:
        """The velocity limits commands are clipped to, and the robot's size."""
        ...

    def observe(self) -> Observation:
        """One snapshot of all sensors and the time (never blocks for new data)."""
        ...

    def command(self, v: float, omega: float) -> Twist2:
        """Set the velocity command [m/s, rad/s]; returns the command after clipping."""
        ...

    def step(self, dt: float) -> None:
        """Let ``dt`` [s] of adapter time pass with the current command applied."""
        ...

    def close(self) -> None:
        """Stop the robot and release the hardware or simulator."""
        ...
