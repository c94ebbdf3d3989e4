"""One rule for "reachable" (homing.mapping.navigable): the truth's navigable area, the costmap's planner and the
explorer's frontier report agree on where a round robot fits, and what lies behind narrower passages is reported
with their widths."""

from __future__ import annotations

import numpy as np
import pytest
from homing.mapping.evaluate import coverage, navigable_truth, unseen_places
from homing.mapping.grid import OccupancyGrid
from homing.mapping.navigable import inscribed_radius, navigable
from homing.mapping.reachable import frontier_report
from homing.navigation.costmap import Costmap
from homing.navigation.planner import distance_map
from homing.robot.turtlebot import FOOTPRINT_RADIUS

from homing.map_server import FREE, OCCUPIED, UNKNOWN, MapData

RES = 0.05  # [m/cell]


def _plan(passage: float) -> MapData:
    """21 m × 12 m at 5 cm: a 6 m × 6 m start room at the left; a 0.9 m door into a 6 m × 5 m room above the
    corridor; and a straight corridor ``passage`` [m] wide and 5 m long to an 8 m × 9 m room (72 m²) at the right."""
    g = np.full((240, 420), OCCUPIED, np.int8)
    g[20:140, 20:140] = FREE  # start room: x 1..7, y 1..7
    g[160:220, 20:140] = FREE  # room above: y 8..11
    g[140:160, 70:88] = FREE  # its 0.9 m door through the 1 m wall
    w = int(round(passage / RES))
    g[70 : 70 + w, 140:240] = FREE  # the corridor: x 7..12, y 3.5..
    g[40:220, 240:400] = FREE  # far room: x 12..20, y 2..11 (72 m²)
    return MapData(g, RES, (0.0, 0.0, 0.0))


START = (3.0, 3.0)  # [m]
FAR_ROOM = (slice(45, 215), slice(250, 395))  # its cells away from the corridor's mouth


def test_a_room_behind_a_passage_narrower_than_the_robot_is_reported_with_the_width() -> None:
    truth = _plan(0.40)  # the robot is 0.354 m across, but no cell of a 0.40 m corridor is clear of both walls
    nav = navigable_truth(truth, START)
    assert not nav.mask[FAR_ROOM].any()
    assert nav.mask[190, 80] and nav.mask[60, 60]  # the room through the 0.9 m door, and the start room
    assert len(nav.blocked) == 1
    b = nav.blocked[0]
    assert 70.0 <= b.area <= 76.0  # the far room and the corridor beyond the footprint's reach
    assert abs(b.width - 0.40) <= 0.5 * RES + 1e-9  # within half a cell of the drawn width
    assert not b.marginal  # the footprint does not fit through it even on an exact map
    assert b.x > 12.0
    assert f"through {b.width:.2f} m" in nav.summary()
    # Everything the robot can use is covered by a map of the two rooms and the door, the far room unseen.
    seen = np.full(truth.grid.shape, UNKNOWN, np.int8)
    seen[:, :145] = truth.grid[:, :145]
    grid = OccupancyGrid.from_map_data(MapData(seen, RES, (0.0, 0.0, 0.0)), grow=False)
    assert coverage(grid, truth, START).coverage == pytest.approx(1.0)
    assert unseen_places(grid, truth, START) == []


def test_a_passage_a_little_wider_than_the_robot_is_navigable() -> None:
    truth = _plan(0.60)
    nav = navigable_truth(truth, START)
    assert nav.mask[FAR_ROOM].all() and not nav.blocked
    seen = np.full(truth.grid.shape, UNKNOWN, np.int8)
    seen[:, :145] = truth.grid[:, :145]
    grid = OccupancyGrid.from_map_data(MapData(seen, RES, (0.0, 0.0, 0.0)), grow=False)
    assert coverage(grid, truth, START).coverage < 0.6
    places = unseen_places(grid, truth, START)
    assert len(places) == 1 and places[0] > 70.0  # the far room: a place left unseen, not a corner


def test_a_passage_within_a_map_cell_a_side_of_the_rule_is_reported_apart() -> None:
    # The footprint fits through a 0.50 m corridor drawn exactly (10 cells, the rule wants 9), but a map that
    # draws each wall face a cell in (a face on a cell boundary, a pose 3 cm off) shows it 8 cells wide: the
    # truth leaves the far room out of the navigable area and reports it apart, marginal, with the width.
    truth = _plan(0.50)
    nav = navigable_truth(truth, START)
    assert not nav.mask[FAR_ROOM].any()
    assert len(nav.blocked) == 1 and nav.blocked[0].marginal and 70.0 <= nav.blocked[0].area <= 76.0
    assert abs(nav.blocked[0].width - 0.50) <= 0.5 * RES + 1e-9
    assert "a map may draw narrower than the robot" in nav.summary()
    drawn = truth.grid.copy()
    drawn[70, 140:240] = drawn[79, 140:240] = OCCUPIED  # each face a cell in: 8 cells
    cm = Costmap()
    cm.set_static(drawn, RES, (0.0, 0.0))
    assert not np.isfinite(distance_map(cm, START)[130, 300])
    # A 0.55 m corridor keeps the room navigable whichever way the map rounds its faces.
    assert not navigable_truth(_plan(0.55), START).blocked


