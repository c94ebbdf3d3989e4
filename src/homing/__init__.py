"""homing: behaviour-tree missions for persistent autonomous mobile robots.

The package's parts stand at the top of the repository (DESIGN.md, Layout):
``homing.robot`` (the adapter contract), ``homing.sim`` (pybullet),
``homing.perception``, ``homing.mapping``, ``homing.navigation``,
``homing.behaviours``, ``homing.missions`` and ``homing.benchmarks``.
This root package holds only what every part shares: the error a user's
mistake raises and atomic file writes.
"""

__version__ = "0.1.0"
