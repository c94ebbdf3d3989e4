"""Mapping: occupancy grid, scan matching, frontiers and goal strategies, landmark SLAM, map I/O."""
