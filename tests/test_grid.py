"""Occupancy grid: ray tracing against exact geometry, growth, map I/O, and the grid built in a known world vs its truth."""

from __future__ import annotations

import math

import numpy as np
from homing.mapping.evaluate import cell_agreement
from homing.mapping.grid import L_FREE, L_OCC, OPEN_REACH, OccupancyGrid
from homing.mapping.grid_slam import GridSlam
from homing.mapping.map_io import load_grid, save_grid
from homing.robot import Pose2, Scan

from homing.map_server import FREE, OCCUPIED, UNKNOWN, MapData
from tests.mapping_helpers import cast_scan, drifting_odometry, odometry_msg, path_poses, truth


def test_one_ray_clears_its_cells_and_marks_its_end():
    g = OccupancyGrid(0.1, (-1.0, -1.0), (20, 40), grow=False)
    g.integrate_rays(np.array([0.05, 0.05]), np.array([0.0]), np.array([1.0]), np.array([True]))
    row = g.data[10]  # y = 0.05 lies in row 10
    # cells x ∈ [0, 1.0) are crossed: cols 10..19; the end x = 1.05 is col 20
    assert (row[10:20] == FREE).all()
    assert row[20] == OCCUPIED
    assert (row[21:] == UNKNOWN).all() and (row[:10] == UNKNOWN).all()
    assert (g.data[9] == UNKNOWN).all() and (g.data[11] == UNKNOWN).all()


def test_grid_grows_and_keeps_world_coordinates():
    g = OccupancyGrid(0.05, (0.0, 0.0), (10, 10), grow=True)
    g.integrate_rays(np.array([0.2, 0.2]), np.array([math.pi]), np.array([3.0]), np.array([True]))
    assert g.origin[0] < -2.8
    assert g.value_at(-2.8 + 0.001, 0.21) == OCCUPIED
    assert g.value_at(-1.0, 0.21) == FREE
    fixed = OccupancyGrid(0.05, (0.0, 0.0), (10, 10), grow=False)
    fixed.integrate_rays(np.array([0.2, 0.2]), np.array([math.pi]), np.array([3.0]), np.array([True]))
    assert fixed.shape == (10, 10) and fixed.value_at(0.1, 0.21) == FREE


def test_isolated_dropout_does_not_clear_the_wall_behind():
    # a wall 2 m ahead on every ray but one, which returned nothing
    ranges = np.full(360, 2.0, dtype=np.float32)
    ranges[180] = np.inf  # straight ahead (angle 0)
    scan = Scan(0.0, -math.pi, 2 * math.pi / 360, ranges, 0.15, 6.0)
    g = OccupancyGrid(0.05, (-5.0, -5.0), (200, 200), grow=False)
    g.integrate(scan, Pose2())
    assert g.value_at(1.5, 0.0) == FREE
    assert g.value_at(2.5, 0.0) == UNKNOWN  # beyond the wall stays unknown


def test_map_round_trip(tmp_path):
    g = OccupancyGrid(0.05, (-1.0, -2.0), (30, 40), grow=False)
    g.integrate_rays(np.array([0.0, 0.0]), np.linspace(0, 1, 20), np.full(20, 0.8), np.ones(20, bool))
    path = save_grid(tmp_path / "m.yaml", g)
    back = load_grid(path)
    assert back.resolution == g.resolution and np.allclose(back.origin, g.origin)
    assert np.array_equal(back.data, g.data)
    assert not list(tmp_path.glob(".*.tmp"))  # written atomically, nothing left behind


