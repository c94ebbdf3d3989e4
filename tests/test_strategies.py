"""Each strategy's goal choice on a fixed grid is the one its rule says; the explorer blacklists stalled goals."""

from __future__ import annotations

import numpy as np
from homing.mapping.explorer import Explorer
from homing.mapping.frontier import raw_frontiers, smoothed_frontiers
from homing.mapping.grid import OccupancyGrid
from homing.mapping.strategies import (
    MIN_GAIN,
    SETBACK,
    VIEW_RADIUS,
    VIEW_RAYS,
    GoalContext,
    make_strategy,
    visible_unknown,
)
from homing.robot import Pose2

from homing.map_server import FREE, OCCUPIED, UNKNOWN, MapData
from tests.mapping_helpers import travel_distance

RES = 0.05


def _corridor_world() -> tuple[np.ndarray, tuple[int, int]]:
    """A 2 m-wide corridor along x; robot at its west end. A short opening (small frontier) in the south wall
    near the robot, and the whole far east end open onto unknown (large frontier)."""
    g = np.full((100, 200), UNKNOWN, dtype=np.int8)
    g[40:80, 5:150] = FREE
    g[40, 5:150] = OCCUPIED
    g[79, 5:150] = OCCUPIED
    g[40:80, 5] = OCCUPIED
    g[25:41, 30:60] = FREE  # a pocket to the south, 1.5 m wide, unknown beyond
    g[25:41, 29] = g[25:41, 60] = OCCUPIED
    # everything south of the corridor is solid except a thin unknown strip beyond the pocket
    south = g[:40]
    south[south == UNKNOWN] = OCCUPIED
    g[21:25, 30:60] = UNKNOWN
    return g, (60, 12)


def _ctx(seed: int = 0) -> GoalContext:
    g, robot = _corridor_world()
    dist = travel_distance(g, RES, robot)
    excluded = np.zeros(g.shape, bool)
    return GoalContext(g, RES, (float(robot[0]), float(robot[1])), 0.0, dist, excluded, np.random.default_rng(seed))


def test_nearest_goes_to_the_closest_point_of_the_nearest_segment():
    ctx = _ctx()
    choice = make_strategy("nearest").choose(ctx)
    assert choice is not None
    near_pocket = choice.cell[1] < 60
    assert near_pocket
    # the chosen cell is the minimum travel distance over every reachable frontier cell
    segs = smoothed_frontiers(ctx.grid, RES)
    all_d = min(float(np.min(ctx.distance[s.cells[:, 0], s.cells[:, 1]])) for s in segs)
    assert ctx.distance[choice.cell] == all_d


def test_largest_closest_and_largest_random_use_the_largest_segment():
    ctx = _ctx()
    lc = make_strategy("largest_closest").choose(ctx)
    assert lc is not None and lc.segment is not None
    assert lc.segment.size == max(s.size for s in lc.segments)
    assert lc.cell[1] > 140  # the open east end
    cells = lc.segment.cells
    assert ctx.distance[lc.cell] == np.min(ctx.distance[cells[:, 0], cells[:, 1]])
    picks = {make_strategy("largest_random").choose(_ctx(seed)).cell for seed in range(5)}
    assert len(picks) > 1
    assert all(c[1] > 140 for c in picks)


def test_largest_random_raw_picks_a_raw_frontier_cell():
    ctx = _ctx(3)
    choice = make_strategy("largest_random_raw").choose(ctx)
    assert choice is not None
    raw = raw_frontiers(ctx.grid, RES)
    largest = max(raw, key=lambda s: s.size)
    assert choice.cell in {tuple(c) for c in largest.cells}


def test_explore_lite_cost_and_centroid():
    ctx = _ctx()
    el = make_strategy("explore_lite")
    segs = el.frontiers(ctx)
    rr, rc = ctx.robot_cell
    costs = [3.0 * float(np.min(np.hypot(s.cells[:, 0] - rr, s.cells[:, 1] - rc))) * RES * RES - s.size * RES for s in segs]
    best = segs[int(np.argmin(costs))]
    choice = el.choose(ctx)
    assert choice is not None and choice.segment is not None
    assert np.array_equal(choice.segment.cells, best.cells)
    cr, cc = best.centroid()
    assert np.hypot(choice.cell[0] - cr, choice.cell[1] - cc) * RES <= 1.0