def test_a_plan_coarser_than_the_robot_grid_is_judged_on_the_grid_cells() -> None:
    # At 0.1 m the middle of a 0.5 m and of a 0.6 m passage are both 3 cells from a wall; on the robot's 5 cm
    # cells the first is marginal and the second navigable.
    for passage, marginal in ((0.50, True), (0.60, False)):
        fine = _plan(passage)
        coarse = MapData(fine.grid[::2, ::2].copy(), 2 * RES, (0.0, 0.0, 0.0))
        nav = navigable_truth(coarse, START)
        assert [b.marginal for b in nav.blocked] == ([True] if marginal else [])
        assert nav.mask.shape == coarse.grid.shape
        assert nav.mask[FAR_ROOM[0].start // 2 + 5, FAR_ROOM[1].start // 2 + 5] is not np.bool_(marginal)


@pytest.mark.parametrize(("passage", "through"), [(0.40, False), (0.45, True), (0.50, True)])
def test_the_planner_and_the_explorer_use_the_same_rule(passage: float, through: bool) -> None:
    # On a map drawn exactly the planner and the explorer pass what the rule passes: the truth has the same rule
    # with the map's margin, so passages the footprint fits through by less are reported marginal.
    truth = _plan(passage)
    assert [b.marginal for b in navigable_truth(truth, START).blocked] == [through]
    cm = Costmap()
    cm.set_static(truth.grid, RES, (0.0, 0.0))
    assert cm.inscribed_radius == pytest.approx(inscribed_radius(RES, FOOTPRINT_RADIUS))
    d = distance_map(cm, START)
    assert bool(np.isfinite(d[130, 300])) is through  # the middle of the far room
    # The explorer, standing in the start room of a map that knows everything but the far room's inside,
    # calls the far room's frontier reachable exactly when the planner reaches it, narrow when it does not.
    known = truth.grid.copy()
    known[60:200, 260:390] = UNKNOWN
    grid = OccupancyGrid.from_map_data(MapData(known, RES, (0.0, 0.0, 0.0)), grow=False)
    report = frontier_report(grid, START)
    far = [s for s in report.reachable if s.x > 12.0]
    narrow = [s for s in report.narrow if s.x > 12.0]
    assert bool(far) is through and bool(narrow) is not through


def test_a_start_beside_a_wall_takes_the_nearest_place_it_fits() -> None:
    truth = _plan(0.9)
    at_wall = navigable(truth.grid == FREE, RES, (0.0, 0.0), (1.02, 3.0))
    assert at_wall.area == pytest.approx(navigable_truth(truth, START).area)


def test_a_done_with_a_reachable_room_unseen_is_a_false_done_whatever_the_frontiers_said() -> None:
    # The explorer gave up the frontier into the far room (so it counted no frontier left, frontiers_left 0)
    # and said done: the truth still has the room, navigable and unseen, so the bench calls it a false done.
    # Behind a 0.40 m corridor the same unseen room is no false done: the robot cannot get there; nor behind a
    # 0.50 m one, which the robot's map may draw narrower than the robot.
    from dataclasses import replace

    from homing.benchmarks.explore import FALSE_DONE_AREA, RunResult, false_done

    nan = float("nan")
    said_done = RunResult("plan", "frontier_travel", 0, 0.1, 100.0, 0.5, 5.0, 50.0, 300.0, nan, nan, True, 0, 0, 9,
                          1.0, 1.0, 1.0, frontiers_left=0, given_up=1)
    for passage, expected in ((0.60, True), (0.50, False), (0.40, False)):
        truth = _plan(passage)
        seen = np.full(truth.grid.shape, UNKNOWN, np.int8)
        seen[:, :145] = truth.grid[:, :145]  # everything but the corridor's far end and the far room
        grid = OccupancyGrid.from_map_data(MapData(seen, RES, (0.0, 0.0, 0.0)), grow=False)
        places = unseen_places(grid, truth, START, min_area=0.0)
        run = replace(said_done, unseen_place=places[0] if places else 0.0)
        assert false_done(run) is expected, (passage, places)
        assert (run.unseen_place >= FALSE_DONE_AREA) is expected
        assert not false_done(replace(run, done=False))  # an incomplete end says so: no false done


def test_a_strip_along_a_wall_the_map_draws_a_little_off_is_no_unseen_place() -> None:
    # A map drawn 0.3 m short of a 9 m wall (a degree of rotation over a long wall) leaves a 2.7 m² strip of
    # the navigable area under unknown cells: no place the robot's footprint fits in, so no false done.
    truth = _plan(0.60)
    seen = truth.grid.copy()
    seen[40:220, 394:400] = UNKNOWN  # the far room's east strip, 0.3 m wide
    grid = OccupancyGrid.from_map_data(MapData(seen, RES, (0.0, 0.0, 0.0)), grow=False)
    assert coverage(grid, truth, START).coverage < 1.0
    assert unseen_places(grid, truth, START, min_area=0.0) == []
    seen[100:130, 370:400] = UNKNOWN  # and a 1.5 m × 1.5 m corner of the room, unseen: a place
    grid = OccupancyGrid.from_map_data(MapData(seen, RES, (0.0, 0.0, 0.0)), grow=False)
    places = unseen_places(grid, truth, START)
    assert len(places) == 1 and 1.5 < places[0] < 2.7
