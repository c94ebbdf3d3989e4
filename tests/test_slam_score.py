"""bench slam's baselines (tags placed through the grid's or odometry's pose): their sightings averaged with the same
care the pose graph takes, a corner heading no surer than GTSAM takes it, a wall heading as measured."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import pytest
from homing.mapping.landmark_slam import TAG_YAW_SIGMA
from homing.robot import Pose2

from benchmarks.slam_score import ate, ate_along_across, heading_weight, mean_pose, tag_errors


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


def test_each_tags_error_after_dock_alignment_is_its_own_distance_to_the_truth() -> None:
    # The estimated map is the true one moved by a rigid transform, except that the dock tag's heading came out
    # δ off: aligned on the dock tag, every tag turns by −δ about it, so a tag r away is off by 2·r·sin(δ/2).
    truth = {0: Pose2(7.0, 0.0, 0.0), 1: Pose2(-3.0, 0.0, math.pi), 2: Pose2(7.0, 5.0, -math.pi / 2),
             3: Pose2(0.0, -8.0, math.pi / 2)}
    moved = Pose2(1.5, -2.0, 0.7)
    delta = math.radians(0.2)
    est = {i: moved.compose(p) for i, p in truth.items() if i != 3}  # tag 3 never seen
    est[0] = est[0].compose(Pose2(0.0, 0.0, delta))
    out = tag_errors(est, truth, dock_id=0)
    assert out["tag0_m"] == pytest.approx(0.0, abs=1e-12)
    assert out["tag1_m"] == pytest.approx(2 * 10.0 * math.sin(delta / 2))  # 3.5 cm at 10 m
    assert out["tag2_m"] == pytest.approx(2 * 5.0 * math.sin(delta / 2))
    assert math.isnan(out["tag3_m"])
    assert out["dock_mean_m"] == pytest.approx((out["tag1_m"] + out["tag2_m"]) / 3)


def test_trajectory_error_splits_along_and_across_the_heading() -> None:
    # Four poses around the origin, each displaced 2 cm along its own heading: facing outwards the map grows
    # (no rigid fit undoes it) and the error is all along; facing round the loop it is all across.
    for heading_offset, expect_along in ((0.0, True), (math.pi / 2, False)):
        truth = [Pose2(math.cos(a), math.sin(a), a + heading_offset) for a in np.arange(4) * math.pi / 2]
        radial = [Pose2(p.x * 1.02, p.y * 1.02, p.theta) for p in truth]
        along, across = ate_along_across(radial, truth)
        big, small = (along, across) if expect_along else (across, along)
        assert big == pytest.approx(0.02) and small == pytest.approx(0.0, abs=1e-12)
        assert ate(radial, truth) == pytest.approx(0.02)
    assert all(math.isnan(x) for x in ate_along_across([Pose2()], [Pose2()]))