def test_gain_rate_prefers_the_big_unknown_over_the_near_pocket():
    ctx = _ctx()
    choice = make_strategy("gain_rate").choose(ctx)
    assert choice is not None and choice.segment is not None and choice.segment.cells[:, 1].min() > 140
    # The goal may be a viewpoint standing back from the frontier, never more than SETBACK from it.
    assert choice.cell[1] >= choice.segment.cells[:, 1].min() - SETBACK / RES - 1
    assert np.isfinite(ctx.distance[choice.cell]) and ctx.grid[choice.cell] == FREE


def test_gain_rate_viewpoint_sees_more_than_the_frontier_edge_in_a_corridor_end():
    """In a 2 m corridor ending in the unknown, a cell on the frontier edge sees the unknown fan past the end;
    the viewpoint gain_rate picks sees at least as much as the best frontier cell, at less travel."""
    ctx = _ctx()
    strat = make_strategy("gain_rate")
    choice = strat.choose(ctx)
    assert choice is not None
    edge = choice.segment.cells
    gain_edge = visible_unknown(ctx.grid, RES, edge, VIEW_RADIUS, VIEW_RAYS).max()
    gain_goal = visible_unknown(ctx.grid, RES, np.array([choice.cell]), VIEW_RADIUS, VIEW_RAYS)[0]
    assert gain_goal >= 0.5 * gain_edge and gain_goal >= MIN_GAIN
    assert ctx.distance[choice.cell] <= ctx.distance[edge[:, 0], edge[:, 1]].min() + 1e-6


def test_gain_rate_goal_is_spent_once_nothing_unknown_is_in_view():
    g, robot = _corridor_world()
    strat = make_strategy("gain_rate")
    assert not strat.goal_spent(g, RES, (60, 140))  # the open east end is 0.5 m away
    walled = g.copy()
    walled[40:80, 149] = OCCUPIED  # close the east end and the pocket: nothing left to see from there
    walled[25, 30:61] = OCCUPIED
    assert strat.goal_spent(walled, RES, (60, 140))


def test_explorer_blacklists_a_goal_without_progress_and_chooses_again():
    g, robot = _corridor_world()
    grid = OccupancyGrid.from_map_data(MapData(g, RES, (0.0, 0.0, 0.0)))
    dist = travel_distance(g, RES, robot)
    pose = Pose2((robot[1] + 0.5) * RES, (robot[0] + 0.5) * RES, 0.0)
    ex = Explorer(make_strategy("nearest"), progress_timeout=30.0)
    first = ex.update(grid, pose, dist, 0.0)
    assert first.goal is not None and first.changed
    same = ex.update(grid, pose, dist, 20.0)
    assert same.goal == first.goal and not same.changed
    later = ex.update(grid, pose, dist, 31.0)  # no progress for > 30 s
    assert later.goal is not None and later.goal.distance_to(first.goal) > 0.5
    assert len(ex.blacklist) == 1
    # within one robot diameter of the goal: a new goal
    at_goal = Pose2(later.goal.x - 0.1, later.goal.y, 0.0)
    nxt = ex.update(grid, at_goal, dist, 32.0)
    assert nxt.goal is None or nxt.goal.distance_to(later.goal) > 0.2


def test_frontier_travel_takes_the_pocket_on_the_way_to_the_corridors_open_end():
    """The 1.5 m pocket 2 m away and the 2 m-wide open end 7 m down the corridor: the shortest tour through both
    takes the pocket first (going east first means coming all the way back); the goal is the pocket's centroid
    moved onto a reachable cell within 1 m, as explore_lite's."""
    ctx = _ctx()
    ft = make_strategy("frontier_travel")
    segs = ft.frontiers(ctx)
    assert len(segs) == 2
    choice = ft.choose(ctx)
    assert choice is not None and choice.segment is not None
    assert choice.cell[1] < 60  # the pocket, not the east end
    assert [c for _, c in ft.tour][1] > 140  # then the east end
    cr, cc = choice.segment.centroid()
    assert np.hypot(choice.cell[0] - cr, choice.cell[1] - cc) * RES <= 1.0
    assert np.isfinite(ctx.distance[choice.cell])