def test_grid_built_in_known_world_matches_truth():
    """Grid SLAM on noisy scans and drifting odometry around a room: ≥ 97 % of observed cells agree with the truth."""
    world = truth("room_with_corner")
    poses = path_poses([(-3.5, -5.5), (-3.5, -1.5), (-8.0, -1.5)], speed=0.5)
    rng = np.random.default_rng(7)
    odom = drifting_odometry(poses, rng, bias=0.01, noise=0.01)
    slam = GridSlam(0.05)
    for i, (p, o) in enumerate(zip(poses, odom, strict=True)):
        slam.update(odometry_msg(i / 5.5, o), cast_scan(world, p, i / 5.5, rng, dropout=0.02))
    agreement = cell_agreement(slam.grid, world, world_from_map=poses[0])
    observed = int((slam.grid.data != UNKNOWN).sum())
    assert observed * 0.05**2 > 60.0  # a real area was mapped [m²]
    assert agreement >= 0.97, agreement
    # the raw odometry grid is visibly worse on the same run
    raw = GridSlam(0.05, use_matcher=False)
    rng = np.random.default_rng(7)
    drifting_odometry(poses, rng, bias=0.01, noise=0.01)
    for i, (p, o) in enumerate(zip(poses, odom, strict=True)):
        raw.update(odometry_msg(i / 5.5, o), cast_scan(world, p, i / 5.5, rng, dropout=0.02))
    assert cell_agreement(raw.grid, world, world_from_map=poses[0]) < agreement


def test_a_blanked_scan_clears_nothing_while_a_scan_of_open_space_still_does():
    # A wall 2 m ahead, seen once; then a lidar dropout blanks every ray: the wall must stay.
    grid = OccupancyGrid(0.05, (-3.0, -3.0), (120, 120))
    angles = np.linspace(-math.pi, math.pi, 360, endpoint=False)
    seen = np.where(np.abs(angles) < 0.3, 2.0 / np.cos(angles), np.inf).astype(np.float32)
    scan = Scan(0.0, -math.pi, 2 * math.pi / 360, seen, 0.15, 6.0)
    grid.integrate(scan, Pose2())
    wall = grid.value_at(2.02, 0.0)
    assert wall == OCCUPIED
    blank = Scan(0.1, -math.pi, 2 * math.pi / 360, np.full(360, np.inf, np.float32), 0.15, 6.0)
    for _ in range(20):
        grid.integrate(blank, Pose2())
    assert grid.value_at(2.02, 0.0) == OCCUPIED
    # A scan that mostly returned, with a gap of no returns (open space beyond the lidar's reach), clears the gap.
    open_gap = np.where(np.abs(angles - math.pi / 2) < 0.2, np.inf, 1.5).astype(np.float32)
    grid.integrate(Scan(0.2, -math.pi, 2 * math.pi / 360, open_gap, 0.15, 6.0), Pose2())
    assert grid.value_at(0.0, 4.0) == FREE


def test_an_obstacle_taken_away_from_a_room_is_cleared_by_the_rays_that_now_return_nothing():
    # A room 3 m round with an open door to the east, a box 2 m ahead in the doorway, seen for a while; then it
    # is gone and the rays through the door return nothing (the space beyond is out of reach). The scan mostly
    # returned: those rays clear the lidar's reach, the box's cells too. A blanked scan takes no wall away.
    grid = OccupancyGrid(0.05, (-8.0, -8.0), (320, 320))
    angles = np.linspace(-math.pi, math.pi, 360, endpoint=False)
    door = np.abs(angles) < 0.1
    room = np.where(door, np.inf, 3.0).astype(np.float32)
    box = np.where(door, 2.0, room).astype(np.float32)
    for k in range(5):
        grid.integrate(Scan(0.1 * k, -math.pi, 2 * math.pi / 360, box, 0.15, 6.0), Pose2())
    assert grid.value_at(2.02, 0.0) == OCCUPIED
    for k in range(20):
        grid.integrate(Scan(1.0 + 0.1 * k, -math.pi, 2 * math.pi / 360, room, 0.15, 6.0), Pose2())
    assert grid.value_at(2.02, 0.0) == FREE and grid.value_at(4.0, 0.0) == FREE
    walls = grid.data == OCCUPIED
    assert walls.sum() > 50
    for k in range(20):
        grid.integrate(Scan(3.0 + 0.1 * k, -math.pi, 2 * math.pi / 360, np.full(360, np.inf, np.float32), 0.15, 6.0),
                       Pose2())  # fmt: skip
    assert (grid.data[walls] == OCCUPIED).all()


