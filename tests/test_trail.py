"""The robot's trail (homing.navigation.trail): where its centre has been it fits, so a door the map redrew a cell
narrower once the robot was through still lets it plan back and explore beyond — but never next to an obstacle."""

from __future__ import annotations

import math
from types import SimpleNamespace

import numpy as np
import py_trees
import pytest
from homing.behaviours.explore import NoFrontierLeft
from homing.mapping.explorer import RETRY_ROUNDS, Explorer
from homing.mapping.grid import OccupancyGrid
from homing.mapping.reachable import frontier_report
from homing.mapping.strategies import make_strategy
from homing.navigation.costmap import INSCRIBED, MAX_NON_OBSTACLE, Costmap
from homing.navigation.dwb import DWB
from homing.navigation.navigator import Navigator, NavStatus
from homing.navigation.planner import NoPathFound, make_planner
from homing.navigation.trail import Trail
from homing.robot import BatteryState, Bumpers, DockIR, Observation, Odometry, Pose2, Twist2
from homing.robot.turtlebot import BASE_RADIUS, FOOTPRINT_RADIUS
from py_trees.common import Access, Status

from homing.map_server import FREE, OCCUPIED, UNKNOWN, MapData
from tests.navworld import point_rect_distance, rasterise, scan_of, unicycle

RES = 0.05  # [m/cell]
DOOR_ROW = 46  # the passage's first free row (y 2.30 m)
WALL = slice(60, 65)  # the wall's columns (x 3.00..3.25 m), 0.25 m thick as the generator's
INSIDE = Pose2(1.5, 2.525, 0.0)  # [m] in the room, level with the passage's middle cells
OUTSIDE = Pose2(4.5, 2.525, 0.0)  # [m] in the hall beyond it


def _floor(passage_cells: int) -> np.ndarray:
    """5 m × 8 m at 5 cm: a room (x 0.5..3 m) and, through a 0.25 m wall, a hall (x 3.25..5.5 m) that opens on
    unknown space (x ≥ 5.5 m); the passage through the wall drawn ``passage_cells`` free cells wide (rows from
    ``DOOR_ROW``), as a lidar map draws the generator's 0.5 m door (10 cells) one or two cells narrower."""
    g = np.full((100, 160), UNKNOWN, np.int8)
    g[9:91, 9:111] = OCCUPIED
    g[10:90, 10:110] = FREE
    g[10:90, WALL] = OCCUPIED
    g[DOOR_ROW : DOOR_ROW + passage_cells, WALL] = FREE
    g[10:90, 110] = FREE  # the hall's far side: mapped free up to the unknown (a frontier)
    g[9, 110] = g[90, 110] = OCCUPIED
    return g


def _costmap(g: np.ndarray) -> Costmap:
    cm = Costmap()
    cm.set_static(g, RES, (0.0, 0.0))
    return cm


def _drive(cm: Costmap, start: Pose2, end: Pose2, step: float = 0.1) -> None:
    """The robot's localised centre from ``start`` to ``end``, a pose every ``step`` [m] (as the navigator marks it)."""
    n = int(np.ceil(start.distance_to(end) / step))
    for t in np.linspace(0.0, 1.0, n + 1):
        cm.mark_trail(Pose2(start.x + t * (end.x - start.x), start.y + t * (end.y - start.y), 0.0))


def _samples(path: np.ndarray, step: float = 0.5 * RES) -> np.ndarray:
    """(M, 2) [m]: points every ``step`` along a path's segments (a smoothed path keeps only its corners)."""
    out = [path[:1]]
    for a, b in zip(path[:-1], path[1:], strict=True):
        n = max(1, int(np.ceil(np.hypot(*(b - a)) / step)))
        out.append(a + np.linspace(0.0, 1.0, n + 1)[1:, None] * (b - a))
    return np.vstack(out)


def _grid(g: np.ndarray) -> OccupancyGrid:
    return OccupancyGrid.from_map_data(MapData(g, RES, (0.0, 0.0, 0.0)))


def _walked_in() -> tuple[np.ndarray, OccupancyGrid, Costmap]:
    """The passage drawn 8 cells wide, and a costmap whose robot came in through it from the hall: (the grid's
    array, the grid, the costmap)."""
    g = _floor(8)
    cm = _costmap(g)
    _drive(cm, OUTSIDE, INSIDE)
    return g, _grid(g), cm


