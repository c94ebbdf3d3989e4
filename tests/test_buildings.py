"""Generated buildings: seeded, rooms behind 0.8-1.2 m doors, every room reachable by the robot's footprint, loadable by name;
large floors and atria with long corridors, diagonal walls and passages a little wider than the robot."""

from __future__ import annotations

import math
import time

import cv2
import numpy as np
import pytest
from homing.robot.turtlebot import FOOTPRINT_RADIUS
from homing.robot.types import Pose2
from homing.sim import SimRobot, load_world
from homing.sim.buildings import (
    DOOR_MAX,
    DOOR_MIN,
    RES,
    atrium,
    floor,
    hospital,
    office,
    office_builder,
    slam_office,
)
from homing.sim.floors import atrium_plan, floor_plan
from scipy import ndimage

from homing.errors import UserError
from homing.map_server import FREE, OCCUPIED, UNKNOWN
from tests.conftest import homing_cli


def _footprint_component(grid: np.ndarray, cell: tuple[int, int]) -> np.ndarray:
    """(H, W) bool: where the robot's centre can go from ``cell``: free cells farther than the footprint's radius
    from anything not free, 8-connected (computed here from scratch, not with the generator's helpers)."""
    blocked = (grid != FREE).astype(np.uint8)
    k = int(np.ceil(FOOTPRINT_RADIUS / RES))
    yy, xx = np.mgrid[-k : k + 1, -k : k + 1]
    disc = (xx * xx + yy * yy <= (FOOTPRINT_RADIUS / RES) ** 2).astype(np.uint8)
    fits = cv2.dilate(blocked, disc) == 0
    labels = cv2.connectedComponents(fits.astype(np.uint8), connectivity=8)[1]
    return labels == labels[cell]


@pytest.mark.parametrize("make", [office, hospital, slam_office, floor, atrium])
def test_same_seed_same_plan_other_seed_other_plan(make) -> None:
    a, b, c = make(4), make(4), make(5)
    assert np.array_equal(a.grid, b.grid)
    assert a.grid.shape != c.grid.shape or not np.array_equal(a.grid, c.grid)


@pytest.mark.parametrize("seed", range(6))
def test_office_rooms_have_doors_of_a_door_width_and_the_robot_reaches_every_room(seed: int) -> None:
    b = office_builder(seed)
    assert len(b.rooms) >= 6
    world = load_world(f"office:{seed}")
    r, c = (int(v) for v in np.floor(((world.start.y - world.map.origin[1]) / RES,
                                       (world.start.x - world.map.origin[0]) / RES)))
    reach = _footprint_component(world.map.grid, _nearest_fit(world.map.grid, (r, c)))
    for room in b.rooms:
        assert room.doors, f"room {room} has no door"
        for d in room.doors:
            width = max(d[1] - d[0], d[3] - d[2]) * RES
            assert DOOR_MIN - RES / 2 <= width <= DOOR_MAX + RES / 2
        inside = reach[b.m + room.r0 : b.m + room.r1, b.m + room.c0 : b.m + room.c1]
        assert inside.mean() > 0.3, f"the robot reaches only {inside.mean():.0%} of room {room}"
    # The building is closed: unknown (outside) never touches free floor but through the doors' walls.
    grid = world.map.grid
    assert (grid[0] == UNKNOWN).all() and (grid[:, -1] == UNKNOWN).all()
    assert (grid == OCCUPIED).sum() > 0.1 * (grid == FREE).sum()  # walls and furniture, not an open hall


def _nearest_fit(grid: np.ndarray, cell: tuple[int, int]) -> tuple[int, int]:
    blocked = (grid != FREE).astype(np.uint8)
    d = cv2.distanceTransform(1 - blocked, cv2.DIST_L2, 5) * RES
    rr, cc = np.nonzero(d > FOOTPRINT_RADIUS + RES)
    k = int(np.argmin((rr - cell[0]) ** 2 + (cc - cell[1]) ** 2))
    return int(rr[k]), int(cc[k])


def test_hospital_is_a_long_corridor_lined_with_small_rooms() -> None:
    plan = hospital(2)
    h, w = plan.grid.shape
    assert w * RES >= 40.0 and w > 2.5 * h
    # The corridor: a row band free (but for the nurses' bay and lobby walls) along most of the building.
    free_rows = (plan.grid == FREE).mean(axis=1)
    assert free_rows.max() > 0.85
    # Rooms: the free cells just off the corridor split into many rooms on each side.
    mid = int(np.argmax(free_rows))
    for side in (-1, 1):
        row = mid + side * int(3.0 / RES)
        runs = np.diff(np.concatenate([[0], (plan.grid[row] == FREE).astype(np.int8), [0]]))
        assert (runs == 1).sum() >= 8


