"""What keeps a robot alive across dock cycles, apart from the tree: the energy policy and the run directory.

- :mod:`homing.lifecycle.energy`: go-home thresholds per battery and the
  reserve the way home needs, from the batteries' own drain.
- :mod:`homing.lifecycle.rundir`: the map, the SLAM graph and the mission's
  counters saved atomically at every dock, and read back to resume.

Plain functions and small classes over numbers and numpy arrays, like the
algorithm packages: no py_trees, no pybullet.
"""
