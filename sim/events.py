"""A changing world: boxes that appear, chairs that move, doors that close and open, at seeded times.

A robot that lives in a building for days sees it change. Each change is a
lidar-visible box (``Change``) standing in the world during ``[start, end)``
of simulated time:

- ``box``: a parcel left on the floor at ``start``, taken away at ``end`` (or never);
- ``chair``: a chair that moves — one change stands at its old place until
  ``start``, another at its new place from then (:func:`chair`);
- ``door``: a slab across a doorway, closed during ``[start, end)``; a door
  that opens is one that was closed from 0.

The simulator holds back a change that would land on the robot or shut it
off from its dock (a person does not close a door on a robot, nor drop a
box on it): it appears as soon as it no longer would. The dock's approach
stays clear of random changes (the ``dock_obstacle`` fault is for that).

A world file lists changes under ``events:`` (``{kind, start, end, x, y, yaw,
size: [sx, sy]}``, metres, radians, seconds); :func:`random_changes` draws a
seeded set over a horizon for ``homing bench persist``. Ground truth: only the
simulator and evaluation code may read these.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from homing.robot.turtlebot import BASE_RADIUS
from homing.robot.types import Pose2
from homing.sim.walls import cell_to_world, solid_mask, world_to_cell
from scipy import ndimage

from homing.map_server import OCCUPIED, MapData
from homing.section import Section

KINDS = ("box", "chair", "door")
BOX_SIZE = (0.40, 0.40)  # [m] a parcel
CHAIR_SIZE = (0.45, 0.45)  # [m]
DOOR_THICKNESS = 0.08  # [m]
DOOR_WIDTHS = (0.7, 1.3)  # [m] gaps a door may close: (narrowest, widest) clear width
MIN_ROOM = 2.0  # [m²] a door shuts off at least this much floor (not a corner)
DOCK_CLEARANCE = 2.5  # [m] no random change this close to the dock's staging pose
ROBOT_MARGIN = 0.15  # [m] a change waits while it would stand this close to the robot's rim
FLOOR_CLEARANCE = 0.6  # [m] a random box or chair stands where walls are at least this far
CHAIR_MOVE = 1.5  # [m] a chair moves at most this far


@dataclass(frozen=True)
class Change:
    """A box of ``size`` (sx, sy) [m] centred at (x, y) [m] turned by ``yaw`` [rad], there during [start, end) [s]."""

    kind: str
    start: float
    end: float
    x: float
    y: float
    yaw: float = 0.0
    size: tuple[float, float] = BOX_SIZE

    def __post_init__(self) -> None:
        if self.kind not in KINDS:
            raise ValueError(f"unknown change kind {self.kind!r}; known: {', '.join(KINDS)}")
        if not (self.end > self.start >= 0.0):
            raise ValueError(f"a change needs 0 ≤ start < end, not [{self.start}, {self.end})")
        if not all(0.02 <= s <= 5.0 for s in self.size):
            raise ValueError(f"a change's size must be 0.02–5 m each way, not {self.size}")

    def present(self, t: float) -> bool:
        return self.start <= t < self.end

    def footprint(self, step: float = 0.05) -> np.ndarray:
        """(N, 2) [m] points covering the box, for rasterising and clearance checks."""
        sx, sy = self.size
        u = np.arange(-sx / 2, sx / 2 + 1e-9, step)
        v = np.arange(-sy / 2, sy / 2 + 1e-9, step)
        uu, vv = np.meshgrid(u, v)
        return Pose2(self.x, self.y, self.yaw).transform_points(np.column_stack([uu.ravel(), vv.ravel()]))


def chair(start: float, old: Pose2, new: Pose2) -> list[Change]:
    """A chair standing at ``old`` from the beginning, moved to ``new`` at ``start`` [s]."""
    return [Change("chair", 0.0, start, old.x, old.y, old.theta, CHAIR_SIZE),
            Change("chair", start, math.inf, new.x, new.y, new.theta, CHAIR_SIZE)]


def change_from_section(sec: Section) -> Change:
    """One item of a world file's ``events:`` list."""
    sec.only(("kind", "start", "end", "x", "y", "yaw", "size"))
    kind = sec.string("kind", choices=KINDS)
    size = sec.vector("size", 2) if sec.has("size") else (CHAIR_SIZE if kind == "chair" else BOX_SIZE)
    start = sec.number("start", lo=0.0)
    end = sec.optional_number("end", lo=0.0)
    try:
        return Change(kind, start, math.inf if end is None else end, sec.number("x"), sec.number("y"),
                      sec.number("yaw", 0.0), (float(size[0]), float(size[1])))
    except ValueError as err:
        raise sec.error("kind", str(err)) from None


# ------------------------------------------------------------------------------------- the truth, changed
def rasterise(data: MapData, changes: list[Change]) -> MapData:
    """The floor plan with ``changes`` drawn in as occupied cells (evaluation: the world as it stands)."""
    grid = data.grid.copy()
    h, w = grid.shape
    for ch in changes:
        rows, cols = world_to_cell(data, ch.footprint(data.resolution / 2))
        ok = (rows >= 0) & (rows < h) & (cols >= 0) & (cols < w)
        grid[rows[ok], cols[ok]] = OCCUPIED
    return MapData(grid, data.resolution, data.origin)


