"""Generated floor plans that look like buildings: offices, hospital wards, and the SLAM maps a robot makes of them.

The six Explore-Bench blueprints are open halls, loops and corridors; real
buildings are mostly rooms behind doors. These seeded generators give the
kinds exploration fails on, as map_server grids a world can be built from
(``load_world("office:3")``):

- ``office:SEED`` — a 20–30 m × 15–22 m floor: a corridor (straight, with a
  side corridor, or ending short of the far wall: dead ends), rooms on both
  sides, each with one 0.8–1.2 m door onto the corridor or, for rooms with
  no corridor frontage, into a neighbouring room; desks and cabinets
  against the walls;
- ``hospital:SEED`` — a ward 40–54 m long: one corridor lined on both sides
  with small rooms (3–4 m wide, a bed and a cabinet each), a lobby at one
  end, a nurses' bay open onto the corridor;
- ``floor:SEED`` and ``atrium:SEED`` — ~2000 m² floors with 45–60 m corridors, halls, diagonal walls and
  0.5–0.6 m passages, and a pillared hall (:mod:`homing.sim.floors`);
- ``slam_office:SEED`` — a larger office as a real robot's SLAM map shows it
  ("not free" taken as wall, as the simulator does): jagged grey wall
  fringes, chair legs and bins as specks, rooms the mapping robot never
  entered left unknown except the fan its lidar saw through the door, and
  one-cell lidar streaks through gaps.

Every free place is reachable with the robot's footprint (doors at least
``DOOR_MIN`` wide; furniture that would cut a room off is not placed), so
coverage of the reachable free area can reach 100 %. Grids are (H, W) int8,
row 0 at the lowest y, ``RES`` m per cell, origin at the lower-left corner
(``homing.map_server``). Same seed, same plan.
"""

from __future__ import annotations

import argparse
import math
import re
from dataclasses import dataclass, field

import cv2
import numpy as np

from homing.map_server import FREE, OCCUPIED, UNKNOWN, MapData

RES = 0.1  # [m/cell] as the shared blueprints
WALL = 0.2  # [m] wall thickness
MARGIN = 1.0  # [m] unknown around the building
DOOR_MIN, DOOR_MAX = 0.8, 1.2  # [m] door widths (the robot is 0.35 m wide)
DOOR_JAMB = 0.3  # [m] wall kept either side of a door
ROBOT_CLEAR = 0.25  # [m] a place counts as reachable when a disc this wide fits there (footprint 0.19 + margin)
SPEC = re.compile(r"^(office|hospital|slam_office|floor|atrium):(\d{1,9})$")


@dataclass
class Room:
    """A room's inside, in cells: rows [r0, r1), cols [c0, c1); ``front`` the side its door prefers (N, S, E, W)."""

    r0: int
    r1: int
    c0: int
    c1: int
    front: str
    doors: list[tuple[int, int, int, int]] = field(default_factory=list)  # carved rectangles (r0, r1, c0, c1)


