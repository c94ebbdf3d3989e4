"""bench slam's baselines (tags placed through the grid's or odometry's pose): their sightings averaged with the same
care the pose graph takes, a corner heading no surer than GTSAM takes it, a wall heading as measured."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import pytest
from homing.mapping.landmark_slam import TAG_YAW_SIGMA
from homing.robot import Pose2

from benchmarks.slam_score import heading_weight, mean_pose


@dataclass
class _Sighting:
    covariance: np.ndarray
    yaw_source: str


def _cov(yaw_sigma: float) -> np.ndarray:
    return np.diag([0.01**2, 0.01**2, yaw_sigma**2])


def test_a_mirrored_corner_heading_does_not_turn_a_tag_its_wall_headings_agree_on() -> None:
    # Four sightings from the wall behind the tag (0.2° σ) at 0.5°, one from the corners mirrored to 40°.
    wall = [_Sighting(_cov(math.radians(0.2)), "wall")] * 4
    corner = _Sighting(_cov(math.radians(2.0)), "tag")  # the detector's own σ: taken as TAG_YAW_SIGMA
    assert heading_weight(corner) == pytest.approx(1.0 / TAG_YAW_SIGMA**2)
    poses = [Pose2(1.0, 2.0, math.radians(0.5))] * 4 + [Pose2(1.02, 2.0, math.radians(40.0))]
    weights = [heading_weight(m) for m in (*wall, corner)]
    weighted = mean_pose(poses, weights)
    alike = mean_pose(poses)
    assert abs(math.degrees(weighted.theta) - 0.5) < 0.01
    assert math.degrees(alike.theta) > 7.0  # averaged alike, one mirrored sighting of five turns it by 8°
    assert weighted.x == pytest.approx(1.004) and weighted.y == pytest.approx(2.0)  # positions: the plain mean


def test_headings_average_on_the_circle() -> None:
    # Either side of ±180°: the mean is 180°, not 0°.
    p = mean_pose([Pose2(0.0, 0.0, math.radians(179.0)), Pose2(0.0, 0.0, math.radians(-179.0))], [1.0, 1.0])
    assert abs(abs(math.degrees(p.theta)) - 180.0) < 1e-9