def test_slam_office_looks_like_a_slam_map() -> None:
    plain, slam = office_builder(3, (28.0, 38.0, 18.0, 24.0)).map(), slam_office(3)
    assert plain.grid.shape == slam.grid.shape
    # Rooms never entered are unknown inside the building (a fan seen through their door aside), walls are
    # ragged (wall fringes unknown) and clutter specks stand in the rooms.
    inside = cv2.erode((plain.grid != UNKNOWN).astype(np.uint8), np.ones((3, 3), np.uint8)).astype(bool)
    lost = inside & (plain.grid == FREE) & (slam.grid == UNKNOWN)
    assert lost.sum() * RES**2 > 5.0
    specks = (slam.grid == OCCUPIED) & (plain.grid == FREE)
    assert specks.sum() > 20
    # Streaks: free cells outside the plain building's outline.
    assert ((slam.grid == FREE) & (plain.grid == UNKNOWN)).sum() > 0


def test_generated_worlds_load_by_name_and_bad_names_say_what_exists() -> None:
    world = load_world("hospital:1")
    assert world.name == "hospital_1" and world.is_free(world.start.x, world.start.y)
    with pytest.raises(UserError, match="office:SEED"):
        load_world("offfice:1")
    code, _, err = homing_cli("bench", "explore", "--worlds", "office:x", "--seeds", "1")
    assert code == 2 and "office:SEED" in err and "Traceback" not in err


@pytest.mark.parametrize("kind, seed", [("office", s) for s in range(1, 8)] + [("floor", 1), ("floor", 2),
                                                                             ("atrium", 1), ("atrium", 2)])
def test_nothing_stands_in_front_of_a_door(kind: str, seed: int) -> None:
    # A door is only as wide as the floor before it: a cabinet against the wall beside a door cut from a room
    # off this one (listed in that room's doors) once left office:3 a 0.5 m way through a 0.9 m door. On the
    # large floors: pillars and partitions too, and the halls' wide openings and the narrow passages.
    b = {"office": office_builder, "floor": lambda s: floor_plan(s).builder,
         "atrium": lambda s: atrium_plan(s).builder}[kind](seed)
    depth = int(round((0.6 if kind == "office" else 1.0) / RES))  # [cells] floor kept clear either side
    doors = [d for room in b.rooms for d in room.doors]
    assert len(doors) >= len(b.rooms) - (kind == "atrium")  # the atrium's hall has its rooms' doors only
    for r0, r1, c0, c1 in doors:
        across_rows = r1 - r0 < c1 - c0  # a door in a wall along the columns is passed along the rows
        if across_rows:
            r0, r1 = r0 - depth, r1 + depth
        else:
            c0, c1 = c0 - depth, c1 + depth
        floor = b.grid[b.m + r0 : b.m + r1, b.m + c0 : b.m + c1]
        assert (floor == FREE).all(), f"{kind}:{seed}: {(floor != FREE).sum()} cells block door {(r0, r1, c0, c1)}"


# -- large floors and atria ---------------------------------------------------------------------------------------
PASSAGE_MIN = 0.45  # [m] the narrowest way into any room (the robot is 0.354 m across)


def _start_cell(world) -> tuple[int, int]:
    r, c = (int(v) for v in np.floor(((world.start.y - world.map.origin[1]) / RES,
                                       (world.start.x - world.map.origin[0]) / RES)))
    return r, c


def _through_passages(grid: np.ndarray, cell: tuple[int, int], width: float) -> np.ndarray:
    """(H, W) bool: free cells 8-connected to ``cell`` through free cells at least ``width`` / 2 from anything
    solid (scipy's exact distance from cell centres): the places a disc ``width`` across can reach."""
    clear = ndimage.distance_transform_edt(grid == FREE) * RES >= width / 2
    labels = cv2.connectedComponents(clear.astype(np.uint8), connectivity=8)[1]
    k = _nearest_fit(grid, cell)
    return labels == labels[k]


def _longest_lane(free: np.ndarray, width: float) -> float:
    """[m] the longest straight run, along the rows or the columns, of a free lane ``width`` wide."""
    k = int(round(width / RES))
    best = 0
    for lane in (cv2.erode(free, np.ones((k, 1), np.uint8)), cv2.erode(free, np.ones((1, k), np.uint8)).T):
        padded = np.pad(lane.astype(np.int8), ((0, 0), (1, 1)))
        d = np.diff(padded, axis=1)
        starts, stops = np.nonzero(d == 1), np.nonzero(d == -1)
        best = max(best, int((stops[1] - starts[1]).max()))  # rows scanned in order: starts and stops pair up
    return best * RES