class Builder:
    """A floor plan under construction: a grid, its rooms, and a seeded generator."""

    def __init__(self, width: float, height: float, rng: np.random.Generator) -> None:
        self.rng = rng
        self.m = _cells(MARGIN)
        self.t = _cells(WALL)
        self.w, self.h = _cells(width), _cells(height)
        self.grid = np.full((self.h + 2 * self.m, self.w + 2 * self.m), UNKNOWN, np.int8)
        self.grid[self.m : self.m + self.h, self.m : self.m + self.w] = FREE
        self.rooms: list[Room] = []
        self.box(0, self.h, 0, self.w)

    # Coordinates below are building cells (0 at the inside of the outer wall's outer face), walls drawn inward.
    def wall(self, r0: int, r1: int, c0: int, c1: int) -> None:
        m = self.m
        self.grid[m + max(r0, 0) : m + min(r1, self.h), m + max(c0, 0) : m + min(c1, self.w)] = OCCUPIED

    def box(self, r0: int, r1: int, c0: int, c1: int) -> None:
        """Walls of thickness ``t`` just inside the rectangle [r0, r1) × [c0, c1)."""
        t = self.t
        self.wall(r0, r0 + t, c0, c1)
        self.wall(r1 - t, r1, c0, c1)
        self.wall(r0, r1, c0, c0 + t)
        self.wall(r0, r1, c1 - t, c1)

    def room(self, r0: int, r1: int, c0: int, c1: int, front: str) -> Room:
        """A room whose walls are the rectangle's border (shared with its neighbours); returns its inside."""
        self.box(r0, r1, c0, c1)
        room = Room(r0 + self.t, r1 - self.t, c0 + self.t, c1 - self.t, front)
        self.rooms.append(room)
        return room

    def door(self, room: Room, side: str, width_m: float | None = None) -> bool:
        """Carve a door ``width_m`` wide (default: DOOR_MIN..DOOR_MAX at random) through ``side`` of ``room``;
        False if the side is too short."""
        t = self.t
        width = _cells(self.rng.uniform(DOOR_MIN, DOOR_MAX) if width_m is None else width_m)
        jamb = _cells(DOOR_JAMB)
        lo, hi = (room.c0, room.c1) if side in "NS" else (room.r0, room.r1)
        if hi - lo < width + 2 * jamb:
            return False
        a = int(self.rng.integers(lo + jamb, hi - jamb - width + 1))
        if side == "N":
            rect = (room.r1, room.r1 + t, a, a + width)
        elif side == "S":
            rect = (room.r0 - t, room.r0, a, a + width)
        elif side == "E":
            rect = (a, a + width, room.c1, room.c1 + t)
        else:
            rect = (a, a + width, room.c0 - t, room.c0)
        m = self.m
        self.grid[m + rect[0] : m + rect[1], m + rect[2] : m + rect[3]] = FREE
        room.doors.append(rect)
        return True

    def strip(self, r0: int, r1: int, c0: int, c1: int, front: str, widths: tuple[float, float]) -> list[Room]:
        """Cut the block [r0, r1) × [c0, c1) into rooms side by side along its ``front`` (rooms share walls)."""
        along_rows = front in "EW"
        lo, hi = (r0, r1) if along_rows else (c0, c1)
        cuts = [lo]
        while hi - cuts[-1] > _cells(widths[1]):
            cuts.append(cuts[-1] + _cells(self.rng.uniform(*widths)))
        if hi - cuts[-1] < _cells(widths[0]) and len(cuts) > 1:
            cuts.pop()  # a sliver: the last room takes it
        cuts.append(hi)
        rooms = []
        for a, b in zip(cuts[:-1], cuts[1:], strict=False):
            # Neighbours share the wall on their common edge: extend each room by a wall's thickness past it.
            b2 = min(b + self.t, hi)
            rooms.append(self.room(a, b2, c0, c1, front) if along_rows else self.room(r0, r1, a, b2, front))
        return rooms

    def furnish(self, room: Room, pieces: list[tuple[float, float]], place: bool = True) -> list[tuple[int, int, int, int]]:
        """Put each (length, depth) [m] piece against a random wall of ``room``, away from its doors, unless it
        would cut off part of the building from the robot; with ``place`` False only choose the spots. Returns the
        rectangles chosen."""
        # Nor in front of a door into the room from a room off it (``connect`` lists that door in the other
        # room's doors): a cabinet there would narrow a 0.9 m door to 0.5 m (office:3 had one).
        inside = (room.r0, room.r1, room.c0, room.c1)
        ahead = [_ahead(d, _cells(1.0)) for other in self.rooms if other is not room for d in other.doors
                 if _near(d, inside, 1)]
        chosen: list[tuple[int, int, int, int]] = []
        for length, depth in pieces:
            side = str(self.rng.choice(list("NSEW")))
            ln, dp = _cells(length), _cells(depth)
            if side in "NS":
                if room.c1 - room.c0 < ln + 2:
                    continue
                c = int(self.rng.integers(room.c0, room.c1 - ln + 1))
                r = room.r1 - dp if side == "N" else room.r0
                rect = (r, r + dp, c, c + ln)
            else:
                if room.r1 - room.r0 < ln + 2:
                    continue
                r = int(self.rng.integers(room.r0, room.r1 - ln + 1))
                c = room.c1 - dp if side == "E" else room.c0
                rect = (r, r + ln, c, c + dp)
            if any(_near(rect, d, _cells(1.0)) for d in room.doors) or any(_near(rect, a, 0) for a in ahead):
                continue
            if place:
                self.place(rect)
            chosen.append(rect)
        return chosen

    def place(self, rect: tuple[int, int, int, int], value: int = OCCUPIED) -> bool:
        """Set the rectangle to ``value`` unless that splits the footprint-reachable space; True if placed."""
        m = self.m
        view = self.grid[m + rect[0] : m + rect[1], m + rect[2] : m + rect[3]]
        before = view.copy()
        parts = _parts(self.grid)
        view[...] = value
        if _parts(self.grid) != parts or not _connected(self.grid):
            view[...] = before
            return False
        return True

    def connect(self) -> None:
        """Give every room the robot cannot reach yet a door into a reachable neighbour (rooms off rooms)."""
        for _ in range(len(self.rooms)):
            labels = _reach_labels(self.grid)
            main = _largest(labels)
            lonely = [r for r in self.rooms if not (labels[self._inside(r)] == main).any()]
            if not lonely:
                return
            for room in lonely:
                for side in self.rng.permutation(list("NSEW")):
                    if self._beyond_reachable(room, str(side), labels, main) and self.door(room, str(side)):
                        break

    def _inside(self, room: Room) -> tuple[slice, slice]:
        m = self.m
        return slice(m + room.r0, m + room.r1), slice(m + room.c0, m + room.c1)

    def _beyond_reachable(self, room: Room, side: str, labels: np.ndarray, main: int) -> bool:
        m, k = self.m, self.t + _cells(ROBOT_CLEAR) + 1
        rm, cm = (room.r0 + room.r1) // 2, (room.c0 + room.c1) // 2
        r, c = {"N": (room.r1 + k, cm), "S": (room.r0 - 1 - k, cm), "E": (rm, room.c1 + k),
                "W": (rm, room.c0 - 1 - k)}[side]
        h, w = labels.shape
        return 0 <= m + r < h and 0 <= m + c < w and labels[m + r, m + c] == main

    def map(self) -> MapData:
        return MapData(self.grid.copy(), RES, (-(self.w / 2 + self.m) * RES, -(self.h / 2 + self.m) * RES, 0.0))