def test_frontier_travel_visits_frontiers_smaller_than_explore_lites_minimum_once_no_other_is_left():
    """A closed room with one 0.9 m gap onto unknown, of which 0.5 m is frontier the robot can reach (its
    footprint keeps it 0.19 m off each side): explore_lite (min 0.75 m) says done, frontier_travel goes."""
    g = np.full((60, 60), OCCUPIED, dtype=np.int8)
    g[10:50, 10:50] = FREE
    g[10:50, 9] = g[10:50, 50] = g[9, 9:51] = g[50, 9:51] = OCCUPIED
    g[16:34, 5:10] = UNKNOWN  # an 18-cell gap in the west wall onto unknown
    robot = (30, 40)
    dist = travel_distance(g, RES, robot)
    ctx = GoalContext(g, RES, (30.0, 40.0), 0.0, dist, np.zeros(g.shape, bool), np.random.default_rng(0))
    assert make_strategy("explore_lite").choose(ctx) is None
    choice = make_strategy("frontier_travel").choose(ctx)
    assert choice is not None
    assert 16 <= choice.cell[0] < 34 and choice.cell[1] <= 14  # at the gap


def test_frontier_travel_leaves_a_goal_whose_frontier_was_seen_before_its_next_replan():
    """The pocket's goal is spent once the pocket's unknown strip is seen (walled off): the explorer chooses the
    east end at its next update, 1 s later, not at frontier_travel's next replan (3 s)."""
    g, robot = _corridor_world()
    ft = make_strategy("frontier_travel")
    ex = Explorer(ft)
    grid = OccupancyGrid.from_map_data(MapData(g, RES, (0.0, 0.0, 0.0)))
    dist = travel_distance(g, RES, robot)
    pose = Pose2((robot[1] + 0.5) * RES, (robot[0] + 0.5) * RES, 0.0)
    first = ex.update(grid, pose, dist, 0.0)
    assert first.choice is not None and first.choice.cell[1] < 60  # the pocket first (the test above)
    assert not ft.goal_spent(g, RES, first.choice.cell)  # the pocket's unknown strip borders its goal
    seen = g.copy()
    seen[21:25, 30:60] = OCCUPIED  # the lidar saw the strip: a wall
    assert ft.goal_spent(seen, RES, first.choice.cell)
    grid = OccupancyGrid.from_map_data(MapData(seen, RES, (0.0, 0.0, 0.0)))
    nxt = ex.update(grid, pose, dist, 1.0)
    assert nxt.changed and nxt.choice is not None and nxt.choice.cell[1] > 140  # the east end, now
    # A frontier cell 1.5 m off the goal keeps it (the frontier is the one driven to); one farther does not.
    r, c = first.choice.cell
    near, far = seen.copy(), seen.copy()
    near[r + 29, c] = far[r + 31, c] = UNKNOWN  # in the corridor, FREE all round: 1.45 / 1.55 m off
    assert not ft.goal_spent(near, RES, (r, c)) and ft.goal_spent(far, RES, (r, c))


def test_explore_lites_segments_are_the_labelled_cells_in_row_major_order_label_by_label() -> None:
    import cv2
    from homing.mapping.strategies import _bordering

    ctx = _ctx()
    segs = make_strategy("explore_lite").frontiers(ctx, 0.0)
    cand = _bordering(ctx.grid, (ctx.grid == FREE) & np.isfinite(ctx.distance))
    _, labels = cv2.connectedComponents(cand.astype(np.uint8), connectivity=8)
    rows, cols = np.nonzero(labels)  # as first written: the 2-D nonzero of the labels
    want = [np.column_stack([rows[labels[rows, cols] == k], cols[labels[rows, cols] == k]])
            for k in range(1, int(labels.max()) + 1)]
    assert len(segs) == len(want) >= 2
    for seg, cells in zip(segs, want, strict=True):
        assert seg.cells.dtype == np.int64 and np.array_equal(seg.cells, cells)


