"""Landmark SLAM (iSAM2) on synthetic drives whose truth is known."""

from __future__ import annotations

import copy
import dataclasses
import math

import numpy as np
import pytest
from homing.mapping.landmark_slam import LandmarkSlam, SlamConfig, interpolate_pose
from homing.mapping.landmark_synthetic import SyntheticRun, synthetic_loop
from homing.perception.apriltag import TagMeasurement
from homing.robot.types import Pose2, Scan

from tests.navworld import scan_of


def _run(run: SyntheticRun, **cfg) -> LandmarkSlam:
    slam = LandmarkSlam(SlamConfig(**cfg))
    for stamp, _, odom, seen in run.ticks:
        slam.update(stamp, odom, None, seen)
    slam.flush()
    return slam


def _best_fit_errors(est: dict[int, np.ndarray], truth: dict[int, Pose2]) -> np.ndarray:
    """Per-tag distance [m] after the best rigid 2-D fit (Kabsch), so the map's gauge does not count."""
    ids = sorted(est)
    A = np.array([est[i] for i in ids])
    B = np.array([[truth[i].x, truth[i].y] for i in ids])
    ma, mb = A.mean(0), B.mean(0)
    U, _, Vt = np.linalg.svd((A - ma).T @ (B - mb))
    d = np.sign(np.linalg.det(Vt.T @ U.T))
    R = Vt.T @ np.diag([1.0, d]) @ U.T
    return np.linalg.norm((A - ma) @ R.T + mb - B, axis=1)


@pytest.fixture(scope="module")
def loop() -> SyntheticRun:
    return synthetic_loop(seed=0)


@pytest.fixture(scope="module")
def loop_slam(loop: SyntheticRun) -> LandmarkSlam:
    return _run(loop)


def test_noise_free_drive_recovers_the_exact_map():
    run = synthetic_loop(seed=1, slip=0.0, yaw_bias=0.0, tag_noise=0.0, yaw_noise=0.0)
    slam = _run(run)
    est = slam.landmarks()
    assert set(est) == set(run.tags)
    for tag_id, p in run.tags.items():
        assert est[tag_id].distance_to(p) < 0.005
        assert abs(math.remainder(est[tag_id].theta - p.theta, 2 * math.pi)) < 0.005


def test_loop_recovers_known_landmarks_within_the_noise(loop, loop_slam):
    est = loop_slam.landmarks()
    assert set(est) == set(loop.tags)
    slam_err = _best_fit_errors({i: np.array([p.x, p.y]) for i, p in est.items()}, loop.tags)
    # Raw odometry baseline: every sighting placed through the odometry pose, averaged per tag.
    placed: dict[int, list[np.ndarray]] = {}
    for _, _, odom, seen in loop.ticks:
        for m in seen:
            q = odom.compose(m.pose)
            placed.setdefault(m.tag_id, []).append(np.array([q.x, q.y]))
    odom_err = _best_fit_errors({i: np.mean(v, axis=0) for i, v in placed.items()}, loop.tags)
    assert slam_err.mean() < 0.03
    assert slam_err.mean() < 0.6 * odom_err.mean()  # odometry with a gyro drifts gently (0.2 % scale error)
    # Each tag lies within 3 σ of its own marginal (the graph's uncertainty is honest).
    for tag_id, p in loop.tags.items():
        sigma = math.sqrt(np.trace(loop_slam.landmark_covariance(tag_id)[:2, :2]))
        assert est[tag_id].distance_to(p) < 3.0 * sigma


def test_closing_the_loop_corrects_map_to_odom(loop, loop_slam):
    _, truth_end, odom_end, _ = loop.ticks[-1]
    assert truth_end.distance_to(odom_end) > 0.15  # the odometry really drifted
    assert truth_end.distance_to(loop_slam.pose(odom_end)) < 0.5 * truth_end.distance_to(odom_end)
    assert truth_end.distance_to(loop_slam.pose(odom_end)) < 0.1


