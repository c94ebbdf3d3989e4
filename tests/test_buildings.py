"""Generated buildings: seeded, rooms behind 0.8-1.2 m doors, every room reachable by the robot's footprint, loadable by name."""

from __future__ import annotations

import cv2
import numpy as np
import pytest
from homing.robot.turtlebot import FOOTPRINT_RADIUS
from homing.sim import load_world
from homing.sim.buildings import (
    DOOR_MAX,
    DOOR_MIN,
    RES,
    hospital,
    office,
    office_builder,
    slam_office,
)

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


@pytest.mark.parametrize("make", [office, hospital, slam_office])
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


@pytest.mark.parametrize("seed", range(1, 8))
def test_nothing_stands_in_front_of_a_door(seed: int) -> None:
    # A door is only as wide as the floor before it: a cabinet against the wall beside a door cut from a room
    # off this one (listed in that room's doors) once left office:3 a 0.5 m way through a 0.9 m door.
    b = office_builder(seed)
    depth = int(round(0.6 / RES))  # [cells] how far either side of the wall the floor is kept clear
    doors = [d for room in b.rooms for d in room.doors]
    assert len(doors) >= len(b.rooms)
    for r0, r1, c0, c1 in doors:
        across_rows = r1 - r0 < c1 - c0  # a door in a wall along the columns is passed along the rows
        if across_rows:
            r0, r1 = r0 - depth, r1 + depth
        else:
            c0, c1 = c0 - depth, c1 + depth
        floor = b.grid[b.m + r0 : b.m + r1, b.m + c0 : b.m + c1]
        assert (floor == FREE).all(), f"office:{seed}: {(floor != FREE).sum()} cells block door {(r0, r1, c0, c1)}"
