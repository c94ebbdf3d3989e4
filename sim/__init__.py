"""The pybullet world and the simulated TurtleBot 2 that implements the robot contract."""
