"""Generated large floors: long corridors, open halls, diagonal walls and passages a little wider than the robot.

The office, ward and SLAM-office kinds (:mod:`homing.sim.buildings`) are up to
~800 m², every wall axis-aligned, every door 0.8–1.2 m. These seeded kinds
give what they lack (issue 36, deliverable 7):

- ``floor:SEED`` — a floor of ~2000 m² (45–60 m × 32–48 m outer size): a
  main corridor the building's whole length (45–60 m) crossed by a second
  one its whole depth, cutting it into four quarters; a quarter is either
  rooms (a row facing the main corridor, a side corridor behind it — running
  through, or ending short at a row of rooms — and a row of rooms facing
  that, deep ones split into rooms off rooms) or an open hall (a 2.5–4 m
  opening onto the main corridor and a door onto the cross one, pillars,
  one or two free-standing diagonal partitions, a diagonal wall across one
  corner, a storeroom in another). Narrow passages, 0.5–0.6 m (the robot is
  0.354 m across): one room per rooms quarter whose only way in is one, one
  shortcut through a room from the side corridor, and every storeroom's door;
- ``atrium:SEED`` — a 30–40 m × 24–32 m building that is mostly one hall:
  rooms along two sides opening into it (one through a narrow passage), a
  storeroom, pillars, two to four diagonal partitions and a diagonal corner.

Diagonal walls are rasterised at ``RES`` (0.2 m thick), so the simulator's
wall mesh follows them in 0.1 m steps. Free-standing partitions and pillars
keep ``HALL_CLEAR`` from everything else, so they never make a gap narrower
than that nor stand in front of a door. ``floor_plan(seed)`` returns the plan
with what a test needs to check it (corridors, halls, narrow passages,
diagonals); ``floor(seed)`` the map alone, as every kind.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import cv2
import numpy as np
from homing.sim.buildings import (
    RES,
    Builder,
    Room,
    _ahead,
    _cells,
    _connected,
    _disc,
    _faces_corridor,
    _parts,
    _split_deep,
)

from homing.map_server import FREE, OCCUPIED, UNKNOWN, MapData

NARROW = (0.5, 0.6)  # [m] narrow passages: a 0.1 m grid holds 5 or 6 cells (0.45 would round to 0.4 or 0.5)
HALL_CLEAR = 1.0  # [m] free floor kept around pillars and partitions
ROOM_WIDTHS = (3.0, 5.5)  # [m] rooms along a corridor
DOOR_TRIES = 8  # places tried along a wall for a door with free floor before it
DEEP = 7.5  # [m] a room deeper than this is split in two (the back one off the front one)


@dataclass
class FloorPlan:
    """A generated plan and its parts: ``corridors`` (their clear floor) and ``narrow`` (the gaps in the walls) as
    (r0, r1, c0, c1) rectangles in building cells (``builder.m`` from the grid's edge); ``diagonals`` as the
    wall centre lines' ends ((row, col), (row, col)), grid cells whose centres the line joins."""

    builder: Builder
    corridors: list[tuple[int, int, int, int]] = field(default_factory=list)
    halls: list[Room] = field(default_factory=list)
    narrow: list[tuple[int, int, int, int]] = field(default_factory=list)
    diagonals: list[tuple[tuple[int, int], tuple[int, int]]] = field(default_factory=list)

    def map(self) -> MapData:
        return self.builder.map()

    def diagonal_ends(self) -> list[tuple[tuple[float, float], tuple[float, float]]]:
        """The diagonal walls' centre lines as ((x0, y0), (x1, y1)) [m] in the world frame of :meth:`map`."""
        ox, oy, _ = self.map().origin
        return [((ox + (c0 + 0.5) * RES, oy + (r0 + 0.5) * RES), (ox + (c1 + 0.5) * RES, oy + (r1 + 0.5) * RES))
                for (r0, c0), (r1, c1) in self.diagonals]


# -- the plans ----------------------------------------------------------------------------------------------------
def floor_plan(seed: int) -> FloorPlan:
    """A ~2000 m² floor (module doc)."""
    rng = np.random.default_rng([seed, 19])
    width = rng.uniform(45.0, 60.0)
    b = Builder(width, rng.uniform(1950.0, 2150.0) / width, rng)
    plan = FloorPlan(b)
    t = b.t
    cw, vw = _cells(rng.uniform(2.2, 2.8)), _cells(rng.uniform(2.2, 2.6))  # wall to wall: 1.8-2.4 m clear
    cy, vx = int(b.h * rng.uniform(0.42, 0.55)), int(b.w * rng.uniform(0.35, 0.6))
    plan.corridors += [(cy + t, cy + cw - t, t, b.w - t), (t, b.h - t, vx + t, vx + vw - t)]
    quarters = [((0, cy + t, 0, vx + t), "N", "E"), ((0, cy + t, vx + vw - t, b.w), "N", "W"),
                ((cy + cw - t, b.h, 0, vx + t), "S", "E"), ((cy + cw - t, b.h, vx + vw - t, b.w), "S", "W")]
    n_halls = 1 + int(rng.random() < 0.5)
    order = rng.permutation(4)
    for k, i in enumerate(order):
        rect, ms, xs = quarters[int(i)]
        if k < n_halls:
            _hall_quarter(plan, rect, ms, xs)
        else:
            _rooms_quarter(plan, rect, ms, xs)
    b.connect()
    _furnish(plan)
    return plan


def atrium_plan(seed: int) -> FloorPlan:
    """A building that is mostly one pillared hall with diagonal partitions (module doc)."""
    rng = np.random.default_rng([seed, 20])
    b = Builder(rng.uniform(30.0, 40.0), rng.uniform(24.0, 32.0), rng)
    plan = FloorPlan(b)
    t = b.t
    ds, dw = _cells(rng.uniform(4.0, 6.0)), _cells(rng.uniform(4.0, 6.0))
    south = b.strip(0, ds + t, 0, b.w, "N", ROOM_WIDTHS)
    west = b.strip(ds, b.h, 0, dw + t, "E", ROOM_WIDTHS)
    hall = Room(ds + t, b.h - t, dw + t, b.w - t, "S")
    plan.halls.append(hall)
    b.rooms.append(hall)
    narrow_room = int(rng.integers(len(south) + len(west)))
    for k, room in enumerate(south + west):
        if _faces_corridor(b, room, room.front):
            _door(plan, room, room.front, narrow=k == narrow_room)
    # The storeroom against the north wall, in the west half; the diagonal corner in the north-east one.
    span = hall.c1 - hall.c0
    c0 = hall.c0 - t + int(span * rng.uniform(0.2, 0.3))
    _storeroom(plan, (hall.r1 + t - _cells(rng.uniform(3.0, 4.0)), hall.r1 + t, c0, c0 + _cells(rng.uniform(3.0, 4.0))),
               "S")
    _chamfer(plan, hall, "N", "E")
    _partitions(plan, hall, int(rng.integers(2, 5)))
    _pillars(plan, hall)
    b.connect()
    _furnish(plan)
    return plan


def floor(seed: int) -> MapData:
    """A ~2000 m² floor of corridors, rooms and halls (module doc)."""
    return floor_plan(seed).map()


def atrium(seed: int) -> MapData:
    """A pillared hall with rooms along two sides (module doc)."""
    return atrium_plan(seed).map()


# -- quarters of a floor ------------------------------------------------------------------------------------------
def _rooms_quarter(plan: FloorPlan, rect: tuple[int, int, int, int], ms: str, xs: str) -> None:
    """Rooms in the quarter ``rect`` whose ``ms`` side is the main corridor and ``xs`` side the cross one: a row
    facing the main corridor, a side corridor behind it from the cross corridor, a row of rooms facing that."""
    b, rng, t = plan.builder, plan.builder.rng, plan.builder.t
    r0, r1, c0, c1 = rect
    depth = r1 - r0
    sw = _cells(rng.uniform(2.0, 2.4))  # wall to wall: 1.6-2.0 m clear
    d1 = max(_cells(rng.uniform(5.0, 7.0)), (depth - sw) // 2 - _cells(3.0))
    if ms == "N":
        s0, s1 = r1 - d1 - sw, r1 - d1
        front_rows, back_rows = (s1 - t, r1), (r0, s0 + t)
    else:
        s0, s1 = r0 + d1, r0 + d1 + sw
        front_rows, back_rows = (r0, s0 + t), (s1 - t, r1)
    end = _cells(rng.uniform(4.0, 7.0)) if rng.random() < 0.5 else 0  # a dead end: rooms across its far end
    lo, hi = (c0 + end - t if end else c0, c1) if xs == "E" else (c0, c1 - end + t if end else c1)
    plan.corridors.append((s0 + t, s1 - t, lo + t, hi - t))
    first = len(b.rooms)
    front = b.strip(*front_rows, lo, hi, ms, ROOM_WIDTHS)
    b.strip(*back_rows, lo, hi, ms, ROOM_WIDTHS)
    if end:
        b.strip(r0, r1, c0, c0 + end, xs, (3.5, 6.0)) if xs == "E" else b.strip(r0, r1, c1 - end, c1, xs, (3.5, 6.0))
    rooms = b.rooms[first:]
    for room in list(rooms):
        deep = (room.r1 - room.r0) if room.front in "NS" else (room.c1 - room.c0)
        if deep > _cells(DEEP) and rng.random() < 0.8:
            _split_deep(b, room)
    facing = [room for room in rooms if _faces_corridor(b, room, room.front)]
    only_narrow = facing[int(rng.integers(len(facing)))] if facing else None
    for room in facing:
        _door(plan, room, room.front, narrow=room is only_narrow)
    # A shortcut through a room of the front row: a narrow door from the side corridor.
    back_side = "S" if ms == "N" else "N"
    through = [room for room in front if room is not only_narrow and _faces_corridor(b, room, back_side)]
    if through:
        _door(plan, through[int(rng.integers(len(through)))], back_side, narrow=True)


def _hall_quarter(plan: FloorPlan, rect: tuple[int, int, int, int], ms: str, xs: str) -> None:
    """An open hall in the quarter ``rect``: a wide opening onto the main corridor (``ms`` side), a door onto the
    cross one (``xs``), a storeroom in the building's corner, a diagonal wall across the other outer corner,
    partitions and pillars."""
    b, rng, t = plan.builder, plan.builder.rng, plan.builder.t
    r0, r1, c0, c1 = rect
    b.box(r0, r1, c0, c1)
    hall = Room(r0 + t, r1 - t, c0 + t, c1 - t, ms)
    plan.halls.append(hall)
    b.rooms.append(hall)
    # The opening, in the half of the wall nearer the cross corridor (the diagonal corner takes the other end).
    width, jamb = _cells(rng.uniform(2.5, 4.0)), _cells(0.5)
    mid = (hall.c0 + hall.c1) // 2
    a_lo, a_hi = (mid, hall.c1 - jamb - width) if xs == "E" else (hall.c0 + jamb, mid - width)
    a = int(rng.integers(a_lo, max(a_lo, a_hi) + 1))
    rows = (hall.r1, hall.r1 + t) if ms == "N" else (hall.r0 - t, hall.r0)
    opening = (rows[0], rows[1], a, a + width)
    b.grid[b.m + rows[0] : b.m + rows[1], b.m + a : b.m + a + width] = FREE
    hall.doors.append(opening)
    _door(plan, hall, xs, narrow=False)
    outer_y, outer_x = ("S" if ms == "N" else "N"), ("W" if xs == "E" else "E")
    h, w = _cells(rng.uniform(3.0, 4.0)), _cells(rng.uniform(3.0, 4.0))
    rows = (hall.r1 + t - h, hall.r1 + t) if outer_y == "N" else (hall.r0 - t, hall.r0 - t + h)
    cols = (hall.c1 + t - w, hall.c1 + t) if outer_x == "E" else (hall.c0 - t, hall.c0 - t + w)
    _storeroom(plan, (*rows, *cols), ms)
    _chamfer(plan, hall, ms, outer_x)
    _partitions(plan, hall, 1 + int(rng.random() < 0.6))
    _pillars(plan, hall)


# -- parts --------------------------------------------------------------------------------------------------------
def _door(plan: FloorPlan, room: Room, side: str, narrow: bool) -> None:
    """A door through ``side`` of ``room``: 0.8–1.2 m, or a narrow passage (``NARROW``) if ``narrow``; where the
    floor is free HALL_CLEAR either side of the wall (not facing the end of a wall across the way, as a door
    onto the dead end of a side corridor can), else none."""
    b, m = plan.builder, plan.builder.m
    width = float(b.rng.choice(NARROW)) if narrow else None
    for _ in range(DOOR_TRIES):
        if not b.door(room, side, width):
            return
        door = room.doors[-1]
        r0, r1, c0, c1 = _ahead(door, _cells(HALL_CLEAR))
        ahead = b.grid[m + r0 : m + r1, m + c0 : m + c1]
        if (ahead == FREE).all():
            if narrow:
                plan.narrow.append(door)
            return
        room.doors.pop()
        b.grid[m + door[0] : m + door[1], m + door[2] : m + door[3]] = OCCUPIED


def _storeroom(plan: FloorPlan, rect: tuple[int, int, int, int], into: str) -> Room:
    """A small room on ``rect`` (walls included) whose only door, through its ``into`` side, is a narrow passage."""
    store = plan.builder.room(*rect, into)
    _door(plan, store, into, narrow=True)
    return store


def _chamfer(plan: FloorPlan, hall: Room, ys: str, xs: str) -> None:
    """A diagonal wall across the hall's (``ys``, ``xs``) corner, legs of 3 m up to a third of the hall's sides;
    the corner behind it is outside (unknown)."""
    b, rng, m = plan.builder, plan.builder.rng, plan.builder.m
    span_c, span_r = hall.c1 - hall.c0, hall.r1 - hall.r0
    leg_c = int(rng.integers(_cells(3.0), max(_cells(3.0), span_c // 3) + 1))
    leg_r = int(rng.integers(_cells(3.0), max(_cells(3.0), span_r // 3) + 1))
    rc = hall.r1 - 1 if ys == "N" else hall.r0
    cc = hall.c1 - 1 if xs == "E" else hall.c0
    dr, dc = (-1 if ys == "N" else 1), (-1 if xs == "E" else 1)
    corner = (cc, rc)
    a, z = (cc + dc * leg_c, rc), (cc, rc + dr * leg_r)  # (col, row) on the two walls
    tri = np.array([corner, a, z], np.int32) + m
    region = np.zeros(b.grid.shape, np.uint8)
    cv2.fillPoly(region, [tri], 1)
    b.grid[region.astype(bool) & (b.grid == FREE)] = UNKNOWN
    _diagonal(plan, (a[1], a[0]), (z[1], z[0]))
    # Seal: outside cells touching the floor become wall.
    near_free = cv2.dilate((b.grid == FREE).astype(np.uint8), np.ones((3, 3), np.uint8)).astype(bool)
    b.grid[region.astype(bool) & near_free & (b.grid == UNKNOWN)] = OCCUPIED


def _line(shape: tuple[int, ...], p: tuple[float, float], q: tuple[float, float], m: int, thickness: int
          ) -> tuple[np.ndarray, tuple[tuple[int, int], tuple[int, int]]]:
    """(mask of a line ``thickness`` cells thick from p to q, its ends): p, q (row, col) building cells; the ends
    are the grid cells (row, col) whose centres it joins."""
    a, z = ((int(round(r + m)), int(round(c + m))) for r, c in (p, q))
    mask = np.zeros(shape, np.uint8)
    cv2.line(mask, (a[1], a[0]), (z[1], z[0]), 1, thickness=thickness, lineType=cv2.LINE_8)
    return mask, (a, z)


def _diagonal(plan: FloorPlan, p: tuple[float, float], q: tuple[float, float]) -> None:
    """Draw a wall WALL thick along the centre line p → q, (row, col) building cells."""
    b = plan.builder
    mask, ends = _line(b.grid.shape, p, q, b.m, b.t)
    b.grid[mask.astype(bool)] = OCCUPIED
    plan.diagonals.append(ends)


def _open_floor(b: Builder) -> np.ndarray:
    """(H, W) bool: free cells not within HALL_CLEAR in front of any door (where a pillar or partition may stand)."""
    ok = b.grid == FREE
    depth = _cells(HALL_CLEAR)
    for room in b.rooms:
        for door in room.doors:
            r0, r1, c0, c1 = _ahead(door, depth)
            ok[b.m + max(r0, 0) : b.m + r1, b.m + max(c0, 0) : b.m + c1] = False
    return ok


def _partitions(plan: FloorPlan, hall: Room, n: int) -> None:
    """Up to ``n`` free-standing diagonal walls 3–6 m long at 25–65° off the axes, HALL_CLEAR from everything."""
    b, rng, m = plan.builder, plan.builder.rng, plan.builder.m
    clear = _disc(HALL_CLEAR / RES + b.t)
    placed = 0
    for _ in range(12 * n):
        if placed == n:
            return
        half = _cells(rng.uniform(3.0, 6.0)) / 2
        angle = math.radians(rng.uniform(25.0, 65.0) + 90.0 * int(rng.integers(2)))
        margin = int(half) + _cells(HALL_CLEAR) + b.t
        if hall.r1 - hall.r0 <= 2 * margin or hall.c1 - hall.c0 <= 2 * margin:
            return
        r = rng.uniform(hall.r0 + margin, hall.r1 - margin)
        c = rng.uniform(hall.c0 + margin, hall.c1 - margin)
        p = (r - half * math.sin(angle), c - half * math.cos(angle))
        q = (r + half * math.sin(angle), c + half * math.cos(angle))
        mask, _ = _line(b.grid.shape, p, q, m, b.t)
        around = cv2.dilate(mask, clear).astype(bool)
        if not _open_floor(b)[around].all():
            continue
        _diagonal(plan, p, q)
        placed += 1


def _pillars(plan: FloorPlan, hall: Room) -> None:
    """Square pillars 0.4–0.6 m on a 4–6 m grid, each HALL_CLEAR from everything else."""
    b, rng, m = plan.builder, plan.builder.rng, plan.builder.m
    ok = _open_floor(b)
    step, side = _cells(rng.uniform(4.0, 6.0)), _cells(rng.uniform(0.4, 0.6))
    k = _cells(HALL_CLEAR) + 1
    inset = _cells(2.0)
    for r in range(hall.r0 + inset, hall.r1 - inset - side, step):
        for c in range(hall.c0 + inset, hall.c1 - inset - side, step):
            if ok[m + r - k : m + r + side + k, m + c - k : m + c + side + k].all():
                b.grid[m + r : m + r + side, m + c : m + c + side] = OCCUPIED
                ok[m + r - k : m + r + side + k, m + c - k : m + c + side + k] = False


def _furnish(plan: FloorPlan) -> None:
    """Desks and cabinets in the rooms (not the halls), as in an office. The spots are chosen room by room and
    set all at once, checked once (a check per piece, as ``Builder.place`` does, costs seconds on 2000 m²); only
    if together they cut a place off are they placed one at a time."""
    b, rng, m = plan.builder, plan.builder.rng, plan.builder.m
    rects = []
    for room in b.rooms:
        if any(room is hall for hall in plan.halls):
            continue
        area = (room.r1 - room.r0) * (room.c1 - room.c0) * RES**2
        pieces = [(rng.uniform(1.2, 1.6), rng.uniform(0.6, 0.8)) for _ in range(int(area // 10))]  # desks
        pieces += [(rng.uniform(0.8, 1.2), rng.uniform(0.4, 0.6)) for _ in range(int(rng.integers(0, 2)))]
        rects += b.furnish(room, pieces, place=False)
    before, parts = b.grid.copy(), _parts(b.grid)
    for r0, r1, c0, c1 in rects:
        b.grid[m + r0 : m + r1, m + c0 : m + c1] = OCCUPIED
    if _parts(b.grid) != parts or not _connected(b.grid):
        b.grid[...] = before
        for rect in rects:
            b.place(rect)


def main() -> None:
    import time

    for kind, make in (("floor", floor_plan), ("atrium", atrium_plan)):
        for seed in range(1, 4):
            t0 = time.perf_counter()
            plan = make(seed)
            g = plan.builder.grid
            print(f"{kind}:{seed} {plan.builder.w * RES:.1f} x {plan.builder.h * RES:.1f} m, free "
                  f"{(g == FREE).sum() * RES**2:.0f} m², {len(plan.builder.rooms)} rooms, {len(plan.narrow)} narrow, "
                  f"{len(plan.diagonals)} diagonals, {time.perf_counter() - t0:.2f} s")


if __name__ == "__main__":
    main()
