"""Scan matching: recovers a known offset, and reduces pose error against odometry alone on a drifting run."""

from __future__ import annotations

import math

import numpy as np
from homing.mapping.grid import OccupancyGrid
from homing.mapping.grid_slam import GridSlam
from homing.mapping.scan_match import CorrelativeMatcher
from homing.robot import Pose2

from tests.mapping_helpers import cast_scan, drifting_odometry, odometry_msg, path_poses, truth


def test_matcher_recovers_a_known_offset():
    world = truth("loop")
    pose = Pose2(-8.4, -8.4, 0.3)
    rng = np.random.default_rng(3)
    grid = OccupancyGrid(0.05)
    for _ in range(3):
        grid.integrate(cast_scan(world, pose, 0.0, rng), pose)
    pts = cast_scan(world, pose, 0.0, rng).points()
    for dx, dy, dth in [(0.12, -0.08, 0.05), (-0.1, 0.15, -0.1)]:
        result = CorrelativeMatcher().match(grid, pts, Pose2(pose.x + dx, pose.y + dy, pose.theta + dth))
        assert result.ok
        assert result.pose.distance_to(pose) < 0.06
        assert abs(result.pose.theta - pose.theta) < math.radians(1.5)


def test_scan_matching_beats_odometry_on_a_drifting_loop():
    world = truth("loop")
    poses = path_poses([(-8.4, -8.4), (8.4, -8.4), (8.4, 8.4)], speed=0.5)
    odom = drifting_odometry(poses, np.random.default_rng(1), bias=0.03, noise=0.02)
    errors = {}
    for use in (False, True):
        slam = GridSlam(0.05, use_matcher=use)
        rng = np.random.default_rng(2)
        err = []
        for i, (p, o) in enumerate(zip(poses, odom, strict=True)):
            slam.update(odometry_msg(i / 5.5, o), cast_scan(world, p, i / 5.5, rng, dropout=0.02))
            t = poses[0].between(p)
            err.append(math.hypot(slam.pose.x - t.x, slam.pose.y - t.y))
        errors[use] = float(np.mean(err))
    assert errors[False] > 2.0  # the run really drifts
    assert errors[True] < 0.25 * errors[False], errors