def test_a_passage_drawn_8_cells_has_middle_cells_within_the_padding_not_within_the_footprint() -> None:
    cm = _costmap(_floor(8))
    door = cm.clearance[DOOR_ROW : DOOR_ROW + 8, 62]
    # The premise: no cell of it clears the inscribed radius, the middle two clear the bare footprint.
    assert (door <= cm.inscribed_radius).all()
    assert (door > FOOTPRINT_RADIUS).sum() == 2


@pytest.mark.parametrize("planner", ["dijkstra", "fmm", "astar"])
def test_the_planner_goes_back_out_along_the_trail_and_not_without_it(planner: str) -> None:
    g = _floor(8)
    bare = _costmap(g)
    with pytest.raises(NoPathFound):
        make_planner(planner).plan(bare, INSIDE, OUTSIDE)
    cm = _costmap(g)
    _drive(cm, OUTSIDE, INSIDE)  # it came in through the passage (the map drew it wider then)
    path = make_planner(planner).plan(cm, INSIDE, OUTSIDE)
    assert np.hypot(*(path[-1] - [OUTSIDE.x, OUTSIDE.y])) < 0.1
    # Through the wall it goes on the trail's cells, the only ones of the passage the costmap lifted.
    rc = cm.world_to_cell(_samples(path))
    in_wall = (rc[:, 1] >= WALL.start) & (rc[:, 1] < WALL.stop)
    assert in_wall.any()
    assert (cm.cost[rc[in_wall, 0], rc[in_wall, 1]] == MAX_NON_OBSTACLE).all()
    lifted = cm.cost == MAX_NON_OBSTACLE
    assert cm.trail.mask(cm.origin, RES, cm.shape)[lifted].all()


def test_the_explorer_reaches_the_frontier_beyond_the_passage_with_the_trail_and_calls_it_narrow_without() -> None:
    _, grid, cm = _walked_in()
    without = frontier_report(grid, (INSIDE.x, INSIDE.y))
    assert not without.reachable and without.narrow
    trail = cm.trail.mask(grid.origin, grid.resolution, grid.shape)
    report = frontier_report(grid, (INSIDE.x, INSIDE.y), trail=trail)
    assert not report.narrow
    assert [s for s in report.reachable if s.x > 5.0]  # the hall's open side at x 5.5 m


def test_a_trail_through_a_passage_narrower_than_the_footprint_lifts_nothing() -> None:
    # Drawn 6 cells: its middle cells are 0.15 m from a jamb's centre, within the footprint (0.19 m).
    g = _floor(6)
    cm = _costmap(g)
    _drive(cm, OUTSIDE, Pose2(INSIDE.x, 2.475, 0.0))
    assert len(cm.trail) > 0
    assert not (cm.cost[:, WALL] == MAX_NON_OBSTACLE).any()
    with pytest.raises(NoPathFound):
        make_planner("dijkstra").plan(cm, Pose2(INSIDE.x, 2.475, 0.0), OUTSIDE)
    trail = cm.trail.mask(cm.origin, RES, cm.shape)
    report = frontier_report(_grid(g), (INSIDE.x, 2.475), trail=trail)
    assert not report.reachable and report.narrow


def test_an_obstacle_put_on_the_trail_later_takes_its_cells_back() -> None:
    g = _floor(8)
    cm = _costmap(g)
    _drive(cm, OUTSIDE, INSIDE)
    assert cm.cost[50, 62] == MAX_NON_OBSTACLE
    # A parcel put down in the passage since, mapped a cell off the trail: the trail's cells beside it are within
    # the footprint of it, and stop being lifted.
    g2 = g.copy()
    g2[51, 62] = OCCUPIED
    cm.set_static(g2, RES, (0.0, 0.0))
    assert cm.cost[50, 62] >= INSCRIBED
    with pytest.raises(NoPathFound):
        make_planner("dijkstra").plan(cm, INSIDE, OUTSIDE)
    # A bumper mark beside the trail (what the lidar cannot see) keeps its padding too.
    cm.set_static(g, RES, (0.0, 0.0))
    assert cm.cost[50, 62] == MAX_NON_OBSTACLE
    cm.bumps.add(np.array([[3.125, 2.35]]), 0.0)  # a cell beside the passage's lower jamb
    cm.set_static(g2, RES, (0.0, 0.0))
    cm.set_static(g, RES, (0.0, 0.0))
    assert cm.cost[50, 62] == INSCRIBED


