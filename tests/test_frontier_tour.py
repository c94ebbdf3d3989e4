"""The frontier tour: shortest orders, path distances along corridors, doors found where the walls say, and the
default strategy's order on constructed buildings whose answer is known from geometry."""

from __future__ import annotations

import itertools

import numpy as np
import pytest
from homing.mapping import frontier_tour
from homing.mapping.frontier_tour import (
    COARSE,
    DOOR_REACH,
    DOOR_TOLL,
    EXACT_GOALS,
    HYSTERESIS_MIN,
    door_cells,
    keep_first,
    open_tour,
    path_distances,
    tour_length,
)
from homing.mapping.strategies import GoalContext, make_strategy, robot_room

from homing.map_server import FREE, OCCUPIED, UNKNOWN
from tests.mapping_helpers import travel_distance

RES = 0.05  # [m]


def _euclid(points: np.ndarray, robot: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    start = np.hypot(*(points - robot).T)
    between = np.hypot(points[:, None, 0] - points[None, :, 0], points[:, None, 1] - points[None, :, 1])
    return start, between


@pytest.mark.parametrize("seed", range(12))
def test_tour_is_the_shortest_of_all_orders(seed):
    """Up to EXACT_GOALS goals (Held-Karp), with and without a forced first goal: no permutation is shorter."""
    rng = np.random.default_rng(seed)
    k = int(rng.integers(1, 8))
    start, between = _euclid(rng.uniform(0, 20, (k, 2)), rng.uniform(0, 20, 2))
    best = min(tour_length(list(p), start, between) for p in itertools.permutations(range(k)))
    assert tour_length(open_tour(start, between), start, between) == pytest.approx(best)
    first = int(rng.integers(k))
    forced = open_tour(start, between, first=first)
    assert forced[0] == first and sorted(forced) == list(range(k))
    best_forced = min(tour_length([first, *p], start, between)
                      for p in itertools.permutations([i for i in range(k) if i != first]))
    assert tour_length(forced, start, between) == pytest.approx(best_forced)


def test_local_search_tour_of_many_goals_along_a_line_is_in_line_order():
    """More goals than the exact solver takes, on a line from the robot (shuffled): the shortest tour walks them
    in order, its length the farthest goal's distance."""
    k = 3 * EXACT_GOALS
    xs = np.random.default_rng(1).permutation(np.arange(1, k + 1, dtype=float))
    pts = np.column_stack([xs, np.zeros(k)])
    start, between = _euclid(pts, np.zeros(2))
    order = open_tour(start, between)
    assert list(xs[order]) == sorted(xs)
    assert tour_length(order, start, between) == pytest.approx(float(k))


def test_path_distances_go_round_the_corner_of_an_l_shaped_corridor():
    """Two ends of an L-shaped corridor: their path distance is the two legs along its middle, not the straight
    line, to within the coarse graph's cells."""
    passable = np.zeros((200, 200), bool)
    passable[10:20, 10:190] = True  # 9 m east-west leg
    passable[10:190, 180:190] = True  # 9 m north-south leg
    pts = np.array([[15, 12], [188, 185]])
    d = path_distances(passable, RES, pts)
    legs = (185 - 12) * RES + (188 - 15) * RES
    assert d[0, 1] == pytest.approx(legs, abs=4 * COARSE)
    assert d[0, 1] > 1.3 * np.hypot(173, 173) * RES  # not the diagonal
    passable[96:104, 180:190] = False  # a wall across, with the footprint's margin either side
    assert np.isinf(path_distances(passable, RES, pts)[0, 1])


def _corridor() -> np.ndarray:
    """A 2 m-wide corridor (rows 20-59, cols 10-479) walled north, south and west, its east end open onto
    unknown."""
    g = np.full((160, 520), UNKNOWN, np.int8)
    g[20:60, 10:480] = FREE
    g[19, 9:480] = g[60, 9:480] = OCCUPIED
    g[19:61, 9] = OCCUPIED
    return g


def _rooms_off_a_corridor(doors: tuple[int, ...] = (90, 190, 290, 390)) -> np.ndarray:
    """A 2 m-wide corridor (rows 20-59, cols 10-479) walled south and west, its east end open onto unknown; a
    1.2 m door in its north wall at each of ``doors`` (cols), through which the lidar has seen a 1.5 m × 0.7 m
    patch of the room beyond (the rest of each room unknown)."""
    g = _corridor()
    for c in doors:
        g[60, c - 12 : c + 12] = FREE
        g[61:75, c - 15 : c + 15] = FREE
    return g


def test_door_cells_are_the_doorways_not_the_corridor_nor_its_corners():
    g = _rooms_off_a_corridor()
    doors = door_cells(g, RES)
    rows, cols = np.nonzero(doors)
    assert len(rows)
    reach = int(round(DOOR_REACH / RES))
    for c in (90, 190, 290, 390):  # every doorway is a door from jamb to jamb
        assert doors[60, c - 8 : c + 8].all()
    near_a_door = np.zeros(len(cols), bool)
    for c in (90, 190, 290, 390):
        near_a_door |= np.hypot(rows - 60, np.maximum(np.abs(cols - c) - 12, 0)) <= reach + 1
    assert near_a_door.all()  # none elsewhere in the corridor, its corners or the seen patches


def test_a_door_passed_costs_the_toll():
    """Two rooms joined by one door: the path distance across it grows by the toll, a path within a room not."""
    g = np.full((100, 200), OCCUPIED, np.int8)
    g[10:90, 10:95] = FREE
    g[10:90, 100:190] = FREE
    g[40:60, 95:100] = FREE  # a 1 m door
    passable = g == FREE
    pts = np.array([[50, 50], [50, 150], [20, 20]])
    plain = path_distances(passable, RES, pts)
    tolled = path_distances(passable, RES, pts, door_cells(g, RES), DOOR_TOLL)
    assert tolled[0, 1] - plain[0, 1] == pytest.approx(DOOR_TOLL)
    assert tolled[0, 2] == pytest.approx(plain[0, 2])


def _ctx(g: np.ndarray, robot: tuple[int, int], current: tuple[int, int] | None = None) -> GoalContext:
    dist = travel_distance(g, RES, robot)
    return GoalContext(g, RES, (float(robot[0]), float(robot[1])), 0.0, dist, np.zeros(g.shape, bool),
                       np.random.default_rng(0), current_goal=current)


def test_default_strategy_visits_the_rooms_off_a_corridor_in_corridor_order():
    """From the corridor's west end: each room on the way, then the open east end — not the east end first and
    all the way back (the tour is bounded by the corridor's length plus a detour into each doorway)."""
    g = _rooms_off_a_corridor()
    robot = (40, 20)
    ft = make_strategy("frontier_travel")
    choice = ft.choose(_ctx(g, robot))
    assert choice is not None
    cols = [c for _, c in ft.tour]
    assert len(cols) == 5
    assert cols == sorted(cols)  # corridor order
    assert all(abs(c - d) <= 15 and r > 60 for (r, c), d in zip(ft.tour[:4], (90, 190, 290, 390), strict=True))
    assert ft.tour[-1][1] >= 470  # the east end last
    assert choice.cell == ft.tour[0]
    # Its length on the map (no toll) against the geometry: along the corridor to its east end, and up to each
    # seen patch and back (rows 40 -> the goal).
    pts = np.array([robot, *ft.tour])
    d = path_distances(g == FREE, RES, pts)
    length = sum(d[i, i + 1] for i in range(len(pts) - 1))
    bound = (ft.tour[-1][1] - robot[1]) * RES + sum(2 * (r - robot[0]) * RES for r, _ in ft.tour[:4])
    assert length <= bound + len(pts) * 2 * COARSE
    assert length < 2 * (ft.tour[-1][1] - robot[1]) * RES  # what going to the east end first would cost at least


def _room_beside_a_corridor() -> np.ndarray:
    """A 6 m × 4 m room (rows 20-99, cols 40-159) with two 1.4 m openings onto unknown in its north wall, and a 1.2 m door in its west wall onto a north-south corridor (cols 10-38) whose north end, just
    beyond the door, is open onto unknown."""
    g = np.full((140, 200), UNKNOWN, np.int8)
    g[20:100, 40:160] = FREE
    g[19, 39:161] = g[100, 39:161] = OCCUPIED
    g[19:101, 39] = g[19:101, 160] = OCCUPIED
    g[100, 95:123] = UNKNOWN  # two 1.4 m openings in the north wall, 1.55 m apart
    g[100, 126:154] = UNKNOWN
    g[48:72, 39] = FREE  # the door
    g[20:90, 10:39] = FREE  # the corridor, open to the north at row 90
    g[19, 9:40] = OCCUPIED
    g[19:90, 9] = OCCUPIED
    return g


def test_a_robot_in_a_room_finishes_the_room_before_leaving_it():
    """The corridor's open end is nearer than either of the room's openings, so the nearest frontier is outside;
    leaving first means passing the door twice (out, and back for the room), and the tour, which counts the
    door's toll, clears the room first. With a the way out to the corridor's end, b to the nearer opening and c
    between the openings, leaving first costs a + T - b - c more: 2.8 + T - 3.05 - 1.55 m."""
    g = _room_beside_a_corridor()
    robot = (60, 62)
    ctx = _ctx(g, robot)
    nearest = make_strategy("nearest").choose(ctx)
    assert nearest is not None and nearest.cell[1] < 39  # outside: the geometry puts the corridor nearest
    ft = make_strategy("frontier_travel", long_frontier=0.0)  # the tour alone: every frontier in one tier
    choice = ft.choose(ctx)
    assert choice is not None and len(ft.tour) == 3
    assert all(c > 40 for _, c in ft.tour[:2])  # both room openings first ...
    assert ft.tour[2][1] < 39  # ... then out through the door
    assert choice.cell == ft.tour[0]
    # The default does the same by its tiers: the corridor's end (1.45 m, shorter than LONG_FRONTIER) lies
    # beyond the door, so it waits until the room the robot stands in is done.
    ft = make_strategy("frontier_travel")
    again = ft.choose(ctx)
    assert again is not None and again.cell == choice.cell
    assert len(ft.tour) == 2 and all(c > 40 for _, c in ft.tour)


def _rooms_seen_through_their_doors(doors: tuple[int, ...] = (90, 190, 290, 390)) -> np.ndarray:
    """The corridor of :func:`_rooms_off_a_corridor`, through each of whose 1.2 m doors the lidar has seen a
    1.3 m × 0.7 m patch of the room beyond between the room's seen side walls: a 1 m frontier per room (a
    hospital's row of rooms, looked into from the corridor), and the corridor's 2 m open east end."""
    g = _corridor()
    for c in doors:
        g[60, c - 12 : c + 12] = FREE
        g[61:75, c - 13 : c + 13] = FREE
        g[61:75, c - 14] = g[61:75, c + 13] = OCCUPIED
    return g


def test_from_a_corridor_the_rooms_seen_through_their_doors_wait_for_the_long_frontiers():
    """Rooms whose doors the robot has looked through show a short frontier each (shorter than LONG_FRONTIER,
    longer than explore_lite's minimum); the corridor's open end is long. The default sweeps the corridor
    first and comes back for the rooms once no long frontier is left; the tour alone visits each room on the
    way (as in :func:`test_default_strategy_visits_the_rooms_off_a_corridor_in_corridor_order`)."""
    g = _rooms_seen_through_their_doors()
    robot = (40, 20)
    ft = make_strategy("frontier_travel")
    choice = ft.choose(_ctx(g, robot))
    assert choice is not None and choice.cell[1] >= 470 and len(ft.tour) == 1  # the east end, alone
    tour_only = make_strategy("frontier_travel", long_frontier=0.0)
    first = tour_only.choose(_ctx(g, robot))
    assert first is not None and abs(first.cell[1] - 90) <= 15 and len(tour_only.tour) == 5
    g[20:60, 470:480] = OCCUPIED  # the east end seen closed: only the rooms are left, and they are toured
    choice = ft.choose(_ctx(g, robot))
    assert choice is not None and len(ft.tour) == 4 and abs(choice.cell[1] - 90) <= 15


def test_the_robots_room_ends_at_its_doors():
    """Two rooms joined by a 1 m door: from inside one, the robot's room is that room (less the door's cells);
    standing in the door, it is both."""
    g = np.full((100, 200), OCCUPIED, np.int8)
    g[10:90, 10:95] = FREE
    g[10:90, 100:190] = FREE
    g[40:60, 95:100] = FREE
    doors = door_cells(g, RES)
    inside = robot_room(_ctx(g, (50, 40)))
    assert inside[20:80, 20:80].all() and not inside[:, 100:].any() and not (inside & doors).any()
    in_door = robot_room(_ctx(g, (50, 97)))
    assert in_door[20:80, 20:80].all() and in_door[20:80, 120:180].all()


def test_the_current_goal_is_kept_unless_another_tour_is_clearly_shorter():
    """A corridor open at both ends, the robot a little west of its middle: with no goal it heads west (the
    shorter tour); driving east already, it keeps going east, the tours differing by less than the hysteresis."""
    g = np.full((60, 420), UNKNOWN, np.int8)
    g[10:50, 10:410] = FREE
    g[9, 10:410] = g[50, 10:410] = OCCUPIED
    robot = (30, 205 - int(0.25 * HYSTERESIS_MIN / RES))
    ft = make_strategy("frontier_travel")
    west = ft.choose(_ctx(g, robot))
    assert west is not None and west.cell[1] < 50
    east = ft.tour[1]
    kept = make_strategy("frontier_travel").choose(_ctx(g, robot, current=east))
    assert kept is not None and kept.cell[1] > 370
    # Far enough west, the east goal is dropped: the tour beginning there is longer by more than the hysteresis.
    robot = (30, 60)
    switched = make_strategy("frontier_travel").choose(_ctx(g, robot, current=east))
    assert switched is not None and switched.cell[1] < 50


def test_keep_first_holds_a_goal_within_the_hysteresis_and_drops_one_beyond():
    start = np.array([1.0, 1.5])
    between = np.array([[0.0, 2.5], [2.5, 0.0]])
    assert keep_first(start, between, [0, 1], current=1) == [1, 0]  # 4.0 against 3.5: within HYSTERESIS_MIN
    start = np.array([1.0, 10.0])
    between = np.array([[0.0, 11.0], [11.0, 0.0]])
    assert keep_first(start, between, [0, 1], current=1) == [0, 1]  # 21 against 12


def test_plan_orders_goals_beyond_the_cap_after_the_rest(monkeypatch):
    """More goals than MAX_GOALS: the nearest are toured, the rest follow nearest first."""
    monkeypatch.setattr(frontier_tour, "MAX_GOALS", 3)
    g = np.full((40, 400), FREE, np.int8)
    goals = np.array([[20, c] for c in (390, 50, 300, 100, 200)])
    start = (goals[:, 1] - 10) * RES
    order = frontier_tour.plan((20, 10), g, RES, g == FREE, goals, start)
    assert [int(goals[i, 1]) for i in order] == [50, 100, 200, 300, 390]


def test_the_first_goal_weighs_the_frontier_it_opens():
    """In an open hall, a 0.8 m crumb 1 m west of the robot and a 6 m frontier 3 m east: by distance alone the crumb
    comes first (1 + 4 m against 3 + 4 m); counting FIRST_GAIN × length off the way to the first goal, the long
    frontier does (1 - 0.8 + 4 against 3 - 6 + 4 m), as explore_lite's gain would have it."""
    g = np.full((100, 200), FREE, np.int8)
    goals = np.array([[50, 80], [50, 160]])
    start = np.array([1.0, 3.0])
    assert frontier_tour.plan((50, 100), g, RES, g == FREE, goals, start) == [0, 1]
    assert frontier_tour.plan((50, 100), g, RES, g == FREE, goals, start, lengths=np.array([0.8, 6.0])) == [1, 0]


def test_doors_kept_up_to_date_round_what_changed_are_the_doors_of_the_whole_map():
    # A generated 2000 m² floor mapped window by window, as a robot maps it (with a speck of noise now and then):
    # after every window the doors kept up to date round the change are those found over the whole grid.
    from homing.sim import load_world

    truth = load_world("floor:1").map
    res = truth.resolution
    rng = np.random.default_rng(0)
    grid = np.full(truth.grid.shape, UNKNOWN, np.int8)
    doors = frontier_tour.Doors()
    h, w = grid.shape
    found = 0
    for k in range(14):
        r, c = int(rng.integers(0, h - 60)), int(rng.integers(0, w - 60))
        size = int(rng.integers(40, 140))
        grid = grid.copy()
        grid[r:r + size, c:c + size] = truth.grid[r:r + size, c:c + size]
        if k % 4 == 3:  # a speck the lidar drew in the open, or one it clears
            grid[r + 5, c + 5] = OCCUPIED if grid[r + 5, c + 5] == FREE else grid[r + 5, c + 5]
        kept = doors(grid, res)
        whole = frontier_tour.door_cells(grid, res)
        assert np.array_equal(kept, whole), f"window {k}: {int((kept != whole).sum())} cells differ"
        found = max(found, int(whole.sum()))
    assert found > 0  # the office's doors were found: the comparison was not of empty maps