def _cells(metres: float) -> int:
    return max(1, int(round(metres / RES)))


def _near(a: tuple[int, int, int, int], b: tuple[int, int, int, int], gap: int) -> bool:
    return a[0] < b[1] + gap and b[0] < a[1] + gap and a[2] < b[3] + gap and b[2] < a[3] + gap


def _ahead(door: tuple[int, int, int, int], depth: int) -> tuple[int, int, int, int]:
    """The door's rectangle stretched ``depth`` cells both ways through the wall: where a robot passing it goes."""
    r0, r1, c0, c1 = door
    if r1 - r0 < c1 - c0:  # a door in a wall along the columns: the robot passes it along the rows
        return (r0 - depth, r1 + depth, c0, c1)
    return (r0, r1, c0 - depth, c1 + depth)


def _reach_labels(grid: np.ndarray) -> np.ndarray:
    """(H, W) int32: 8-connected components of the cells where the robot's centre fits (ROBOT_CLEAR from solid)."""
    free = (grid == FREE).astype(np.uint8)
    # A cell is clear when no cell within ROBOT_CLEAR of it is solid: an erosion by that disc, exact in integers
    # (the same cells as scipy's exact distance transform > ROBOT_CLEAR, ~10x faster; OpenCV's precise transform
    # is not used: its last bits depend on where its buffers fall in memory, homing.mapping.distance).
    clear = cv2.erode(free, _disc(ROBOT_CLEAR / RES), borderType=cv2.BORDER_CONSTANT, borderValue=1)
    return cv2.connectedComponents(clear, connectivity=8)[1]


def _largest(labels: np.ndarray) -> int:
    counts = np.bincount(labels.ravel())
    counts[0] = 0
    return int(np.argmax(counts))


def _parts(grid: np.ndarray) -> int:
    """Number of 8-connected free components."""
    return int(cv2.connectedComponents((grid == FREE).astype(np.uint8), connectivity=8)[0]) - 1


def _connected(grid: np.ndarray) -> bool:
    """Whether every free cell is within reach of the footprint's single reachable region: each free component is
    one, and the robot's centre fits everywhere but within ROBOT_CLEAR + a cell of walls."""
    labels = _reach_labels(grid)
    main = _largest(labels)
    if (labels > 0).any() and ((labels > 0) & (labels != main)).any():
        return False
    near = cv2.dilate((labels == main).astype(np.uint8), _disc(ROBOT_CLEAR / RES + 2)).astype(bool)
    return bool(not ((grid == FREE) & ~near).any())


def _disc(radius: float) -> np.ndarray:
    k = int(math.ceil(radius))
    yy, xx = np.mgrid[-k : k + 1, -k : k + 1]
    return (xx * xx + yy * yy <= radius * radius).astype(np.uint8)