def test_the_trail_stays_in_place_when_the_grid_grows() -> None:
    g = _floor(8)
    cm = _costmap(g)
    _drive(cm, OUTSIDE, INSIDE)
    before = cm.cost == MAX_NON_OBSTACLE
    grown = np.pad(g, ((7, 3), (11, 2)), constant_values=UNKNOWN)  # the origin moves 11 cells left, 7 down
    cm.set_static(grown, RES, (-11 * RES, -7 * RES))
    after = cm.cost == MAX_NON_OBSTACLE
    assert before.any()
    np.testing.assert_array_equal(after[7 : 7 + g.shape[0], 11 : 11 + g.shape[1]], before)
    assert after.sum() == before.sum()


def test_the_controller_drives_into_the_passage_along_the_trail() -> None:
    g = _floor(8)
    path = np.array([[2.6, 2.525], [3.6, 2.525]])  # along the trail, through the wall (x 3.00..3.25 m)
    pose = Pose2(2.75, 2.525, 0.0)  # facing the passage, 0.25 m before it
    ends = []
    for trail in (False, True):
        cm = _costmap(g)
        if trail:
            _drive(cm, OUTSIDE, INSIDE)
        dwb = DWB()
        try:
            dwb.compute(pose, Twist2(0.2, 0.0), path, np.zeros((0, 2)), cm, 0.1)
        except Exception:  # noqa: BLE001 - without the trail every way ahead may be refused: that is the point
            ends.append(pose.x)
            continue
        ends.append(float(dwb.best[:, 0].max()))
    assert ends[1] > 3.1  # with the trail the chosen trajectory enters the passage (x 3.00..3.25 m)
    assert ends[0] < 3.0  # without it the centre stays out of the passage's padded cells


def test_a_trail_is_bounded_and_joins_only_steps_the_robot_could_drive() -> None:
    trail = Trail(RES, max_cells=200 * 200)
    trail.mark(0.0, 0.0)
    trail.mark(0.2, 0.0)  # a step: joined by a line of cells
    assert len(trail) == 5
    trail.mark(2.0, 0.0)  # a jump (relocalisation): its own cell alone
    assert len(trail) == 6
    assert trail.mark(50.0, 50.0) is None  # beyond the bound: dropped
    assert trail.cells.size <= 200 * 200
    m = trail.mask((-0.5, -0.5), RES, (20, 60))
    assert m.sum() == 6 and m[10, 10] and m[10, 14] and m[10, 50] and not m[10, 15]



# A 6 m × 4 m floor: a room (x < 3 m) and a hall (x > 3.25 m) through a true 0.5 m door (y 1.76..2.26 m) in a
# 0.25 m wall, as the floor generator's; the map draws the door 9 cells wide on the way in (y 1.80..2.25 m), 8 once
# inside (y 1.80..2.20 m). (Jambs off the cell boundaries: a scan's hits on a face on a boundary fall either side,
# and draw the door narrower still.)
WORLD = np.array([
    (0.0, 0.0, 6.0, 0.1), (0.0, 3.9, 6.0, 4.0), (0.0, 0.0, 0.1, 4.0), (5.9, 0.0, 6.0, 4.0),
    (3.0, 0.0, 3.25, 1.76), (3.0, 2.26, 3.25, 4.0),
])


def _drawn(lower_jamb: float, upper_jamb: float) -> MapData:
    walls = WORLD.copy()
    walls[4, 3], walls[5, 1] = lower_jamb, upper_jamb
    return MapData(rasterise(walls, (6.0, 4.0), RES), RES, (0.0, 0.0, 0.0))