def test_a_wrong_id_is_down_weighted_instead_of_bending_the_map(loop):
    bad = copy.deepcopy(loop)
    half = len(bad.ticks) // 2
    for _, _, _, seen in bad.ticks[half:]:
        hits = [j for j, m in enumerate(seen) if m.tag_id == 3]
        if hits:  # one sighting of tag 3 reported as tag 6: a wrong association
            seen[hits[0]] = dataclasses.replace(seen[hits[0]], tag_id=6)
            break
    else:
        pytest.fail("tag 3 never seen in the second half")
    shift = {}
    for kernel in ("cauchy", "none"):
        clean, corrupted = _run(loop, robust=kernel).landmarks(), _run(bad, robust=kernel).landmarks()
        shift[kernel] = max(clean[i].distance_to(corrupted[i]) for i in clean)
    assert shift["none"] > 0.2  # least squares lets one wrong factor bend the map
    assert shift["cauchy"] < 0.03
    assert shift["cauchy"] < 0.1 * shift["none"]


def test_keyframes_start_every_set_distance_and_turn():
    slam = LandmarkSlam(SlamConfig(keyframe_distance=0.25, keyframe_angle=math.radians(20)))
    t = 0.0
    for i in range(21):  # 1 m straight in 5 cm steps
        slam.update(t, Pose2(0.05 * i, 0.0, 0.0))
        t += 0.1
    assert len(slam.keyframes) == 5
    for i in range(1, 19):  # then 90° on the spot in 5° steps
        slam.update(t, Pose2(1.0, 0.0, math.radians(5 * i)))
        t += 0.1
    assert len(slam.keyframes) == 5 + 4
    assert [round(k.odom.x, 2) for k in slam.keyframes[:5]] == [0.0, 0.25, 0.5, 0.75, 1.0]


def test_the_dock_tag_anchors_the_map(loop):
    anchored = _run(loop, anchor_tag=0)
    assert anchored.anchored
    first = loop.ticks[0][3][0]
    assert first.tag_id == 0
    seen_first = loop.ticks[0][2].compose(first.pose)  # the dock tag where it was first placed
    assert anchored.landmarks()[0].distance_to(seen_first) < 0.02
    assert not _run(loop, anchor_tag=None).anchored


def test_a_late_image_is_placed_with_the_odometry_of_its_stamp():
    """A sighting stamped before the tick is carried with the odometry at its own stamp."""
    tag = Pose2(2.0, 0.0, math.pi)
    slam = LandmarkSlam(SlamConfig(anchor_tag=None))
    cov = np.diag([1e-4, 1e-4, 1e-4])
    t, pose = 0.0, Pose2()
    sighting = None
    for i in range(12):  # turning 0.1 rad per 0.1 s
        pose = Pose2(0.0, 0.0, 0.1 * i)
        if i == 5:
            rel = pose.between(tag)
            sighting = TagMeasurement(4, t, rel, cov, 2.0, 0.0, 0.0, 100.0, 0, 0.4, np.eye(4), np.zeros((4, 2)))
        seen = [sighting] if i == 7 else []  # the image arrives two ticks late
        slam.update(t, pose, None, seen)
        t += 0.1
    slam.flush()
    assert slam.landmarks()[4].distance_to(tag) < 0.01


def test_interpolate_pose_between_samples():
    hist = [(0.0, Pose2(0.0, 0.0, 3.0)), (1.0, Pose2(1.0, 2.0, -3.0))]
    mid = interpolate_pose(hist, 0.5)
    assert mid.x == pytest.approx(0.5) and mid.y == pytest.approx(1.0)
    assert abs(math.remainder(mid.theta - math.pi, 2 * math.pi)) < 1e-9  # wraps through π, not 0
    assert interpolate_pose(hist, -1.0) == hist[0][1] and interpolate_pose(hist, 9.0) == hist[1][1]


def test_same_input_gives_the_same_map_bit_for_bit(loop, loop_slam):
    again = _run(loop)
    assert again.landmarks() == loop_slam.landmarks()
    assert again.map_to_odom == loop_slam.map_to_odom


def test_grid_is_rebuilt_from_optimised_keyframe_poses(loop_slam):
    class Sink:
        def __init__(self) -> None:
            self.poses: list[Pose2] = []

        def integrate(self, scan: Scan, pose: Pose2) -> None:
            self.poses.append(pose)

    slam = LandmarkSlam()
    scan = Scan(0.0, -math.pi, math.radians(1), np.full(360, 2.0, np.float32), 0.15, 6.0)
    t = 0.0
    for i in range(30):
        odom = Pose2(0.05 * i, 0.0, 0.0)
        slam.update(t, odom, dataclasses.replace(scan, stamp=t - 0.1), [])
        t += 0.1
    sink = slam.rebuild_grid(Sink)
    kf = slam.keyframe_poses()
    assert len(sink.poses) == len(slam.keyframes) == len(kf)
    # Each scan is drawn where the robot was at the scan's stamp (0.1 s = 5 cm before the keyframe).
    for p, k in zip(sink.poses[1:], kf[1:], strict=False):
        assert p.x == pytest.approx(k.x - 0.05, abs=1e-6)