# -- the plans ----------------------------------------------------------------------------------------------------
def office_builder(seed: int, size: tuple[float, float, float, float] = (20.0, 30.0, 15.0, 22.0)) -> Builder:
    """An office floor (module doc) of width × height drawn from ``size`` (w_lo, w_hi, h_lo, h_hi) [m]."""
    rng = np.random.default_rng([seed, 16])
    b = Builder(rng.uniform(size[0], size[1]), rng.uniform(size[2], size[3]), rng)
    cw = _cells(rng.uniform(1.6, 2.2))
    cy = int(b.h * rng.uniform(0.38, 0.55))
    layout = str(rng.choice(["straight", "tee", "short"]))
    end = b.w if layout != "short" else b.w - _cells(rng.uniform(4.0, 7.0))
    widths = (3.0, 5.0)
    south = b.strip(0, cy + b.t, 0, end, "N", widths)
    if layout == "tee":
        vx = int(b.w * rng.uniform(0.35, 0.65))
        vw = _cells(rng.uniform(1.6, 2.0))
        b.strip(cy + cw - b.t, b.h, 0, vx + b.t, "E", widths)
        b.strip(cy + cw - b.t, b.h, vx + vw - b.t, b.w, "W", widths)
    else:
        b.strip(cy + cw - b.t, b.h, 0, end, "S", widths)
    if layout == "short":  # the corridor ends at a row of rooms across the building's far end
        b.strip(0, b.h, end - b.t, b.w, "W", (3.5, 6.0))
    for room in list(b.rooms):
        deep = (room.r1 - room.r0) if room.front in "NS" else (room.c1 - room.c0)
        if deep > _cells(7.5) and rng.random() < 0.7:
            _split_deep(b, room)
    for room in list(b.rooms):
        if _faces_corridor(b, room, room.front):
            b.door(room, room.front)
    b.connect()
    for room in b.rooms:
        area = (room.r1 - room.r0) * (room.c1 - room.c0) * RES**2
        pieces = [(rng.uniform(1.2, 1.6), rng.uniform(0.6, 0.8)) for _ in range(int(area // 8))]  # desks
        pieces += [(rng.uniform(0.8, 1.2), rng.uniform(0.4, 0.6)) for _ in range(int(rng.integers(0, 3)))]  # cabinets
        b.furnish(room, pieces)
    del south
    return b


def _split_deep(b: Builder, room: Room) -> None:
    """Split a deep room in two across its depth: the back half is a room off the front one."""
    t = b.t
    if room.front in "NS":
        mid = (room.r0 + room.r1) // 2
        b.wall(mid, mid + t, room.c0, room.c1)
        back = Room(room.r0, mid, room.c0, room.c1, room.front) if room.front == "N" else Room(
            mid + t, room.r1, room.c0, room.c1, room.front)
        if room.front == "N":
            room.r0 = mid + t
        else:
            room.r1 = mid
    else:
        mid = (room.c0 + room.c1) // 2
        b.wall(room.r0, room.r1, mid, mid + t)
        back = Room(room.r0, room.r1, room.c0, mid, room.front) if room.front == "E" else Room(
            room.r0, room.r1, mid + t, room.c1, room.front)
        if room.front == "E":
            room.c0 = mid + t
        else:
            room.c1 = mid
    b.rooms.append(back)


def _faces_corridor(b: Builder, room: Room, side: str) -> bool:
    """Whether free space wider than the robot lies just beyond ``side`` of ``room`` (a corridor, not a room)."""
    m, k = b.m, b.t + 1
    if side in "NS":
        r = room.r1 + k if side == "N" else room.r0 - 1 - k
        cols = slice(m + room.c0, m + room.c1)
        line = b.grid[m + r, cols] if 0 <= m + r < b.grid.shape[0] else np.zeros(0)
    else:
        c = room.c1 + k if side == "E" else room.c0 - 1 - k
        rows = slice(m + room.r0, m + room.r1)
        line = b.grid[rows, m + c] if 0 <= m + c < b.grid.shape[1] else np.zeros(0)
    return bool(len(line)) and bool((line == FREE).mean() > 0.8)


def office(seed: int) -> MapData:
    """An office floor (module doc)."""
    return office_builder(seed).map()


def hospital(seed: int) -> MapData:
    """A hospital ward (module doc): a long corridor lined with small rooms."""
    rng = np.random.default_rng([seed, 17])
    depth = rng.uniform(4.5, 6.0)
    cw_m = rng.uniform(2.0, 2.6)
    b = Builder(rng.uniform(40.0, 54.0), 2 * depth + cw_m, rng)
    cw, d = _cells(cw_m), _cells(depth)
    lobby = _cells(rng.uniform(5.0, 8.0))
    lobby_at_west = bool(rng.random() < 0.5)
    c0, c1 = (lobby, b.w) if lobby_at_west else (0, b.w - lobby)
    if lobby_at_west:
        b.wall(0, b.h, c0, c0 + b.t)
    else:
        b.wall(0, b.h, c1 - b.t, c1)
    rows = [b.strip(0, d + b.t, c0, c1, "N", (3.0, 4.0)), b.strip(d + cw - b.t, b.h, c0, c1, "S", (3.0, 4.0))]
    # The lobby opens onto the corridor through a wide gap in its wall.
    mid = slice(b.m + d + b.t // 2, b.m + d + cw - b.t // 2)
    wall_c = slice(b.m + c0, b.m + c0 + b.t) if lobby_at_west else slice(b.m + c1 - b.t, b.m + c1)
    b.grid[mid, wall_c] = FREE
    # The nurses' bay: one room mid-corridor with its front wall taken away.
    row = rows[int(rng.integers(2))]
    bay = row[len(row) // 2]
    for room in b.rooms:
        if room is bay:
            side = slice(b.m + room.c0, b.m + room.c1)
            r = room.r1 if room.front == "N" else room.r0 - b.t
            b.grid[b.m + r : b.m + r + b.t, side] = FREE
            continue
        b.door(room, room.front)
    b.connect()
    for room in b.rooms:
        if room is not bay:
            b.furnish(room, [(2.0, 1.0), (rng.uniform(0.5, 0.8), 0.5)])  # a bed and a cabinet
    return b.map()


def slam_office(seed: int) -> MapData:
    """A large office as a real robot's SLAM map shows it (module doc), "not free" taken as wall."""
    b = office_builder(seed, (28.0, 38.0, 18.0, 24.0))
    rng = np.random.default_rng([seed, 18])
    g = b.grid
    # Rooms the mapping robot never entered: unknown but for the fan its lidar saw through the door.
    for room in b.rooms:
        if room.doors and rng.random() < 0.25:
            _seen_through_door(b, room, rng)
    # Grey, jagged walls: the fringe of every wall is unknown here and there.
    occ = (g == OCCUPIED).astype(np.uint8)
    fringe = cv2.dilate(occ, np.ones((3, 3), np.uint8)).astype(bool) & (g == FREE)
    rough = fringe & (rng.random(g.shape) < 0.35)
    before = g.copy()
    g[rough] = UNKNOWN
    if not _connected(g):
        g[...] = before
    # Clutter: chair legs and bins, a cell or two each, in rooms (not in doors).
    free_r, free_c = np.nonzero(g == FREE)
    specks = []
    for k in rng.choice(len(free_r), size=min(len(free_r), int(len(free_r) * RES**2 / 3.0)), replace=False):
        r, c = int(free_r[k]) - b.m, int(free_c[k]) - b.m
        s = int(rng.integers(1, 3))
        if not any(_near((r, r + s, c, c + s), d, _cells(1.0)) for room in b.rooms for d in room.doors):
            specks.append((r, r + s, c, c + s))
    before = g.copy()
    for r0, r1, c0, c1 in specks:  # all at once; one at a time only if together they cut a place off
        g[b.m + r0 : b.m + r1, b.m + c0 : b.m + c1] = OCCUPIED
    if not _connected(g):
        g[...] = before
        for rect in specks:
            b.place(rect)
    # Lidar streaks: one-cell rays out through the building's outer wall (windows, glass).
    for _ in range(int(rng.integers(4, 9))):
        _streak(b, rng)
    return b.map()


def _seen_through_door(b: Builder, room: Room, rng: np.random.Generator) -> None:
    """Make ``room`` unknown except the cells a lidar standing outside its first door would see through it."""
    m = b.m
    rs, cs = b._inside(room)
    before = b.grid.copy()
    inside = np.zeros(b.grid.shape, bool)
    inside[rs, cs] = True
    r0, r1, c0, c1 = room.doors[0]
    dr, dc = (r0 + r1) / 2 + m, (c0 + c1) / 2 + m
    room_r, room_c = (rs.start + rs.stop) / 2, (cs.start + cs.stop) / 2
    vr, vc = dr - room_r, dc - room_c  # from the room's centre out through the door
    n = math.hypot(vr, vc)
    eye = (dr + vr / n * _cells(1.5), dc + vc / n * _cells(1.5))
    a = np.linspace(0, 2 * math.pi, 720, endpoint=False)[:, None]
    s = np.arange(0, _cells(6.0), 0.5)[None, :]  # [cells] half-cell steps along each ray
    h, w = b.grid.shape
    r = np.clip((eye[0] + s * np.sin(a)).astype(np.int64), 0, h - 1)
    c = np.clip((eye[1] + s * np.cos(a)).astype(np.int64), 0, w - 1)
    open_ray = np.logical_and.accumulate(b.grid[r, c] == FREE, axis=1)  # up to the first wall
    seen = np.zeros(b.grid.shape, bool)
    seen[r[open_ray], c[open_ray]] = True
    b.grid[inside & ~seen & (b.grid == FREE)] = UNKNOWN
    _prune(b.grid)
    if not _connected(b.grid):
        b.grid[...] = before


def _prune(grid: np.ndarray) -> None:
    """Free cells the robot could not get near (slivers of a fan of rays) become unknown."""
    labels = _reach_labels(grid)
    near = cv2.dilate((labels == _largest(labels)).astype(np.uint8), _disc(ROBOT_CLEAR / RES + 2)).astype(bool)
    grid[(grid == FREE) & ~near] = UNKNOWN


def _streak(b: Builder, rng: np.random.Generator) -> None:
    """A one-cell free ray 1–3 m long from a free cell beside the outer wall, out through it into the unknown."""
    g, m = b.grid, b.m
    side = int(rng.integers(4))
    length = _cells(rng.uniform(1.0, 3.0)) + b.t + 1
    if side < 2:
        c = m + int(rng.integers(b.t + 2, b.w - b.t - 2))
        r = m + b.t if side == 0 else m + b.h - b.t - 1
        step = -1 if side == 0 else 1
        cells = [(r + step * k, c) for k in range(length)]
    else:
        r = m + int(rng.integers(b.t + 2, b.h - b.t - 2))
        c = m + b.t if side == 2 else m + b.w - b.t - 1
        step = -1 if side == 2 else 1
        cells = [(r, c + step * k) for k in range(length)]
    if g[cells[0]] != FREE:
        return
    for rc in cells:
        if 0 <= rc[0] < g.shape[0] and 0 <= rc[1] < g.shape[1]:
            g[rc] = FREE


def floor(seed: int) -> MapData:
    """A ~2000 m² floor: long corridors, halls, diagonal walls, narrow passages (:mod:`homing.sim.floors`)."""
    from homing.sim.floors import floor as make  # floors builds on this module

    return make(seed)


def atrium(seed: int) -> MapData:
    """A pillared hall with diagonal partitions and rooms along two sides (:mod:`homing.sim.floors`)."""
    from homing.sim.floors import atrium as make

    return make(seed)


KINDS = {"office": office, "hospital": hospital, "slam_office": slam_office, "floor": floor, "atrium": atrium}


def generated(spec: str) -> tuple[str, MapData] | None:
    """``(name, plan)`` for a spec ``KIND:SEED`` (``office:3``), or None if ``spec`` is not one."""
    match = SPEC.match(spec)
    if match is None:
        return None
    kind, seed = match.group(1), int(match.group(2))
    return f"{kind}_{seed}", KINDS[kind](seed)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("spec", help="KIND:SEED, KIND one of " + ", ".join(KINDS))
    parser.add_argument("--png", metavar="PATH", help="write a picture of the plan")
    args = parser.parse_args()
    made = generated(args.spec)
    if made is None:
        parser.error(f"not a generated plan: {args.spec}")
    name, plan = made
    print(f"{name}: {plan.width_m:.1f} m × {plan.height_m:.1f} m, free {(plan.grid == FREE).sum() * RES**2:.0f} m²")
    if args.png:
        from homing.atomic import atomic_write

        img = np.where(plan.grid == FREE, 254, np.where(plan.grid == OCCUPIED, 0, 205)).astype(np.uint8)[::-1]
        ok, png = cv2.imencode(".png", cv2.resize(img, None, fx=3, fy=3, interpolation=cv2.INTER_NEAREST))
        atomic_write(args.png, png.tobytes())


if __name__ == "__main__":
    main()
