"""Scan matching: recovers a known offset, and reduces pose error against odometry alone on a drifting run."""

from __future__ import annotations

import math

import numpy as np
import pytest
from homing.mapping.grid import OccupancyGrid
from homing.mapping.grid_slam import (
    TRACKING_PRIOR_POINTS,
    TRACKING_PRIOR_THETA,
    TRACKING_PRIOR_XY,
    GridSlam,
)
from homing.mapping.scan_match import CorrelativeMatcher, GridField, likelihood_field
from homing.robot import Pose2
from homing.robot.frames import wrap_angle

from tests.mapping_helpers import cast_scan, drifting_odometry, odometry_msg, path_poses, truth


def _loop_corner() -> tuple[OccupancyGrid, np.ndarray, Pose2]:
    """A grid of three scans from a corner of the loop world, a fourth scan's points there, and the pose."""
    world = truth("loop")
    pose = Pose2(-8.4, -8.4, 0.3)
    rng = np.random.default_rng(3)
    grid = OccupancyGrid(0.05)
    for _ in range(3):
        grid.integrate(cast_scan(world, pose, 0.0, rng), pose)
    return grid, cast_scan(world, pose, 0.0, rng).points(), pose


def test_matcher_recovers_a_known_offset():
    grid, pts, pose = _loop_corner()
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


def _brute_force(values: np.ndarray, res: float, origin: tuple[float, float], pts: np.ndarray, xs: np.ndarray,
                 ys: np.ndarray, thetas: np.ndarray) -> np.ndarray:
    """(T, X, Y) sums of the field under the points at every pose, one pose at a time (off the field: 0)."""
    h, w = values.shape
    out = np.zeros((len(thetas), len(xs), len(ys)))
    for t, th in enumerate(thetas):
        for i, x in enumerate(xs):
            for j, y in enumerate(ys):
                wpts = Pose2(x, y, th).transform_points(pts)
                c = np.floor((wpts[:, 0] - origin[0]) / res).astype(int)
                r = np.floor((wpts[:, 1] - origin[1]) / res).astype(int)
                ok = (r >= 0) & (r < h) & (c >= 0) & (c < w)
                out[t, i, j] = values[r[ok], c[ok]].sum()
    return out


def test_search_scores_every_pose_as_one_pose_at_a_time_would() -> None:
    from homing.mapping.scan_match import _search

    for seed in range(12):
        rng = np.random.default_rng(seed)
        values = rng.random((30, 40)).astype(np.float32)
        pts = rng.uniform(-4.0, 4.0, (50, 2))  # many land off the 8 m × 6 m field, or straddle its edge
        prior = Pose2(*rng.uniform(-1, 1, 2), rng.uniform(-3, 3))
        xs, ys = prior.x + np.arange(-3, 4) * 0.2, prior.y + np.arange(-3, 4) * 0.2
        thetas = prior.theta + np.arange(-2, 3) * 0.05
        sums = _brute_force(values, 0.2, (-4.0, -2.0), pts, xs, ys, thetas)
        # Without the prior's pull (huge σ) the search returns the brute force's best poses, best first.
        found = _search(values, 0.2, (-4.0, -2.0), pts, xs, ys, thetas, prior, 1e9, 1e9, keep=3)
        t, i, j = np.unravel_index(int(np.argmax(sums)), sums.shape)
        assert found[0][:3] == (xs[i], ys[j], thetas[t])
        assert found[0][3] == pytest.approx(sums.max(), rel=1e-5)
        scores = [f[3] for f in found]
        assert scores == sorted(scores, reverse=True)
        for x, y, th, score in found:  # each kept pose is a local maximum of the brute force's scores
            t, i, j = int(np.argmin(abs(thetas - th))), int(np.argmin(abs(xs - x))), int(np.argmin(abs(ys - y)))
            block = sums[max(t - 1, 0):t + 2, max(i - 1, 0):i + 2, max(j - 1, 0):j + 2]
            assert score == pytest.approx(block.max(), rel=1e-5)