@pytest.mark.parametrize("kind, seed, area, lane", [("floor", s, (1800.0, 2250.0), 40.0) for s in (1, 2, 3)]
                         + [("atrium", s, (700.0, 1300.0), 20.0) for s in (1, 2)])
def test_floor_is_about_2000_m2_with_a_corridor_over_40_m_diagonal_walls_and_narrow_passages(
        kind: str, seed: int, area: tuple[float, float], lane: float) -> None:
    plan = (floor_plan if kind == "floor" else atrium_plan)(seed)
    grid = plan.map().grid
    # Outer size: the building's bounding box (everything not unknown), 1800-2250 m² for a floor; most of it floor.
    rows, cols = np.nonzero(grid != UNKNOWN)
    outer = (rows.max() - rows.min() + 1) * (cols.max() - cols.min() + 1) * RES**2
    assert area[0] <= outer <= area[1]
    assert (grid == FREE).sum() * RES**2 > 0.8 * outer
    # A corridor: a straight free lane 1.4 m wide and at least 40 m long (an atrium's hall: 20 m).
    assert _longest_lane((grid == FREE).astype(np.uint8), 1.4) >= lane
    # Diagonal walls: segments 2.5 m or longer, 20-70 degrees off the axes, solid along their centre line.
    diagonal = 0
    for (x0, y0), (x1, y1) in plan.diagonal_ends():
        length, angle = math.hypot(x1 - x0, y1 - y0), math.degrees(math.atan2(abs(y1 - y0), abs(x1 - x0)))
        if length < 2.5 or not 20.0 <= angle <= 70.0:
            continue
        f = np.linspace(0.0, 1.0, int(length / (RES / 4)))
        r = np.floor((y0 + f * (y1 - y0) - plan.map().origin[1]) / RES).astype(int)
        c = np.floor((x0 + f * (x1 - x0) - plan.map().origin[0]) / RES).astype(int)
        assert (grid[r, c] == OCCUPIED).all()
        diagonal += 1
    assert diagonal >= 2
    if kind == "atrium":  # one open hall: a disc 6 m across fits in it, pillars and partitions about (a room: 3-5 m)
        clear = ndimage.distance_transform_edt(grid == FREE) * RES
        assert clear.max() >= 3.0
    # Narrow passages: twice the clearance (exact distance transform on a grid of half cells, where a gap of n
    # cells has its middle n half-cells from the solid cells' centres either side) is 0.45-0.6 m.
    assert len(plan.narrow) >= (3 if kind == "floor" else 2)
    fine = np.repeat(np.repeat(grid == FREE, 2, axis=0), 2, axis=1)
    clearance = ndimage.distance_transform_edt(fine) * RES / 2
    m = plan.builder.m
    for r0, r1, c0, c1 in plan.narrow:
        width = 2 * clearance[2 * (m + r0) : 2 * (m + r1), 2 * (m + c0) : 2 * (m + c1)].max()
        assert PASSAGE_MIN <= width <= 0.6 + 1e-9, f"{kind}:{seed}: passage {(r0, r1, c0, c1)} is {width:.2f} m"


@pytest.mark.parametrize("kind, seed", [("floor", 1), ("floor", 2), ("floor", 3), ("atrium", 1), ("atrium", 2)])
def test_every_room_and_hall_is_reachable_from_the_start_through_passages_at_least_045_m(kind: str, seed: int) -> None:
    plan = (floor_plan if kind == "floor" else atrium_plan)(seed)
    world = load_world(f"{kind}:{seed}")
    grid = world.map.grid
    assert np.array_equal(grid, plan.map().grid)
    reach = _through_passages(grid, _start_cell(world), PASSAGE_MIN)
    b = plan.builder
    for room in b.rooms:
        inside = reach[b.m + room.r0 : b.m + room.r1, b.m + room.c0 : b.m + room.c1]
        assert inside.mean() > 0.3, f"{kind}:{seed}: the robot reaches only {inside.mean():.0%} of room {room}"
    # And all of the floor is within a footprint of those places: nothing is cut off.
    near = cv2.dilate(reach.astype(np.uint8), np.ones((7, 7), np.uint8)).astype(bool)
    assert not ((grid == FREE) & ~near).any()
    # The narrow passages are ways in: closing them cuts rooms off (the storerooms at least).
    closed = grid.copy()
    for r0, r1, c0, c1 in plan.narrow:
        closed[b.m + r0 : b.m + r1, b.m + c0 : b.m + c1] = OCCUPIED
    cut = (grid == FREE) & ~_through_passages(closed, _start_cell(world), PASSAGE_MIN) & (closed == FREE)
    assert cut.sum() * RES**2 > 5.0


