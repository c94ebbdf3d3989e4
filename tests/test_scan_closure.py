"""Lidar loop closures: ICP recovers a known relative pose, frees a corridor's axis, and straightens SLAM's map."""

from __future__ import annotations

import math

import numpy as np
from homing.mapping import scan_closure
from homing.mapping.landmark_slam import (
    SCAN_LINKS,
    LandmarkSlam,
    SlamConfig,
    X,
    lidar_factor,
    to_gtsam,
)
from homing.robot import Pose2
from homing.robot.types import Scan

ROOM = [((0.0, 0.0), (6.0, 0.0)), ((6.0, 0.0), (6.0, 4.0)), ((6.0, 4.0), (0.0, 4.0)), ((0.0, 4.0), (0.0, 0.0)),
        ((2.0, 1.5), (3.0, 1.5)), ((3.0, 1.5), (3.0, 2.5))]  # a 6 × 4 m room with an L-shaped pillar
CORRIDOR = [((-20.0, 0.0), (20.0, 0.0)), ((-20.0, 2.0), (20.0, 2.0))]  # two parallel walls, no ends in range
RAYS = 360


def _cast(walls: list, pose: Pose2, rng: np.random.Generator, max_range: float = 8.0) -> np.ndarray:
    """(RAYS,) ranges [m] from ``pose`` to the nearest wall segment, with 1 cm noise (inf: no hit)."""
    a = pose.theta + np.linspace(-math.pi, math.pi, RAYS, endpoint=False)
    d = np.column_stack([np.cos(a), np.sin(a)])
    best = np.full(RAYS, np.inf)
    for (x0, y0), (x1, y1) in walls:
        e = np.array([x1 - x0, y1 - y0])
        w = np.array([x0 - pose.x, y0 - pose.y])
        den = d[:, 0] * (-e[1]) - d[:, 1] * (-e[0])
        with np.errstate(divide="ignore", invalid="ignore"):
            t = (w[0] * (-e[1]) - w[1] * (-e[0])) / den
            s = (d[:, 0] * w[1] - d[:, 1] * w[0]) / den
        hit = (np.abs(den) > 1e-12) & (t > 0) & (s >= 0) & (s <= 1)
        best = np.where(hit & (t < best), t, best)
    best = best + rng.normal(0.0, 0.01, RAYS)
    return np.where(best < max_range, best, np.inf)


def _scan(walls: list, pose: Pose2, rng: np.random.Generator, stamp: float = 0.0) -> Scan:
    return Scan(stamp, -math.pi, 2 * math.pi / RAYS, _cast(walls, pose, rng).astype(np.float32), 0.1, 8.0)


def test_icp_recovers_the_relative_pose_in_a_room_from_a_poor_guess():
    rng = np.random.default_rng(0)
    a, b = Pose2(1.5, 1.0, 0.3), Pose2(2.0, 0.8, 1.1)
    truth = a.between(b)
    ref = scan_closure.reference(_scan(ROOM, a, rng).points())
    guess = truth.compose(Pose2(0.2, -0.15, math.radians(5.0)))
    found = scan_closure.match(ref, _scan(ROOM, b, rng).points(), guess)
    assert found is not None
    assert found.pose.distance_to(truth) < 0.01
    assert abs(math.remainder(found.pose.theta - truth.theta, 2 * math.pi)) < math.radians(0.2)
    # a room constrains every direction: no axis freed, σ ≈ 1 cm
    assert np.sqrt(np.linalg.eigvalsh(found.covariance[:2, :2])).max() < 0.02
    # a heading-only closure (SLAM's default) frees the position but keeps the heading's σ
    heading = scan_closure.match(ref, _scan(ROOM, b, rng).points(), guess, position=False)
    assert heading is not None
    assert np.allclose(np.sqrt(np.linalg.eigvalsh(heading.covariance[:2, :2])), scan_closure.FREE_SIGMA)
    assert math.sqrt(heading.covariance[2, 2]) < math.radians(0.2)