def test_in_an_open_hall_rays_without_return_clear_up_to_the_walls_the_map_holds():
    # A hall: one wall 1.2 m to the east, seen by a few rays; nothing else within the lidar's reach. Most rays
    # return nothing (a scan of open space, no dropout): they clear the hall round the robot, OPEN_REACH far,
    # and past that, to the lidar's reach, only cells no ray has touched (a cell the map has a word on, here
    # one that read a wall once and free twice, is left as it is). Rays without return towards the wall (lost
    # at grazing incidence) do not clear the space behind it.
    grid = OccupancyGrid(0.05, (-8.0, -8.0), (320, 320))
    angles = np.linspace(-math.pi, math.pi, 360, endpoint=False)
    east = np.abs(angles) < 0.6
    ranges = np.where(east, 1.2 / np.cos(angles), np.inf).astype(np.float32)
    ys, xs = grid.cell_to_world(*np.indices(grid.shape))[::-1]
    distance = np.hypot(xs, ys)
    said = (xs < -OPEN_REACH - 0.1) & (np.abs(ys) < 0.5) & (distance < 5.0)  # a patch 2.1-5 m west
    grid.logodds[said] = L_OCC + 2 * L_FREE
    for k in range(4):  # the robot turning a quarter degree a scan: far out, rays 10 cm apart fill the gaps
        grid.integrate(Scan(0.1 * k, -math.pi, 2 * math.pi / 360, ranges, 0.15, 6.0), Pose2(0.0, 0.0, math.radians(0.25 * k)))
    west = (xs < 0) & (distance < OPEN_REACH - 0.1)
    assert (grid.data[west] == FREE).mean() > 0.95  # the hall round the robot
    far = (xs < 0) & (distance > OPEN_REACH + 0.1) & (distance < 6.0 - 0.1) & ~said
    assert (grid.data[far] == FREE).mean() > 0.95  # past it, to the lidar's reach, what no ray had touched
    assert np.all(grid.logodds[said] == np.float32(L_OCC + 2 * L_FREE))  # ... but not what the map had a word on
    assert (grid.data[(xs < 0) & (distance > 6.0 + 0.1)] == UNKNOWN).all()  # no farther than the lidar's reach
    assert OCCUPIED in (grid.value_at(1.18, 0.3), grid.value_at(1.22, 0.3))  # the face, on a cell boundary
    lost = ranges.copy()
    lost[east & (np.arange(360) % 10 < 5)] = np.inf  # five rays in ten on the wall lost, for 30 scans
    for k in range(30):
        grid.integrate(Scan(1.0 + 0.1 * k, -math.pi, 2 * math.pi / 360, lost, 0.15, 6.0), Pose2())
    assert OCCUPIED in (grid.value_at(1.18, 0.3), grid.value_at(1.22, 0.3))
    assert grid.value_at(1.6, 0.3) != FREE  # behind the wall, within OPEN_REACH


def _classified(grid: OccupancyGrid) -> np.ndarray:
    out = np.full(grid.shape, UNKNOWN, np.int8)
    out[grid.logodds > 0.40] = OCCUPIED
    out[grid.logodds < -0.20] = FREE
    return out


def test_the_map_view_updated_where_scans_changed_it_is_the_view_computed_afresh():
    # Scans round the loop (the grid grows past its edges), read after every scan and after every third: the
    # view recomputed where the scans since changed the grid equals the view of all its log-odds, and an
    # array read before an update is never changed by it.
    world = truth("loop")
    rng = np.random.default_rng(8)
    grid = OccupancyGrid(0.05, shape=(40, 40))
    before = None
    for i, pose in enumerate(path_poses([(-8.4, -8.4), (8.4, -8.4), (8.4, 8.4)], speed=2.0)):
        grid.integrate(cast_scan(world, pose, 0.0, rng, dropout=0.02), pose)
        if i % 3:
            continue
        if before is not None:
            old, kept = before
            assert np.array_equal(old, kept)
        view = grid.data
        assert np.array_equal(view, _classified(grid))
        before = (view, view.copy())
    assert grid.shape[0] > 40 and grid.shape[1] > 40