def safe_to_place(data: MapData, standing: list[Change], new: Change, robot: Pose2, dock_staging: Pose2) -> bool:
    """Whether ``new`` may appear now: clear of the robot, and the robot still reaches its dock."""
    pts = new.footprint(0.05)
    if np.min(np.hypot(pts[:, 0] - robot.x, pts[:, 1] - robot.y)) < BASE_RADIUS + ROBOT_MARGIN:
        return False
    free = ~solid_mask(rasterise(data, [*standing, new]))
    room = ndimage.distance_transform_edt(free) * data.resolution > BASE_RADIUS + 0.02
    labels, _ = ndimage.label(room)
    cells = [world_to_cell(data, np.array([[p.x, p.y]])) for p in (robot, dock_staging)]
    h, w = free.shape
    ids = [int(labels[r[0], c[0]]) if 0 <= r[0] < h and 0 <= c[0] < w else 0 for r, c in cells]
    return ids[0] != 0 and ids[0] == ids[1]


# ------------------------------------------------------------------------------------ a seeded week of it
def _passable(data: MapData, changes: list[Change]) -> np.ndarray:
    """(H, W) bool: where the robot's centre fits (a rim's width from anything solid), with ``changes`` drawn in."""
    free = ~solid_mask(rasterise(data, changes) if changes else data)
    return np.asarray(ndimage.distance_transform_edt(free) * data.resolution > BASE_RADIUS + 0.02)


def door_spots(data: MapData, reachable: np.ndarray, rng: np.random.Generator, tries: int = 400) -> list[Change]:
    """Doorways of the plan: narrow spots (clear width within DOOR_WIDTHS) that a slab across cuts in two.

    Cut in two for the robot: both sides keep at least ``MIN_ROOM`` of floor its centre can reach.
    """
    free = ~solid_mask(data)
    dist = ndimage.distance_transform_edt(free) * data.resolution
    gy, gx = np.gradient(dist, data.resolution)  # ≈ 1 beside a wall, ≈ 0 on a gap's middle line
    lo, hi = DOOR_WIDTHS[0] / 2, DOOR_WIDTHS[1] / 2
    cand = np.argwhere(reachable & (dist >= lo) & (dist <= hi) & (np.hypot(gx, gy) <= 0.5))
    passable = _passable(data, []) & reachable
    found: list[Change] = []
    min_cells = MIN_ROOM / data.resolution**2
    for k in rng.permutation(len(cand))[:tries]:
        r, c = cand[k]
        xy = cell_to_world(data, np.array([r]), np.array([c]))[0]
        if any(math.hypot(xy[0] - d.x, xy[1] - d.y) < 1.5 for d in found):
            continue
        width = 2 * dist[r, c] + 0.2
        for yaw in (0.0, math.pi / 2, math.pi / 4, -math.pi / 4):
            door = Change("door", 0.0, math.inf, float(xy[0]), float(xy[1]), yaw, (DOOR_THICKNESS, width))
            # Where the robot's centre no longer fits: the slab grown by its radius (a box is close enough).
            grown = Change("door", 0.0, math.inf, door.x, door.y, yaw, (DOOR_THICKNESS + 2 * BASE_RADIUS, width))
            blocked = solid_mask(rasterise(MapData(np.zeros_like(data.grid), data.resolution, data.origin), [grown]))
            labels, n = ndimage.label(passable & ~blocked)
            sizes = np.sort(np.bincount(labels.ravel())[1:]) if n else np.zeros(0)
            if n >= 2 and sizes[-2] >= min_cells:
                found.append(door)
                break
    return found


def random_changes(data: MapData, reachable: np.ndarray, dock_staging: Pose2, seed: int, horizon: float,
                   boxes: int = 6, chairs: int = 4, doors: int = 2) -> list[Change]:
    """A seeded set of changes over ``horizon`` [s]: parcels for hours, chairs moved, doorways closed a while."""
    rng = np.random.default_rng([seed, 7177])
    free = ~solid_mask(data)
    clearance = ndimage.distance_transform_edt(free) * data.resolution
    spots = np.argwhere(reachable & (clearance >= FLOOR_CLEARANCE))
    xy = cell_to_world(data, spots[:, 0], spots[:, 1])
    xy = xy[np.hypot(xy[:, 0] - dock_staging.x, xy[:, 1] - dock_staging.y) > DOCK_CLEARANCE]
    out: list[Change] = []
    if len(xy):
        for _ in range(boxes):
            p = xy[rng.integers(len(xy))]
            start = float(rng.uniform(0.05, 0.9) * horizon)
            end = start + float(rng.uniform(1.0, 12.0)) * 3600.0 if rng.random() < 0.7 else math.inf
            out.append(Change("box", start, end, float(p[0]), float(p[1]), float(rng.uniform(0, math.pi)), BOX_SIZE))
        for _ in range(chairs):
            p = xy[rng.integers(len(xy))]
            near = xy[np.hypot(xy[:, 0] - p[0], xy[:, 1] - p[1]) <= CHAIR_MOVE]
            q = near[rng.integers(len(near))]
            out += chair(float(rng.uniform(0.05, 0.9) * horizon), Pose2(float(p[0]), float(p[1]), 0.0),
                         Pose2(float(q[0]), float(q[1]), float(rng.uniform(0, math.pi))))
    for door in door_spots(data, reachable, rng)[:doors]:
        if math.hypot(door.x - dock_staging.x, door.y - dock_staging.y) <= DOCK_CLEARANCE:
            continue
        start = float(rng.uniform(0.05, 0.8) * horizon)
        out.append(Change("door", start, start + float(rng.uniform(1.0, 8.0)) * 3600.0, door.x, door.y, door.yaw,
                          door.size))
    return out