def test_a_corridor_leaves_its_axis_free_but_fixes_heading_and_offset():
    rng = np.random.default_rng(1)
    a, b = Pose2(0.0, 1.0, 0.0), Pose2(0.5, 0.8, 0.05)
    truth = a.between(b)
    ref = scan_closure.reference(_scan(CORRIDOR, a, rng).points())
    found = scan_closure.match(ref, _scan(CORRIDOR, b, rng).points(), truth.compose(Pose2(0.0, 0.1, 0.03)))
    assert found is not None
    w, v = np.linalg.eigh(found.covariance[:2, :2])
    axis = v[:, 1]
    assert abs(axis[0]) > 0.99 and math.sqrt(w[1]) == scan_closure.FREE_SIGMA  # along x (the corridor) is free
    assert math.sqrt(w[0]) < 0.02
    assert abs(found.pose.y - truth.y) < 0.01  # across the corridor: measured
    assert abs(math.remainder(found.pose.theta - truth.theta, 2 * math.pi)) < math.radians(0.2)


def test_scans_of_different_places_do_not_match():
    rng = np.random.default_rng(2)
    ref = scan_closure.reference(_scan(ROOM, Pose2(1.5, 1.0, 0.0), rng).points())
    assert scan_closure.match(ref, _scan(CORRIDOR, Pose2(0.0, 1.0, 0.0), rng).points(), Pose2()) is None


def test_normals_are_across_the_walls_and_move_with_a_merged_scan():
    rng = np.random.default_rng(3)
    pose = Pose2(1.5, 1.0, 0.4)
    pts = _scan(ROOM, pose, rng).points()
    ref = scan_closure.reference(pts)
    world = pose.transform_points(pts)
    # Points on the room's outer walls (x = 0 or 6, y = 0 or 4 in the room) have normals along the other axis.
    c, s = math.cos(pose.theta), math.sin(pose.theta)
    n_world = ref.normals @ np.array([[c, s], [-s, c]])
    on_x_wall = (np.minimum(abs(world[:, 0]), abs(world[:, 0] - 6.0)) < 0.02) & (world[:, 1] > 0.3) & (world[:, 1] < 3.7)
    on_y_wall = (np.minimum(abs(world[:, 1]), abs(world[:, 1] - 4.0)) < 0.02) & (world[:, 0] > 0.3) & (world[:, 0] < 5.7)
    assert on_x_wall.sum() > 50 and on_y_wall.sum() > 50
    for across in (abs(n_world[on_x_wall & ref.on_line, 0]), abs(n_world[on_y_wall & ref.on_line, 1])):
        assert np.median(across) > 0.995 and across.min() > 0.9  # 1 cm range noise tilts a few by degrees
    # Merged at a pose, points and normals are moved and turned by it; the tree finds the moved points.
    other = Pose2(-2.0, 0.5, -1.0)
    merged = scan_closure.merge([ref, ref], [Pose2(), other])
    assert np.allclose(merged.points[len(pts):], other.transform_points(pts))
    c, s = math.cos(other.theta), math.sin(other.theta)
    assert np.allclose(merged.normals[len(pts):], ref.normals @ np.array([[c, s], [-s, c]]))
    assert np.array_equal(merged.on_line, np.concatenate([ref.on_line, ref.on_line]))
    assert merged.tree.query(other.transform_points(pts[:5]))[0].max() < 1e-12


def test_nearest_old_keyframe_skips_the_recent_ones():
    xy = np.array([[0.0, 0.0], [5.0, 0.0], [0.3, 0.0], [0.1, 0.0]])
    assert scan_closure.nearest_old(xy, np.array([0.0, 0.0]), 1.0, min_gap=1) == 0
    assert scan_closure.nearest_old(xy, np.array([0.25, 0.0]), 1.0, min_gap=1) == 2
    assert scan_closure.nearest_old(xy, np.array([0.25, 0.0]), 1.0, min_gap=2) == 0
    assert scan_closure.nearest_old(xy, np.array([3.0, 3.0]), 1.0, min_gap=1) is None


