"""A tag's heading from the wall behind it (homing.perception.tag_wall), on synthetic scans of known walls."""

from __future__ import annotations

import math

import numpy as np
from homing.perception.apriltag import TagMeasurement
from homing.perception.tag_wall import refine_yaw
from homing.robot.frames import wrap_angle
from homing.robot.types import Pose2, Scan


def _scan(segments: list[tuple[tuple[float, float], tuple[float, float]]], rng: np.random.Generator,
          sigma: float = 0.01, stamp: float = 0.0) -> Scan:
    """A 360-ray scan from base_link's origin of wall ``segments`` (end points in base_link [m])."""
    angles = -math.pi + math.radians(1.0) * np.arange(360)
    ranges = np.full(360, np.inf)
    for (ax, ay), (bx, by) in segments:
        a, b = np.array([ax, ay]), np.array([bx, by])
        for i, th in enumerate(angles):
            d = np.array([math.cos(th), math.sin(th)])
            M = np.column_stack([d, a - b])
            if abs(np.linalg.det(M)) < 1e-12:
                continue
            r, s = np.linalg.solve(M, a)
            if r > 0 and 0.0 <= s <= 1.0:
                ranges[i] = min(ranges[i], r)
    ranges = np.where(np.isfinite(ranges), ranges + sigma * rng.standard_normal(360), np.inf)
    return Scan(stamp, -math.pi, math.radians(1.0), ranges.astype(np.float32), 0.15, 6.0)


def _tag(x: float, y: float, theta: float, sigma_yaw: float = 0.3) -> TagMeasurement:
    cov = np.diag([0.01**2, 0.01**2, sigma_yaw**2])
    r, b = math.hypot(x, y), math.atan2(y, x)
    return TagMeasurement(3, 0.0, Pose2(x, y, theta), cov, r, b, 0.0, 100.0, 0, 0.35, np.eye(4), np.zeros((4, 2)))


def _wall_through(centre: np.ndarray, facing: float, half: float = 2.0):
    along = np.array([-math.sin(facing), math.cos(facing)])
    return (tuple(centre - half * along), tuple(centre + half * along))


def test_heading_comes_from_the_wall_within_half_a_degree():
    rng = np.random.default_rng(0)
    for facing in (math.pi, math.pi - 0.4, math.pi + 0.6):
        centre = np.array([1.8, 0.3])
        scan = _scan([_wall_through(centre, facing)], rng)
        noisy = _tag(*centre, facing + math.radians(12.0))  # the corners' yaw, 12° off
        m = refine_yaw(noisy, scan)
        assert m.yaw_source == "wall"
        assert abs(wrap_angle(m.pose.theta - facing)) < math.radians(0.5)
        assert math.sqrt(m.covariance[2, 2]) < math.radians(1.0)
        assert (m.pose.x, m.pose.y) == (noisy.pose.x, noisy.pose.y)  # position untouched


def test_robot_turning_between_scan_and_image_is_compensated():
    rng = np.random.default_rng(1)
    centre, facing = np.array([2.0, 0.0]), math.pi
    scan_wall = Pose2(0.0, 0.0, -0.2).transform_points(np.array(_wall_through(centre, facing)))
    scan = _scan([(tuple(scan_wall[0]), tuple(scan_wall[1]))], rng)  # the robot had turned 0.2 rad more
    m = refine_yaw(_tag(*centre, facing), scan, image_from_scan=Pose2(0.0, 0.0, 0.2))
    assert m.yaw_source == "wall" and abs(wrap_angle(m.pose.theta - facing)) < math.radians(0.5)
    wrong = refine_yaw(_tag(*centre, facing), scan)  # without it the wall seems turned
    assert abs(wrap_angle(wrong.pose.theta - facing)) > math.radians(8.0)


def test_no_wall_a_far_wall_or_a_disagreeing_one_leave_the_measurement_alone():
    rng = np.random.default_rng(2)
    tag = _tag(2.0, 0.0, math.pi)
    assert refine_yaw(tag, None) is tag
    assert refine_yaw(tag, _scan([], rng)) is tag
    behind = _scan([_wall_through(np.array([2.5, 0.0]), math.pi)], rng)  # 0.5 m behind the tag: not its wall
    assert refine_yaw(tag, behind) is tag
    across = _scan([_wall_through(np.array([2.0, 0.0]), math.pi / 2)], rng)  # perpendicular: wrong surface
    assert refine_yaw(tag, across) is tag


def test_a_corner_beside_the_tag_does_not_tilt_the_fit():
    rng = np.random.default_rng(3)
    centre, facing = np.array([2.0, 0.1]), math.pi
    wall = ((2.0, -2.0), (2.0, 0.35))
    side = ((2.0, 0.35), (1.2, 0.35))  # a wall coming towards the robot 25 cm beside the tag
    m = refine_yaw(_tag(*centre, facing + 0.1), _scan([wall, side], rng))
    assert m.yaw_source == "wall" and abs(wrap_angle(m.pose.theta - facing)) < math.radians(1.0)


def _yaw_errors(segments_of: list, facing: float, seeds: range) -> np.ndarray:
    """|heading error| [rad] of the wall fit over ``seeds`` (each a fresh scan of ``segments_of``)."""
    out = []
    for seed in seeds:
        m = refine_yaw(_tag(1.2, 0.0, facing + 0.1), _scan(segments_of, np.random.default_rng(seed)))
        assert m.yaw_source == "wall"
        out.append(abs(wrap_angle(m.pose.theta - facing)))
    return np.array(out)


def test_a_long_wall_gives_a_better_heading_than_the_stretch_behind_the_tag():
    """The widest straight stretch is used (issue 37): ±1.5 m of wall beats ±0.45 m by ~5x, as measured in sim."""
    facing = math.pi
    long_wall = _yaw_errors([_wall_through(np.array([1.2, 0.0]), facing, half=3.0)], facing, range(20))
    short = _yaw_errors([_wall_through(np.array([1.2, 0.0]), facing, half=0.45)], facing, range(20))
    assert np.sqrt(np.mean(long_wall**2)) < math.radians(0.15)
    assert np.sqrt(np.mean(long_wall**2)) < 0.4 * np.sqrt(np.mean(short**2))


def test_a_tag_on_a_desk_front_takes_the_desk_not_the_wall_behind_it():
    """A 1 m desk front 0.8 m before a wall turned 5°: the wide stretch is not one line, the desk's is used."""
    facing = math.pi
    desk = _wall_through(np.array([1.2, 0.0]), facing, half=0.5)
    back = _wall_through(np.array([2.0, 0.0]), facing + math.radians(5.0), half=3.0)
    errors = _yaw_errors([desk, back], facing, range(10))
    assert errors.max() < math.radians(1.0)