def _corridor_past_a_door(crumb_cols: tuple[int, int]) -> tuple[GoalContext, np.ndarray]:
    """A 2 m-wide corridor 12 m long along x, the robot at its west end behind a door (given as a mask across the
    corridor, so nothing east of it is in the robot's room); a 1.4 m-wide pocket in the north wall near the east
    end (a frontier of explore_lite's size, shorter than LONG_FRONTIER) and a 0.9 m-wide one in the south wall
    at ``crumb_cols`` (its reachable frontier shorter than explore_lite's minimum: a crumb)."""
    g = np.full((120, 260), UNKNOWN, dtype=np.int8)
    g[40:80, 5:250] = FREE
    g[40, 5:250] = g[79, 5:250] = OCCUPIED
    g[40:80, 5] = g[40:80, 249] = OCCUPIED
    for rows, cols, wall_rows in ((slice(79, 100), (214, 242), (80, 100)), (slice(20, 41), crumb_cols, (20, 40))):
        g[rows, cols[0]:cols[1]] = FREE  # the pocket, unknown beyond its far end
        g[wall_rows[0]:wall_rows[1], cols[0] - 1] = g[wall_rows[0]:wall_rows[1], cols[1]] = OCCUPIED
    g[:40][g[:40] == UNKNOWN] = OCCUPIED  # solid south of the corridor but for the crumb's strip …
    g[17:20, crumb_cols[0]:crumb_cols[1]] = UNKNOWN
    g[100:][g[100:] == UNKNOWN] = OCCUPIED  # … and north of it but for the pocket's
    g[100:103, 214:242] = UNKNOWN
    g[80:100, :214][g[80:100, :214] == UNKNOWN] = OCCUPIED
    g[80:100, 242:][g[80:100, 242:] == UNKNOWN] = OCCUPIED
    robot = (60, 12)
    doors = np.zeros(g.shape, bool)
    doors[41:79, 20:24] = True
    dist = travel_distance(g, RES, robot)
    ctx = GoalContext(g, RES, (float(robot[0]), float(robot[1])), 0.0, dist, np.zeros(g.shape, bool),
                      np.random.default_rng(0))
    return ctx, doors


def test_frontier_travel_looks_at_a_crumb_it_passes_before_the_frontier_beyond_it():
    """Past the door, with no long frontier left: the crumb 3 m down the corridor is toured with the pocket 11 m
    down it, and first (it is on the way); explore_lite's minimum alone would send the robot past it to the
    pocket and back for it once nothing else was left."""
    ft = make_strategy("frontier_travel")
    ctx, doors = _corridor_past_a_door((60, 78))
    sizes = sorted(seg.size * RES for seg in ft.frontiers(ctx, ft.crumb_size))
    assert len(sizes) == 2 and ft.crumb_size <= sizes[0] < ft.min_frontier_size <= sizes[1] < ft.long_frontier
    goals = ft.goals(ctx, doors)
    assert sorted(c[1] < 100 for _, c in goals) == [False, True]  # the crumb (west) and the pocket (east)
    ft.doors = lambda grid, resolution: doors  # choose() with the same door as goals() above
    choice = ft.choose(ctx)
    assert choice is not None and choice.cell[1] < 100 and [c for _, c in ft.tour][1] > 200


def test_frontier_travel_leaves_a_crumb_beyond_the_nearest_frontier_for_later():
    """The same corridor with the crumb past the pocket (nearer the east end): it is no nearer than the pocket,
    so it waits for the last tier, as before."""
    ft = make_strategy("frontier_travel")
    ctx, doors = _corridor_past_a_door((228, 246))
    goals = ft.goals(ctx, doors)
    assert len(goals) == 1 and goals[0][0].size * RES >= ft.min_frontier_size