def _laps(seed: int, closures: bool, links: bool = False) -> tuple[float, int]:
    """Drive 3 laps round the room's pillar with a drifting gyro; (RMS keyframe error [m], closures made)."""
    rng = np.random.default_rng(seed)
    corners = [(1.0, 0.7), (5.0, 0.7), (5.0, 3.3), (1.0, 3.3)]
    truth = Pose2(1.0, 0.7, 0.0)
    odom = Pose2()
    slam = LandmarkSlam(SlamConfig(anchor_tag=None, closure_radius=1.0 if closures else 0.0, closure_min_gap=20,
                                   scan_links=SCAN_LINKS if links else ()))
    t, dt, kf_truth = 0.0, 0.1, []
    for _ in range(3):
        for i in range(4):
            gx, gy = corners[(i + 1) % 4]
            while True:
                dx, dy = gx - truth.x, gy - truth.y
                err = math.remainder(math.atan2(dy, dx) - truth.theta, 2 * math.pi)
                dist = math.hypot(dx, dy)
                if dist < 0.02:
                    break
                v, om = (0.0, float(np.clip(err / dt, -0.8, 0.8))) if abs(err) > 1e-3 else (min(0.3, dist / dt), err / dt)
                truth = truth.compose(Pose2(v * dt, 0.0, om * dt))
                odom = odom.compose(Pose2(v * dt * (1 + 0.03 * rng.normal()), 0.0, om * dt * 1.01 + 0.003 * v * dt))
                t += dt
                if slam.update(t, odom, _scan(ROOM, truth, rng, t)):
                    kf_truth.append(truth)
    slam.flush()
    est = slam.keyframe_poses()
    start = kf_truth[0]
    err = [start.compose(e).distance_to(tr) for e, tr in zip(est, kf_truth, strict=True)]  # map frame = start pose
    return float(np.sqrt(np.mean(np.square(err)))), slam.n_closures


def test_closures_straighten_a_drifting_drive():
    plain, none = _laps(0, closures=False)
    closed, made = _laps(0, closures=True)
    assert none == 0 and made > 20
    assert plain > 0.2  # the 1 % gyro scale error bends the odometry-only map (0.35 m RMS)
    assert closed < 0.3 * plain  # the walls keep every lap's heading (0.07 m)


def test_lidar_links_keep_a_slipping_drive_straight_without_closures():
    """Each keyframe's scan matched to the ones 1 and 4 back carries the map where wheels and gyro drift."""
    plain, _ = _laps(0, closures=False)
    linked, made = _laps(0, closures=False, links=True)
    assert made == 0
    assert linked < 0.5 * plain  # 0.35 m RMS → 0.13 m: what is left is the heading's random walk over 3 laps
    closed, _ = _laps(0, closures=True)
    both, _ = _laps(0, closures=True, links=True)
    assert both < 0.8 * closed  # 5.4 cm → 3.8 cm with closures


def test_a_closure_frees_the_corridor_axis_in_the_frame_its_error_is_measured_in():
    """A match's covariance (old keyframe's frame) is rotated into the measured pose's frame for GTSAM.

    The new keyframe is turned 90° from the old one: the corridor's axis,
    free in the old frame's y, is the new frame's x. Unrotated, the factor
    would pin the axis it cannot see and free the one it measured.
    """
    import gtsam

    cov = np.diag([0.01**2, scan_closure.FREE_SIGMA**2, math.radians(0.1) ** 2])  # old frame: y is the corridor
    found = scan_closure.Match(Pose2(1.0, 0.0, math.pi / 2), cov, 0.01, 0.9)
    factor = lidar_factor(0, 1, found)

    def error(dx: float, dy: float) -> float:  # keyframe 1 moved by (dx, dy) in the old keyframe's frame
        v = gtsam.Values()
        v.insert(X(0), to_gtsam(Pose2()))
        v.insert(X(1), to_gtsam(Pose2(1.0 + dx, dy, math.pi / 2)))
        return float(factor.error(v))

    assert error(0.0, 0.3) < 0.1  # along the corridor: the match says nothing
    assert error(0.3, 0.0) > 10.0  # across it: 30 σ