def _go(nav: Navigator, grid: MapData, start: Pose2, goal: Pose2, t0: float = 0.0,
        seconds: float = 40.0) -> tuple[NavStatus, Pose2, float, float]:
    """Drive the navigator (exact odometry, map = odom, a scan of the true walls every tick) from time ``t0`` [s]
    to ``goal``: its status, the pose and the time it ended at, and the least clearance [m] of the robot's centre to
    a true wall on the way."""
    nav.set_goal(goal, yaw_tolerance=math.inf)
    pose, twist, least, t = start, Twist2(), math.inf, t0
    for _ in range(int(seconds / 0.1)):
        obs = Observation(stamp=t, odom=Odometry(t, pose, twist), scan=scan_of(pose, WORLD, stamp=t), image=None,
                          bumpers=Bumpers(), dock_ir=DockIR(), battery=BatteryState(16.0, 90.0))
        status, cmd, _ = nav.step(obs, grid, pose, Pose2())
        if status is not NavStatus.RUNNING:
            return status, pose, t, least
        twist = cmd
        pose = unicycle(pose, cmd.v, cmd.omega, 0.1)
        least = min(least, float(point_rect_distance(np.array([pose.x, pose.y]), WORLD).min()))
        t += 0.1
    return NavStatus.RUNNING, pose, t, least


def test_the_navigator_drives_back_out_through_the_door_the_map_redrew_narrower() -> None:
    hall, room = Pose2(4.6, 2.0, math.pi), Pose2(1.2, 2.0, 0.0)
    wide, narrow = _drawn(1.80, 2.25), _drawn(1.80, 2.20)  # 9 cells, then 8 (the jambs a cell in)
    nav = Navigator()
    status, inside, t, least = _go(nav, wide, hall, room)
    assert status is NavStatus.SUCCEEDED and least > BASE_RADIUS
    status, outside, _, least = _go(nav, narrow, inside, hall, t)
    assert status is NavStatus.SUCCEEDED, nav.feedback.message
    assert outside.x > 3.25 + FOOTPRINT_RADIUS and least > BASE_RADIUS  # out, without touching a jamb
    # Without the trail (a robot put down in the room), the same map keeps it in.
    fresh = Navigator()
    status, _, _, _ = _go(fresh, narrow, inside, hall)
    assert status is NavStatus.FAILED and isinstance(fresh.feedback.error, NoPathFound)


def test_a_place_given_up_behind_the_passage_is_measured_with_the_trail_as_one_the_robot_fits() -> None:
    # Given up on every retry round, a place beyond the passage is measured on the map from inside the room: without
    # the trail, the way out is narrower than the robot (given up for good); with it, the robot fits (deferred).
    _, grid, cm = _walked_in()
    reasons = []
    for trail in (None, cm.trail.mask(grid.origin, grid.resolution, grid.shape)):
        ex = Explorer(make_strategy("nearest"), trail=None if trail is None else lambda _, t=trail: t)
        ex.blacklist, ex.blacklist_reasons = [(OUTSIDE.x, OUTSIDE.y)], ["no_path"]
        ex.rounds = [(OUTSIDE.x, OUTSIDE.y, RETRY_ROUNDS)]
        ex.forgive(grid, INSIDE)
        reasons.append(ex.blacklist_reasons[0])
    assert reasons[0].endswith("narrower than the robot")
    assert "the robot fits the way in" in reasons[1]


def test_the_no_frontier_condition_reads_the_navigator_s_trail() -> None:
    # The mission's "no frontier left" guard asks the map with the trail the navigator's costmap keeps: inside the
    # room, the hall's frontier is left with it (FAILURE), and without it the way out is narrow (SUCCESS: done).
    g, grid, walked = _walked_in()
    statuses = []
    for costmap in (_costmap(g), walked):
        py_trees.blackboard.Blackboard.clear()
        bb = py_trees.blackboard.Client(name="test")
        for key in ("/nav/navigator", "/map/grid", "/map/pose"):
            bb.register_key(key=key, access=Access.WRITE)
        bb.set("/nav/navigator", SimpleNamespace(costmap=costmap))
        bb.set("/map/grid", grid)
        bb.set("/map/pose", INSIDE)
        cond = NoFrontierLeft("NoFrontierLeft")
        cond.setup(robot=SimpleNamespace(clock=SimpleNamespace(now=lambda: 0.0)), seed=0)
        cond.tick_once()
        statuses.append(cond.status)
    assert statuses == [Status.SUCCESS, Status.FAILURE]