def test_a_copy_shares_the_view_and_history_but_changes_apart():
    # The SLAM service publishes copies of its live grid: each copy's view is the live one's (worked out only
    # where scans changed it), and after either changes, each view is still the one of its own log-odds.
    world = truth("loop")
    rng = np.random.default_rng(5)
    live = OccupancyGrid(0.05, shape=(40, 40))
    poses = list(path_poses([(-8.4, -8.4), (8.4, -8.4), (8.4, 8.4)], speed=2.0))
    for pose in poses[:10]:
        live.integrate(cast_scan(world, pose, 0.0, rng), pose)
    copy = live.copy()
    v = copy.version
    assert np.array_equal(copy.data, _classified(copy)) and copy.changed_since(v) == (0, 0, 0, 0)
    frozen = copy.data.copy()
    for pose in poses[10:20]:
        live.integrate(cast_scan(world, pose, 0.0, rng), pose)
    assert np.array_equal(copy.data, frozen)  # the live grid's scans do not reach the copy
    copy.integrate(cast_scan(world, poses[-1], 0.0, rng), poses[-1])
    assert np.array_equal(copy.data, _classified(copy)) and np.array_equal(live.data, _classified(live))
    assert copy.changed_since(v - 5) is not None  # its history came with it


def test_changed_since_bounds_every_changed_cell_and_says_when_it_does_not_know():
    world = truth("loop")
    rng = np.random.default_rng(9)
    grid = OccupancyGrid(0.05)
    pose = Pose2(-8.4, -8.4, 0.3)
    grid.integrate(cast_scan(world, pose, 0.0, rng), pose)
    v, old = grid.version, grid.logodds.copy()
    pose2 = Pose2(-6.0, -8.4, 0.0)
    grid.integrate(cast_scan(world, pose2, 0.0, rng), pose2)
    grid.integrate(cast_scan(world, pose2, 0.0, rng), pose2)
    r0, r1, c0, c1 = grid.changed_since(v)
    assert old.shape == grid.shape  # no growth here: cells compare one to one
    changed = old != grid.logodds
    assert changed.any()
    assert not changed[:r0].any() and not changed[r1:].any()
    assert not changed[:, :c0].any() and not changed[:, c1:].any()
    assert grid.changed_since(grid.version) == (0, 0, 0, 0)
    grid.clear_cache()  # changed from outside, nobody said where
    assert grid.changed_since(v) is None


def _integrate_rays_reference(g: OccupancyGrid, origin: np.ndarray, angles: np.ndarray, lengths: np.ndarray,
                              hit: np.ndarray) -> None:
    """Ray tracing as first written (every sample, masks over all of them), to hold the faster one to its bits."""
    from homing.mapping.grid import L_FREE, L_MAX, L_MIN, L_OCC

    ox, oy = float(origin[0]), float(origin[1])
    ends_x, ends_y = ox + lengths * np.cos(angles), oy + lengths * np.sin(angles)
    if g.grow and len(lengths):
        g.ensure_contains(min(ox, float(ends_x.min())), min(oy, float(ends_y.min())),
                          max(ox, float(ends_x.max())), max(oy, float(ends_y.max())))
    h, w = g.shape
    step = 0.5 * g.resolution
    t = np.arange(int(math.ceil(float(lengths.max(initial=0.0)) / step)) + 1, dtype=float) * step
    counts = np.searchsorted(t, lengths - np.where(hit, step, 0.0), side="left")
    ray = np.repeat(np.arange(len(lengths)), counts)
    k = np.arange(len(ray)) - np.repeat(np.cumsum(counts) - counts, counts)
    r, c = g.world_to_cell(ox + np.cos(angles)[ray] * t[k], oy + np.sin(angles)[ray] * t[k])
    inside = (r >= 0) & (r < h) & (c >= 0) & (c < w)
    free_idx = r[inside] * w + c[inside]
    hr, hc = g.world_to_cell(ends_x[hit], ends_y[hit])
    inside = (hr >= 0) & (hr < h) & (hc >= 0) & (hc < w)
    hit_idx = hr[inside] * w + hc[inside]
    flat = g.logodds.reshape(-1)
    free_idx = free_idx[~np.isin(free_idx, hit_idx)]
    flat[free_idx] += L_FREE
    flat[hit_idx] += L_OCC
    touched = np.concatenate([free_idx, hit_idx])
    flat[touched] = np.clip(flat[touched], L_MIN, L_MAX)
    g.clear_cache()


