"""Global relocalisation: a scan is found again in a known map, and a symmetric room gives no answer, not a wrong one."""

from __future__ import annotations

import math

import numpy as np
import pytest
from homing.mapping.grid import OccupancyGrid
from homing.mapping.grid_slam import GridSlam
from homing.mapping.relocalize import CHUNK, best_first, coarse_scores, relocalise
from homing.robot import Odometry, Pose2, Twist2
from homing.sim import SimRobot, load_world

from tests.sim_helpers import box_room


@pytest.fixture(scope="module")
def lab():
    return load_world("lab")


def _scan_at(world, pose: Pose2, seed: int):
    robot = SimRobot(world, seed=seed, camera=False, start=pose)
    scan = robot.observe().scan
    robot.close()
    return scan


@pytest.mark.parametrize("seed", range(6))
def test_a_scan_is_found_anywhere_in_the_lab(lab, seed: int) -> None:
    grid = OccupancyGrid.from_map_data(lab.map)  # the true plan as the robot's map (world frame)
    rng = np.random.default_rng(seed)
    free = np.argwhere(lab.reachable_free())
    while True:
        r, c = free[rng.integers(len(free))]
        x = lab.map.origin[0] + (c + 0.5) * lab.map.resolution
        y = lab.map.origin[1] + (r + 0.5) * lab.map.resolution
        truth = Pose2(float(x), float(y), float(rng.uniform(-math.pi, math.pi)))
        scan = _scan_at(lab, truth, seed)
        if int(scan.valid().sum()) > 200:  # not pressed into a corner
            break
    found = relocalise(grid, scan.points())
    assert found.pose is not None, found.reason
    assert found.pose.distance_to(truth) < 0.10
    assert abs(math.degrees(math.remainder(found.pose.theta - truth.theta, 2 * math.pi))) < 3.0


def test_a_square_room_is_ambiguous_and_says_so(tmp_path) -> None:
    room = load_world(box_room(tmp_path, 5.0, 5.0))
    grid = OccupancyGrid.from_map_data(room.map)
    scan = _scan_at(room, Pose2(2.5, 2.5, 0.3), seed=1)  # the centre: four turns of the room fit alike
    found = relocalise(grid, scan.points())
    assert found.pose is None and "ambiguous" in found.reason
    assert found.runner_up >= 0.9 * found.fit


def test_grid_slam_refuses_to_draw_a_kidnapped_scan_and_finds_itself_again(lab) -> None:
    # Map the lab's true plan, track a robot at one pose, then teleport it: odometry does not notice.
    slam = GridSlam(grid=OccupancyGrid.from_map_data(lab.map))
    here, there = Pose2(1.5, 2.0, 0.5), Pose2(8.0, 6.5, -2.0)
    slam.set_pose(here, Pose2())
    before = slam.grid.logodds.copy()
    t = 0.0
    for pose in [here] * 4 + [there] * 30:  # a scan is due every second when the robot stands still
        t += 0.2
        scan = _scan_at(lab, pose, seed=int(t * 10))
        scan = type(scan)(t, scan.angle_min, scan.angle_increment, scan.ranges, scan.range_min, scan.range_max,
                          scan.laser_pose)
        slam.update(Odometry(t, Pose2(), Twist2()), scan)
    assert slam.times_lost == 1 and not slam.lost, slam.last_relocalisation
    assert slam.pose.distance_to(there) < 0.10
    changed = np.abs(slam.grid.logodds - before) > 1.0
    assert changed.mean() < 0.01  # the map was not redrawn at the wrong place


def test_found_again_it_tracks_at_full_odometry_scale_whatever_the_floor_it_was_lifted_from(lab) -> None:
    # A robot driving at 0.2 m/s on wheels that had been slipping (its rung of SLIP_SCALES at one half) is picked
    # up and set down elsewhere, driving on; odometry notices nothing. The slip belonged to the old floor.
    slam = GridSlam(grid=OccupancyGrid.from_map_data(lab.map))
    here, there = Pose2(1.5, 2.0, 0.5), Pose2(8.0, 6.5, -2.0)
    slam.set_pose(here, Pose2())
    slam.odom_scale = 0.5
    step = Pose2(0.04, 0.0, 0.0)  # 0.2 s at 0.2 m/s
    truth, odom, t, errors, scale_at_finding = here, Pose2(), 0.0, [], None
    for k in range(40):
        truth = there if k == 5 else truth.compose(step)
        odom, t = odom.compose(step), t + 0.2
        scan = _scan_at(lab, truth, seed=k)
        scan = type(scan)(t, scan.angle_min, scan.angle_increment, scan.ranges, scan.range_min, scan.range_max,
                          scan.laser_pose)
        lost = slam.lost
        slam.update(Odometry(t, odom, Twist2(0.2, 0.0)), scan)
        if lost and not slam.lost:
            scale_at_finding = slam.odom_scale
        if slam.times_lost and not slam.lost:
            errors.append(slam.pose.distance_to(truth))
    assert slam.times_lost == 1 and not slam.lost, slam.last_relocalisation
    assert scale_at_finding == 1.0
    assert slam.slip_switches == 0  # the scans that did not fit said nothing about slip
    assert len(errors) > 20 and max(errors) < 0.10, errors


def test_coarse_scores_are_the_pooled_field_under_each_turned_scan_at_each_candidate() -> None:
    # The gather by whole-cell steps gives, for every candidate cell and heading, the mean pooled value under
    # the scan's points placed at the cell's centre and turned, as scoring each pose on its own does.
    rng = np.random.default_rng(4)
    pooled = rng.random((23, 31)).astype(np.float32)
    size = 0.4
    rows, cols = np.nonzero(rng.random(pooled.shape) < 0.5)  # more candidates than one chunk holds
    assert len(rows) > CHUNK
    pts = rng.uniform(-6.0, 6.0, (40, 2))
    thetas = np.arange(0.0, 2 * math.pi, math.radians(5.0))
    scores = coarse_scores(pooled, rows, cols, size, pts, thetas)
    h, w = pooled.shape
    for n in rng.integers(len(rows), size=25):
        cx, cy = (cols[n] + 0.5) * size, (rows[n] + 0.5) * size
        for t in rng.integers(len(thetas), size=8):
            c, s = math.cos(thetas[t]), math.sin(thetas[t])
            col = np.floor((cx + c * pts[:, 0] - s * pts[:, 1]) / size).astype(int)
            row = np.floor((cy + s * pts[:, 0] + c * pts[:, 1]) / size).astype(int)
            inside = (row >= 0) & (row < h) & (col >= 0) & (col < w)
            expect = np.where(inside, pooled[np.clip(row, 0, h - 1), np.clip(col, 0, w - 1)], 0.0).mean()
            assert scores[n, t] == pytest.approx(expect, abs=1e-6)


@pytest.mark.parametrize("seed", range(4))
def test_best_first_is_argsort_largest_first_with_or_without_ties(seed: int) -> None:
    rng = np.random.default_rng(seed)
    distinct = rng.random((300, 72)).astype(np.float32)
    tied = np.round(distinct * 20) / 20  # many equal scores, at the cut too
    for scores in (distinct, tied):
        expect = np.argsort(scores, axis=None)[::-1][:48]
        assert np.array_equal(best_first(scores, 48), expect)
