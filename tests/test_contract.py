"""The adapter contract's types obey planar geometry and the Kobuki's published facts."""

from __future__ import annotations

import math

import numpy as np
import pytest
from homing.robot import Pose2, Scan
from homing.robot.turtlebot import battery_percent, battery_voltage, bumper_sector


def test_compose_then_between_round_trips(rng: np.random.Generator) -> None:
    for _ in range(100):
        a = Pose2(*rng.uniform(-5, 5, 2), rng.uniform(-math.pi, math.pi))
        b = Pose2(*rng.uniform(-5, 5, 2), rng.uniform(-math.pi, math.pi))
        c = a.between(a.compose(b))
        assert np.allclose([c.x, c.y], [b.x, b.y], atol=1e-9)
        assert abs(math.remainder(c.theta - b.theta, 2 * math.pi)) < 1e-9


def test_compose_matches_homogeneous_matrices(rng: np.random.Generator) -> None:
    a = Pose2(1.0, 2.0, 0.7)
    b = Pose2(-0.5, 0.3, -2.0)
    M = a.matrix() @ b.matrix()
    c = a.compose(b)
    assert np.allclose(c.matrix(), M, atol=1e-12)


def test_transform_points_rotates_then_translates() -> None:
    pose = Pose2(1.0, 0.0, math.pi / 2)
    pts = pose.transform_points(np.array([[1.0, 0.0], [0.0, 1.0]]))
    assert np.allclose(pts, [[1.0, 1.0], [0.0, 0.0]], atol=1e-12)


def test_scan_points_follow_ray_angles() -> None:
    ranges = np.full(4, 2.0, dtype=np.float32)
    ranges[3] = np.inf  # a dropout has no end point
    scan = Scan(0.0, 0.0, math.pi / 2, ranges, 0.15, 6.0, laser_pose=Pose2(0.1, 0.0, 0.0))
    pts = scan.points()
    assert pts.shape == (3, 2)
    assert np.allclose(pts, [[2.1, 0.0], [0.1, 2.0], [-1.9, 0.0]], atol=1e-6)


def test_battery_percent_formula_and_inverse() -> None:
    assert battery_percent(16.5) == pytest.approx(100.0)
    assert battery_percent(13.2) == pytest.approx(5.0)
    assert battery_percent(14.0) == pytest.approx(95 * 0.8 / 3.3 + 5)
    assert battery_percent(20.0) == 100.0 and battery_percent(10.0) == 0.0
    for pct in (5.0, 20.0, 50.0, 90.0):
        assert battery_percent(battery_voltage(pct)) == pytest.approx(pct)


@pytest.mark.parametrize(
    ("deg", "sector"),
    [(0, "centre"), (30, "centre"), (-30, "centre"), (31, "left"), (90, "left"),
     (-31, "right"), (-90, "right"), (91, None), (180, None), (-120, None)],
)
def test_bumper_sectors(deg: float, sector: str | None) -> None:
    assert bumper_sector(math.radians(deg)) == sector


def test_a_scans_kept_ray_angles_are_the_wrapped_angles_worked_out_afresh_and_cannot_be_changed() -> None:
    from homing.robot.frames import wrap_angles

    for amin, inc, n in ((-math.pi, math.radians(1.0), 360), (0.1, 0.0123, 500), (-1.2, 0.01, 240)):
        first = Scan(0.0, amin, inc, np.ones(n, np.float32), 0.15, 6.0)
        again = Scan(1.0, amin, inc, np.full(n, 2.0, np.float32), 0.15, 6.0)  # another scan of the same lidar
        assert again.angles is first.angles  # kept, not worked out again
        assert np.array_equal(first.angles, wrap_angles(amin + inc * np.arange(n)))
        with pytest.raises(ValueError):
            first.angles[0] = 0.0