def test_ray_tracing_gives_the_log_odds_of_the_first_formulas_to_the_bit() -> None:
    rng = np.random.default_rng(5)
    # A growing grid (every ray inside it) and a fixed one that rays leave; scans repeated until cells clamp.
    for grow in (True, False):
        fast = OccupancyGrid(0.05, (-3.0, -2.0), (80, 90), grow=grow)
        slow = OccupancyGrid(0.05, (-3.0, -2.0), (80, 90), grow=grow)
        room = rng.uniform(0.1, 6.0, 360)  # the same walls scan after scan, seen from near the same place
        for _ in range(25):
            origin = rng.uniform(-0.05, 0.05, 2)
            angles = np.linspace(-math.pi, math.pi, 360, endpoint=False) + rng.uniform(-0.01, 0.01)
            lengths = room + rng.normal(0.0, 0.02, 360)
            lengths[rng.random(360) < 0.05] = 0.0
            hit = rng.random(360) > 0.1
            fast.integrate_rays(origin, angles, lengths, hit)
            _integrate_rays_reference(slow, origin, angles, lengths, hit)
            assert fast.origin == slow.origin and np.array_equal(fast.logodds, slow.logodds)
        assert fast.logodds.min() == -4.0 and fast.logodds.max() == 4.0  # the clamps were reached


def test_a_wall_seen_only_along_it_is_not_worn_away_by_the_rays_that_graze_it():
    # A robot drives 8 m beside a long straight wall, 0.4 m from it, a second wall 2.5 m on its other side. Far
    # ahead the lidar meets the wall at a few degrees: its returns lie a metre apart along the wall, and the rays
    # to them run along the wall's cells on the way, 70 cm of ray in a 5 cm cell at 4°. Between two returns the
    # wall is only ever crossed. In atrium:3 (nearest, seed 1) such rays wore a wall seen only that way down to
    # free in seconds; the scans then misfit at the right pose, the robot was counted lost, and the whole map's look
    # put it 9 m away. A return must outweigh the grazing rays between returns (L_OCC against L_FREE).
    res, origin = 0.05, (-4.0, -4.0)
    cells = np.zeros((160, 400), dtype=np.int8)  # 8 × 20 m, free
    cells[88, :] = OCCUPIED  # the wall beside the robot: y ∈ [0.40, 0.45)
    cells[29, :] = OCCUPIED  # the other: y ∈ [-2.55, -2.50)
    world = MapData(cells, res, origin)
    rng = np.random.default_rng(3)
    grid = OccupancyGrid(res)
    for x in np.arange(0.0, 8.0, 0.07):  # 0.4 m/s at 5.5 scans a second
        pose = Pose2(float(x), 0.0, 0.0)
        # drawn where tracking puts it, which a wall seen only along it holds loosely: 2 cm and 0.5° off (σ)
        drawn = Pose2(pose.x, float(rng.normal(0.0, 0.02)), float(rng.normal(0.0, math.radians(0.5))))
        grid.integrate(cast_scan(world, pose, rng=rng), drawn)
    xs = np.arange(0.0, 8.0, res) + res / 2
    wall = np.array([grid.value_at(float(x), 0.425) for x in xs])
    assert (wall == OCCUPIED).mean() >= 0.95, (wall == OCCUPIED).mean()