def test_a_floor_loads_docked_against_a_wall_and_a_sim_robot_drives_in_it() -> None:
    t0 = time.perf_counter()
    world = load_world("floor:1")
    assert time.perf_counter() - t0 < 5.0  # ~0.5 s on an idle core; generous for a loaded machine
    assert world.name == "floor_1" and world.start == world.dock_pose
    # The dock's back is on a wall: straight behind it, within 0.15 m, a solid cell.
    back = world.dock.station.compose(Pose2(-0.15, 0.0, 0.0))
    assert not world.is_free(back.x, back.y) and world.is_free(world.start.x, world.start.y)
    robot = SimRobot(world, seed=1)
    try:
        scan = None
        for k in range(30):
            robot.command(-0.2 if k < 15 else 0.0, 0.0)  # back out of the dock
            robot.step(0.1)
            scan = robot.observe().scan
        assert scan is not None and np.isfinite(scan.ranges).sum() > 100
        moved = robot.truth_pose()
        assert math.hypot(moved.x - world.start.x, moved.y - world.start.y) > 0.2
    finally:
        robot.close()


def _grid_range(grid: np.ndarray, origin: tuple[float, float, float], x: float, y: float, angle: float) -> float:
    """[m] from (x, y) along ``angle`` to the first cell not free, marched in 2 mm steps (the map's own geometry)."""
    s = np.arange(0.0, 6.0, 0.002)
    r = np.floor((y + s * math.sin(angle) - origin[1]) / RES).astype(int)
    c = np.floor((x + s * math.cos(angle) - origin[0]) / RES).astype(int)
    h, w = grid.shape
    inside = (0 <= r) & (r < h) & (0 <= c) & (c < w)
    solid = ~inside | (grid[np.clip(r, 0, h - 1), np.clip(c, 0, w - 1)] != FREE)
    return float(s[np.argmax(solid)])


@pytest.mark.parametrize("kind, seed", [("floor", 1), ("atrium", 1)])
def test_the_lidar_sees_a_diagonal_wall_at_its_geometric_range(kind: str, seed: int) -> None:
    plan = (floor_plan if kind == "floor" else atrium_plan)(seed)
    world = load_world(f"{kind}:{seed}")
    grid, origin = world.map.grid, world.map.origin
    robot = SimRobot(world, seed=1)
    try:
        checked = 0
        for (x0, y0), (x1, y1) in plan.diagonal_ends():
            mx, my = (x0 + x1) / 2, (y0 + y1) / 2
            nx, ny = (y0 - y1), (x1 - x0)
            n = math.hypot(nx, ny)
            nx, ny = nx / n, ny / n
            for sign in (1.0, -1.0):  # stand 1.5 m off the wall's middle, on its free side, facing it
                px, py = mx + sign * 1.5 * nx, my + sign * 1.5 * ny
                if not world.is_free(px, py):
                    continue
                pose = Pose2(px, py, math.atan2(-sign * ny, -sign * nx))
                ranges, _ = robot.lidar.true_ranges(pose)
                for k in list(range(0, 26)) + list(range(len(ranges) - 25, len(ranges))):
                    a = pose.theta + k * 2 * math.pi / len(ranges)
                    # The ray meets the wall where the map has it (its face is drawn in 0.1 m steps)...
                    assert ranges[k] == pytest.approx(_grid_range(grid, origin, px, py, a), abs=0.005)
                    # ...and that is the diagonal wall: a staircase of cells 0.1 m either side of its centre line,
                    # whose steps' corners stand 0.05-0.25 m off it, met at that over cos(angle off the normal).
                    off = math.cos(a - pose.theta)
                    assert (1.5 - 0.25) / off <= ranges[k] <= (1.5 - 0.05) / off, (k, ranges[k])
                checked += 1
        assert checked >= 2
    finally:
        robot.close()


def test_floor_generation_is_fast_and_the_same_per_seed() -> None:
    t0 = time.perf_counter()
    a = floor(7)
    took = time.perf_counter() - t0
    assert took < 3.0  # ~0.3-0.4 s on an idle core
    assert a.grid.tobytes() == floor(7).grid.tobytes() and a.grid.tobytes() != floor(8).grid.tobytes()


@pytest.mark.parametrize("spec", ["floor:x", "floor:", "atrium:-1", "floor:1.5"])
def test_a_bad_seed_is_one_line_naming_the_kind(spec: str) -> None:
    with pytest.raises(UserError, match=f"{spec.split(':')[0]}:SEED") as err:
        load_world(spec)
    assert "\n" not in str(err.value)
    code, _, out = homing_cli("world", "show", spec, "--out", "unused.png")
    assert code == 2 and "Traceback" not in out and len(out.strip().splitlines()) == 1