def test_every_sighting_of_a_standing_robot_counts_not_only_the_best_conditioned():
    """Six frames of one tag from one keyframe are averaged (issue 37: keeping the best one threw five away).

    The best-conditioned frame is 2 cm long and the wall's heading in it
    0.3° off; the others scatter ±2 cm and ±0.3° about the truth, and one
    has only the corners' heading (0.3 rad off, σ 0.5 rad). The map is the mean.
    """
    tag = Pose2(1.2, 0.0, math.pi)
    slam = LandmarkSlam(SlamConfig(anchor_tag=None))
    wall = np.diag([1e-4, 1e-4, math.radians(0.3) ** 2])
    corners = np.diag([1e-4, 1e-4, 0.5**2])
    errors = [(0.02, 0.3, 0.95 * wall), (-0.02, -0.3, wall), (0.02, 0.3, wall), (-0.02, -0.3, wall),
              (0.0, math.degrees(0.3), corners), (0.0, 0.0, wall), (-0.02, -0.3, wall), (0.02, 0.3, wall)]
    for i, (dx, dyaw, cov) in enumerate(errors):
        rel = Pose2(tag.x + dx, 0.0, tag.theta + math.radians(dyaw))
        m = TagMeasurement(5, 0.1 * i, rel, cov, 1.2, 0.0, 0.0, 100.0, 0, 0.4, np.eye(4), np.zeros((4, 2)),
                           yaw_source="tag" if cov is corners else "wall")
        slam.update(0.1 * i, Pose2(), None, [m])
    slam.flush()
    est = slam.landmarks()[5]
    assert est.distance_to(tag) < 0.002  # the best one alone: 2 cm
    assert abs(math.remainder(est.theta - tag.theta, 2 * math.pi)) < math.radians(0.05)  # the best alone: 0.3°


# A straight corridor 26 m long and 3 m wide (walls as rectangles x0, y0, x1, y1 [m]): from its middle the lidar
# (6 m) sees only the two side walls, which say nothing about travel along it.
CORRIDOR = np.array([(-1.1, -1.6, 25.1, -1.5), (-1.1, 1.5, 25.1, 1.6), (-1.1, -1.6, -1.0, 1.6), (25.0, -1.6, 25.1, 1.6)])


def test_the_middle_of_a_corridor_longer_than_twice_the_lidar_range_is_measured_by_the_wheels_alone():
    # The robot drives the corridor's axis from x = 0 to 24 m; its wheels count 2 % too far. The lidar links
    # correct that where an end wall is within 6 m (x < 5, x > 19) and cannot in between, so the map is 2 % long
    # over the 14 m blind middle and right elsewhere (bench slam's loop world: 8 m of each corridor, where its
    # along-corridor error comes from).
    slam = LandmarkSlam(SlamConfig(closure_radius=0.0))
    truth: list[float] = []
    for k in range(801):
        x = 0.03 * k  # [m] 0.3 m/s for 80 s
        slam.update(0.1 * k, Pose2(1.02 * x, 0.0, 0.0), scan_of(Pose2(x, 0.0, 0.0), CORRIDOR, 0.1 * k))
        truth.extend([x] * (len(slam.keyframes) - len(truth)))
    slam.flush()
    true_x = np.array(truth)
    err = np.array([p.x for p in slam.keyframe_poses()]) - true_x  # [m] along the corridor
    at = {q: float(err[np.argmin(np.abs(true_x - q))]) for q in (4.0, 6.0, 18.0, 20.0, 24.0)}
    assert abs(at[4.0]) < 0.005  # the start wall in range: the lidar measures travel
    assert at[18.0] - at[6.0] == pytest.approx(0.02 * 12.0, abs=0.01)  # blind: the wheels' 2 % over 12 m
    assert abs(at[24.0] - at[20.0]) < 0.01  # the far wall in range again: no more error
    assert 0.02 * 13.0 < err[-1] < 0.02 * 15.0 < 0.02 * 24.0  # the blind 14 m's share of the wheels' error
