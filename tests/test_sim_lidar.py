"""The simulated lidar against analytic wall distances in a known rectangular room."""

from __future__ import annotations

import math

import numpy as np
import pytest
from homing.robot.turtlebot import LIDAR_RANGE_MAX
from homing.robot.types import Pose2
from homing.sim import SimRobot, load_world
from homing.sim.lidar import RANGE_SIGMA

from tests.sim_helpers import box_room, range_to_box

W, H = 9.0, 4.0  # [m] room


@pytest.fixture(scope="module")
def room(tmp_path_factory: pytest.TempPathFactory):
    return load_world(box_room(tmp_path_factory.mktemp("lidar"), W, H))


def _scans(world, pose: Pose2, n: int, seed: int = 7):
    robot = SimRobot(world, seed=seed, camera=False, start=pose)
    out = []
    last = None
    while len(out) < n:
        scan = robot.observe().scan
        if scan.stamp != last:
            out.append(scan)
            last = scan.stamp
        robot.step(0.1)
    robot.close()
    return out


def test_ranges_match_analytic_walls_within_noise(room) -> None:
    pose = Pose2(2.0, 1.5, 0.3)
    scans = _scans(room, pose, 10)
    expected = np.array([range_to_box(pose.x, pose.y, pose.theta + a, W, H) for a in scans[0].angles])
    in_range = expected < LIDAR_RANGE_MAX - 0.1
    residuals, lost = [], 0
    for scan in scans:
        r = scan.ranges.astype(float)
        ok = np.isfinite(r) & in_range
        residuals.append(r[ok] - expected[ok])
        lost += int(np.sum(~np.isfinite(r) & in_range))
    res = np.concatenate(residuals)
    assert np.all(np.abs(res) < 6 * RANGE_SIGMA), "a return far from the wall"
    assert abs(res.mean()) < 4 * RANGE_SIGMA / math.sqrt(res.size)
    assert 0.85 * RANGE_SIGMA < res.std() < 1.15 * RANGE_SIGMA
    assert lost / (len(scans) * in_range.sum()) < 0.05  # dropouts are occasional


def test_rays_beyond_range_max_return_nothing(room) -> None:
    pose = Pose2(1.0, 2.0, 0.0)  # the far wall is 8 m ahead
    scan = _scans(room, pose, 1)[0]
    expected = np.array([range_to_box(pose.x, pose.y, a, W, H) for a in scan.angles])
    assert np.all(np.isinf(scan.ranges[expected > LIDAR_RANGE_MAX + 0.1]))
    assert np.isfinite(scan.ranges[expected < 3.0]).mean() > 0.9


def test_scans_arrive_at_5_5_hz(room) -> None:
    scans = _scans(room, Pose2(2.0, 2.0, 0.0), 12)
    gaps = np.diff([s.stamp for s in scans])
    assert np.allclose(gaps.mean(), 1 / 5.5, atol=0.02)
    assert scans[0].ranges.dtype == np.float32 and scans[0].ranges.shape == (360,)


def test_obstacles_added_and_removed_again_and_again_are_seen_where_they_stand_and_make_no_new_shapes(room) -> None:
    """A long run's faults and world changes add and remove boxes for days: each is seen by a ray where it stands
    and gone once removed, and Bullet's shape table stops growing after the first box of each size (Bullet keeps
    a removed body's shapes, so a new shape per box would grow it for ever)."""
    from homing.sim.scene import Scene, p

    scene = Scene(room, visuals=False)
    try:
        up = np.array([[2.0 + x, 0.2, 0.3] for x in (0.0, 1.0, 2.0)])
        down = up + np.array([0.0, 3.6, 0.0])  # rays across the room, at three x

        def seen() -> list[bool]:
            frac, ids = scene.rays(up, down)
            return [bool(i >= 0 and i not in scene.wall_bodies) for i in ids]

        def next_shape() -> int:  # the index Bullet gives the next shape: its table's length
            return p.createCollisionShape(p.GEOM_SPHERE, radius=0.01, physicsClientId=scene.client)

        scene.add_obstacle("a", 2.0, 2.0)
        scene.add_obstacle("b", 3.0, 2.0, size=(0.5, 0.3))
        scene.remove_obstacle("a")
        scene.remove_obstacle("b")
        first = next_shape()
        for k in range(30):
            x = (2.0, 3.0, 4.0)[k % 3]
            scene.add_obstacle("a", x, 2.0)
            scene.add_obstacle("b", 4.0 if x == 2.0 else 2.0, 2.0, size=(0.5, 0.3))
            want = [False, False, False]
            want[int(round(x - 2.0))] = True
            want[2 if x == 2.0 else 0] = True
            assert seen() == want
            scene.remove_obstacle("a")
            scene.remove_obstacle("b")
            assert seen() == [False, False, False]
        assert next_shape() == first + 1
    finally:
        scene.close()