def test_points_field_is_a_gaussian_of_the_distance_to_the_nearest_point() -> None:
    from homing.mapping.scan_match import SIGMA, points_field

    field = points_field(np.array([[0.0, 0.0], [3.0, 0.0]]), 0.05)
    r0, c0 = np.argwhere(field.values == field.values.max())[0]  # the first point's cell (value 1)
    assert field.values[r0, c0] == pytest.approx(1.0)
    for k in range(1, 7):  # k cells away along a row and along a column: exp(−d²/2σ²), d = k·5 cm
        expect = math.exp(-0.5 * (k * 0.05 / SIGMA) ** 2)
        assert field.values[r0, c0 + k] == pytest.approx(expect, abs=1e-3)
        assert field.values[r0 + k, c0] == pytest.approx(expect, abs=1e-3)
    assert field.values[r0 + 3, c0 + 4] == pytest.approx(math.exp(-0.5 * (0.25 / SIGMA) ** 2), abs=0.02)  # 3-4-5
    # Max-pooled levels bound every finer cell under them (the correlative search's pruning relies on it).
    for k in (1, 2, 3):
        coarse, fine = field.level(k), field.values
        h, w = fine.shape
        for r, c in [(0, 0), (h // 2, w // 3), (h - 1, w - 1)]:
            assert coarse[r >> k, c >> k] >= fine[r, c]


def slipping_odometry(poses: list[Pose2], slipping: range, keep: float = 0.5) -> list[Pose2]:
    """Odometry (from identity) of exact encoders, except that over the steps in ``slipping`` the base moved only
    ``keep`` of what the wheels turned (they spun on the floor): the encoders count 1/keep × the true travel."""
    odom = [Pose2()]
    for k, (p0, p1) in enumerate(zip(poses[:-1], poses[1:], strict=False)):
        d = p0.between(p1)
        scale = 1.0 / keep if k in slipping else 1.0
        odom.append(odom[-1].compose(Pose2(d.x * scale, d.y * scale, d.theta)))
    return odom


LAP = [(-9.0, -9.0), (9.0, -9.0), (9.0, 9.0), (-9.0, 9.0), (-9.0, -9.0)]


@pytest.mark.slow
@pytest.mark.parametrize("plan", ["room", "room_with_corner", "corridor", "loop"])
def test_tracking_follows_the_walls_not_the_wheels_while_they_slip(plan: str) -> None:
    """Two laps of a plan; on the second, mapped, lap the wheels slip by half for 12 m (the sim's wheel_slip fault).

    Odometry ends metres out. With one tight odometry prior, tracking slid with it (11.8 m on ``room``; bench
    dock seed 50: 2 m in 10 s); without slip, the rungs of SLIP_SCALES are never left.
    """
    world = truth(plan)
    poses = path_poses(LAP + LAP[1:], speed=0.4)
    first = len(poses) // 2 + 40
    errors = {}
    for slipping in (range(0), range(first, first + int(12.0 / (0.4 / 5.5)))):
        odom = slipping_odometry(poses, slipping)
        slam = GridSlam(0.05)
        rng = np.random.default_rng(3)
        err, drift = [], []
        for i, (p, o) in enumerate(zip(poses, odom, strict=True)):
            slam.update(odometry_msg(i / 5.5, o), cast_scan(world, p, i / 5.5, rng, dropout=0.02))
            t = poses[0].between(p)
            err.append(math.hypot(slam.pose.x - t.x, slam.pose.y - t.y))
            drift.append(math.hypot(o.x - t.x, o.y - t.y))
        errors[len(slipping) > 0] = (max(err), max(drift), slam.slip_switches)
    still, slipped = errors[False], errors[True]
    assert still[2] == 0 and still[0] < 0.15, still  # no slip seen where there is none
    assert slipped[1] > 5.0  # the wheels really slipped
    assert slipped[2] >= 2  # onto a rung and back off it
    assert slipped[0] < 0.25, slipped


@pytest.mark.slow
@pytest.mark.parametrize("plan", ["loop", "room_with_corner"])
def test_tracking_holds_the_walls_heading_while_the_gyro_drifts(plan: str) -> None:
    """A lap with a gyro drifting 0.03° a metre (2° over the lap): the heading comes from the walls, not the gyro.

    The match's Gauss-Newton pulls towards the correlative optimum (on 0.5° steps, tied to the gyro) by 2° per end
    point; near a fit the likelihood field is flat, so the pull outweighed the walls and, with nothing after it,
    tracking turned with the gyro (0.61° and 0.42° on average here, 1.2° and 1.5° at worst). With the heading let go
    once the match is chosen (TRACKING_ANCHOR_THETA): 0.08° and 0.11°, 0.37° and 0.36°.
    """
    world = truth(plan)
    poses = path_poses(LAP, speed=0.4)
    odom = drifting_odometry(poses, np.random.default_rng(1), bias=0.0005, noise=0.002)
    slam = GridSlam(0.05)
    rng = np.random.default_rng(3)
    errors = []
    for i, (p, o) in enumerate(zip(poses, odom, strict=True)):
        slam.update(odometry_msg(i / 5.5, o), cast_scan(world, p, i / 5.5, rng, dropout=0.02))
        errors.append(abs(math.degrees(wrap_angle(slam.pose.theta - poses[0].between(p).theta))))
    drift = abs(math.degrees(wrap_angle(odom[-1].theta - poses[0].between(poses[-1]).theta)))
    assert drift > 1.5  # [deg] the gyro did drift
    assert np.mean(errors) < 0.25 and max(errors) < 0.8, (np.mean(errors), max(errors))


@pytest.mark.slow
@pytest.mark.parametrize("plan", ["room", "loop"])
def test_a_false_step_onto_a_slip_rung_is_undone_when_the_wheels_grip(plan: str) -> None:
    """Half-way round the second lap tracking steps onto ¾ with no slip (as one scan that fits ¾ a little better
    made it on the lab, day 4). Rung 1 then fits better, if only a little, and is taken back on that (SLIP_RETURN);
    asked to win by SLIP_MARGIN, as a step away is, it never did, and tracking slid 3.7 m on both plans."""
    world = truth(plan)
    poses = path_poses(LAP + LAP[1:], speed=0.4)
    first = len(poses) // 2 + 40
    slam = GridSlam(0.05)
    rng = np.random.default_rng(3)
    err, back = [], None
    for i, p in enumerate(poses):
        t = poses[0].between(p)  # exact encoders: odometry is the truth here
        if i == first:
            slam.odom_scale = 0.75
        slam.update(odometry_msg(i / 5.5, t), cast_scan(world, p, i / 5.5, rng, dropout=0.02))
        if i >= first:
            err.append(math.hypot(slam.pose.x - t.x, slam.pose.y - t.y))
            if back is None and slam.odom_scale == 1.0:
                back = (i - first) / 5.5
    assert back is not None and back < 2.0, back  # [s]
    assert max(err) < 0.15, max(err)


@pytest.mark.parametrize(("plan", "pose"), [("room_with_corner", Pose2(-4.0, -3.0, 0.4)),
                                             ("room", Pose2(-2.0, 1.0, 1.0)), ("loop", Pose2(-8.4, -8.4, 0.3))])
def test_polish_moves_a_pose_a_few_centimetres_off_towards_the_walls_where_the_tight_refinement_holds_it(
        plan: str, pose: Pose2) -> None:
    # What GridSlam's polish is for: match()'s Gauss-Newton is pulled to the correlative optimum by GN_ANCHOR_XY
    # per end point, which holds a pose 3.5 cm off (under the search's 5 cm step) where it is: it closes about
    # 1 % of the offset, the polish's looser pull (POLISH_XY) 27-50 % per scan (33-56 % when a crossing ray took
    # 0.40 from a cell, not 0.25: four scans then drew the walls a little thinner).
    from homing.mapping.grid_slam import POLISH_XY
    from homing.mapping.scan_match import GN_ANCHOR_XY

    world = truth(plan)
    rng = np.random.default_rng(5)
    grid = OccupancyGrid(0.05)
    for _ in range(4):
        grid.integrate(cast_scan(world, pose, 0.0, rng), pose)
    pts = cast_scan(world, pose, 0.0, rng).points()
    matcher = CorrelativeMatcher(refine=True)
    for dx, dy in [(0.03, -0.02), (-0.025, -0.025), (0.0, 0.035)]:
        off = Pose2(pose.x + dx, pose.y + dy, pose.theta)
        loose = matcher.polish(grid, pts, off, 8.0, POLISH_XY)
        tight = matcher.polish(grid, pts, off, 8.0, GN_ANCHOR_XY)
        assert loose.distance_to(pose) < 0.8 * off.distance_to(pose), loose
        assert tight.distance_to(pose) > 0.95 * off.distance_to(pose), tight
        assert abs(loose.theta - pose.theta) < math.radians(0.3)


def test_the_kept_field_of_a_growing_grid_is_the_whole_grid_field_bit_for_bit() -> None:
    # A run round the loop grows the grid past its first extent several times; after every scan the field
    # recomputed tile by tile equals the field computed afresh over the whole grid, to the last bit.
    world = truth("loop")
    rng = np.random.default_rng(5)
    grid, kept = OccupancyGrid(0.05, shape=(40, 40)), GridField()
    sizes = set()
    for pose in path_poses([(-8.4, -8.4), (8.4, -8.4), (8.4, 8.4), (-8.4, 8.4)], speed=2.0):
        grid.integrate(cast_scan(world, pose, 0.0, rng, dropout=0.02), pose)
        values = kept.update(grid)
        fresh = likelihood_field(grid, (0.0, 0.0), 1e3).values
        assert values.shape == grid.shape
        assert np.array_equal(values, fresh)
        assert np.array_equal(kept.known, grid.data != -1)
        sizes.add(grid.shape)
    assert len(sizes) > 2  # it grew
    assert kept.tiles_recomputed > 0  # the tile by tile path ran, not only whole recomputations


def test_a_crop_of_the_kept_field_is_the_fresh_crop_away_from_its_edge() -> None:
    # Within the crop, farther than the field's reach (10 sigma) from its edge, cutting the whole grid's field
    # gives the fresh crop's values exactly; nearer the edge only walls outside the crop may differ.
    world = truth("loop")
    rng = np.random.default_rng(6)
    grid = OccupancyGrid(0.05)
    for pose in path_poses([(-8.4, -8.4), (8.4, -8.4)], speed=2.0):
        grid.integrate(cast_scan(world, pose, 0.0, rng), pose)
    kept = GridField()
    for centre in [(-3.0, -8.4), (2.2, -7.9)]:
        fresh = likelihood_field(grid, centre, 3.0)
        cut = likelihood_field(grid, centre, 3.0, whole=kept)
        assert fresh.origin == cut.origin and fresh.values.shape == cut.values.shape
        assert np.array_equal(fresh.known, cut.known)
        inner = int(np.ceil(1.0 / 0.05)) + 1
        assert np.array_equal(fresh.values[inner:-inner, inner:-inner], cut.values[inner:-inner, inner:-inner])
        assert (cut.values >= fresh.values).all()  # a wall outside the crop only ever raises the field


@pytest.mark.parametrize("shape", [(7, 9), (8, 9), (7, 8), (8, 8), (1, 1), (1, 4), (3, 1)])
def test_pooling_is_the_max_of_each_two_by_two_block_padded_with_zeros(shape: tuple[int, int]) -> None:
    from homing.mapping.scan_match import _pool

    rng = np.random.default_rng(sum(shape))
    for values in (rng.random(shape).astype(np.float32), -rng.random(shape).astype(np.float32)):
        h, w = shape
        padded = np.zeros((h + h % 2, w + w % 2), np.float32)
        padded[:h, :w] = values
        expect = padded.reshape(padded.shape[0] // 2, 2, padded.shape[1] // 2, 2).max(axis=(1, 3))
        assert np.array_equal(_pool(values), expect)


def _bilinear_reference(field, x, y):
    """The interpolation as first written (2-D fancy indexing, np.clip), to hold the faster one to its bits."""
    res = field.resolution
    fx = (x - field.origin[0]) / res - 0.5
    fy = (y - field.origin[1]) / res - 0.5
    x0 = np.floor(fx).astype(np.int64)
    y0 = np.floor(fy).astype(np.int64)
    ax, ay = fx - x0, fy - y0
    h, w = field.values.shape
    ok = (x0 >= 0) & (x0 < w - 1) & (y0 >= 0) & (y0 < h - 1)
    x0c, y0c = np.clip(x0, 0, max(w - 2, 0)), np.clip(y0, 0, max(h - 2, 0))
    v = field.values
    v00, v01 = v[y0c, x0c], v[y0c, x0c + 1]
    v10, v11 = v[y0c + 1, x0c], v[y0c + 1, x0c + 1]
    m = (1 - ay) * ((1 - ax) * v00 + ax * v01) + ay * ((1 - ax) * v10 + ax * v11)
    gx = ((1 - ay) * (v01 - v00) + ay * (v11 - v10)) / res
    gy = ((1 - ax) * (v10 - v00) + ax * (v11 - v01)) / res
    col = np.floor((x - field.origin[0]) / res).astype(np.int64)
    row = np.floor((y - field.origin[1]) / res).astype(np.int64)
    inside = (row >= 0) & (row < h) & (col >= 0) & (col < w)
    known = np.zeros(len(x))
    known[inside] = field.known[row[inside], col[inside]]
    return np.where(ok, m, 0.0), np.where(ok, gx, 0.0), np.where(ok, gy, 0.0), known


@pytest.mark.parametrize("view", [False, True])
def test_the_fields_interpolation_and_known_cells_are_the_first_formulas_to_the_bit(view) -> None:
    from homing.mapping.scan_match import LikelihoodField, _bilinear, _known, _residuals

    rng = np.random.default_rng(3)
    whole = rng.random((90, 100)).astype(np.float32)
    known = rng.random((90, 100)) > 0.3
    # A crop of a larger field is a view (not contiguous): the other gather.
    values, seen = (whole[7:67, 5:75], known[7:67, 5:75]) if view else (whole[:60, :70].copy(), known[:60, :70].copy())
    field = LikelihoodField(values, (1.0, 2.0), 0.05, seen)
    # Points on the field, on its edges and off it.
    x = np.concatenate([rng.uniform(0.8, 4.7, 3000), [1.0, 1.025, 4.5, 4.475, 0.9]])
    y = np.concatenate([rng.uniform(1.8, 5.2, 3000), [2.0, 2.025, 5.0, 4.975, 5.3]])
    m, gx, gy, k = _bilinear_reference(field, x, y)
    got = _bilinear(field, x, y)
    for a, b in zip(got, (m, gx, gy), strict=True):
        assert np.array_equal(a, b)
    assert np.array_equal(_bilinear(field, x, y, gradient=False)[0], m)
    assert np.array_equal(_known(field, x, y), k)
    # The Jacobian and residuals share the cells of the two: the same as built from the reference.
    pts = np.column_stack([x, y]) - [2.5, 3.5]
    xi = np.array([2.5, 3.5, 0.0])
    J, r = _residuals(field, pts, xi)
    assert np.array_equal(r, (1.0 - m) * k)
    assert np.array_equal(J[:, 0], gx * k) and np.array_equal(J[:, 1], gy * k)


def test_a_matchs_score_is_the_fields_mean_under_the_scan_at_the_refined_pose() -> None:
    from homing.mapping.scan_match import _score

    grid, points, pose = _loop_corner()
    matcher = CorrelativeMatcher(refine=True)
    for dx, dy, dth in [(0.12, -0.08, 0.05), (-0.1, 0.15, -0.1), (0.0, 0.0, 0.0)]:
        prior = Pose2(pose.x + dx, pose.y + dy, pose.theta + dth)
        result = matcher.match(grid, points, prior)
        prepared = matcher._prepare(grid, points, prior, 5.0)
        assert prepared is not None
        # The score the refinement chose its pose by is the one a fresh look at that pose gives.
        assert result.score == _score(prepared[1], prepared[0], result.pose)


def test_a_sparse_scan_far_from_the_walls_keeps_the_gyros_heading() -> None:
    # An open hall's scan: 40 returns, all 2.5 m and more away, 8 cm of range noise, and a gyro that is right. The
    # fit of so few points is noisy enough that weighing the heading's prior per point (prior_points=0) lets some
    # scans step a search step (0.5°) or so off the gyro; weighed as a room's 180 points, none moves.
    world = truth("loop")
    grid, _, pose = _loop_corner()
    worst = {}
    for prior_points in (0, TRACKING_PRIOR_POINTS):
        errors = []
        for k in range(40):
            r = np.random.default_rng(100 + k)
            pts = cast_scan(world, pose, 0.0, r, noise=0.08).points()
            pts = pts[np.hypot(pts[:, 0], pts[:, 1]) > 2.5]
            pts = pts[r.choice(len(pts), 40, replace=False)]
            matcher = CorrelativeMatcher(prior_xy=TRACKING_PRIOR_XY, prior_theta=TRACKING_PRIOR_THETA, refine=True,
                                         prior_points=prior_points)
            errors.append(abs(wrap_angle(matcher.match(grid, pts, pose).pose.theta - pose.theta)))
        worst[prior_points] = math.degrees(max(errors))
    assert worst[0] > 0.25, worst  # the case is a hard one: per point, the noise wins now and then
    assert worst[TRACKING_PRIOR_POINTS] < 0.05, worst
