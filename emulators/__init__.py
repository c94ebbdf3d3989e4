"""Protocol emulators on pseudo-terminals whose physics is the simulation: the Kobuki base and the RPLIDAR A1.

``Emulation(world, folder)`` runs a :class:`homing.sim.SimRobot` on the wall
clock and serves it as the real robot's devices: a Kobuki on one
pseudo-terminal, an RPLIDAR on another (stable symlinks ``folder/kobuki``
and ``folder/rplidar``, like udev's ``/dev/kobuki``), the computer's battery
as a Linux power_supply folder, and a robot file naming them all, so that
``homing run MISSION --robot folder/robot.yaml`` drives the simulated robot
through the real adapters and the real byte streams. ``homing emulate``
is its command line.

This package sits apart from ``sim/`` (the physics, no threads, no ports)
and ``robot/hardware/`` (the adapters, which must not know the simulator):
it is the one place that imports both.
"""
