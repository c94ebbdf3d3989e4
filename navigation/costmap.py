"""A layered 2-D costmap: static layer, obstacle layer from the latest scan, inflation (Nav2 costmap_2d).

The costmap follows Nav2's ``costmap_2d`` (Marder-Eppstein et al., "The Office
Marathon", ICRA 2010; Lu et al., "Layered Costmaps", IROS 2014): three layers
are combined into one (H, W) uint8 cost array in the ``map`` frame.

- **static**: the occupancy grid (FREE 0 / OCCUPIED 100 / UNKNOWN −1,
  row 0 at the lowest y) — occupied cells are ``LETHAL``, unknown cells
  ``NO_INFORMATION``;
- **obstacle**: what the latest scans see, marked at the rays' end points and
  cleared by ray tracing from the laser, kept between scans until cleared
  (by later rays, by :meth:`Costmap.clear`, the "clear costmap" recovery, or
  in a square round a point by :meth:`Costmap.clear_region`);
- **keep-out** and **bumper** layers (:mod:`homing.navigation.layers`):
  what the lidar cannot see — zones the mission forbids (the dock) and arcs
  where a bumper fired — lethal, untouched by the scan's clearing;
- **inflation**: every cell within ``footprint_radius`` (+ padding) of a lethal
  cell is ``INSCRIBED`` (the robot's centre there means contact); beyond it the
  cost decays as ``252·exp(−k·(d − r_inscribed))`` up to ``inflation_radius``,
  exactly Nav2's inflation layer, so planners keep a margin from walls;
- **trail** (:mod:`homing.navigation.trail`): the cells the robot's centre
  has occupied (:meth:`Costmap.mark_trail`) lose the padding, not the
  footprint: a trail cell farther than ``footprint_radius`` from every lethal
  cell and farther than the inscribed radius from every keep-out or bumper
  cell costs ``MAX_NON_OBSTACLE``, not ``INSCRIBED``, so the robot can plan
  back through a door the map redrew a cell narrower once it was through
  (a 0.5 m door drawn 8 cells: its two middle cells are 0.20 m from the
  jambs' centres, the footprint 0.19 m, the inscribed radius 0.215 m). An
  obstacle later put on the trail brings its cells within the footprint
  again: they are ``INSCRIBED`` as any other; keep-out zones and bumper
  marks keep their padding (what the lidar cannot see is not redrawn).

The costmap spans the grid and, while a goal lies beyond it, a box around
that goal (:meth:`Costmap.require`): the cells outside the grid are unknown,
so a planner with ``allow_unknown`` plans into them as Nav2's does.

The TurtleBot is round, so a cell's cost *is* the footprint cost of the robot
centred there; do not use this for non-circular robots.
"""

from __future__ import annotations

import math
import weakref
from dataclasses import dataclass
from typing import Any

import cv2
import numpy as np
from homing.mapping.distance import squared_distance_cells
from homing.mapping.navigable import disc, inscribed_radius
from homing.navigation.layers import (
    BumpMarks,
    Keepout,
    bumper_arc,
    near,
    parse_keepout,
    rasterise_keepout,
)
from homing.navigation.trail import Trail
from homing.robot import Bumpers, Pose2, Scan
from homing.robot.turtlebot import FOOTPRINT_RADIUS

# Nav2's cost values (nav2_costmap_2d/cost_values.hpp)
FREE = 0
MAX_NON_OBSTACLE = 252
INSCRIBED = 253
LETHAL = 254
NO_INFORMATION = 255

INFLATION_RADIUS = 0.55  # [m] Nav2 default
COST_SCALING_FACTOR = 5.0  # [1/m] how fast the inflation cost decays past the inscribed radius
OBSTACLE_MAX_RANGE = 2.5  # [m] scan returns farther than this do not mark (Nav2 default)
RAYTRACE_MAX_RANGE = 3.0  # [m] rays clear the obstacle layer up to this far (Nav2 default)
FILL_SHIFT = 4  # fractional bits of the clearing polygon's vertices (1/16 cell)
CHANGES_KEPT = 64  # versions whose changed cells are remembered (changed_since)
CLEARANCE_MARGIN = 0.45  # [m] beyond the inscribed radius, ``clearance`` stays exact at least this far
                         # (the controllers slow down within 0.3 m of the footprint)


@dataclass(frozen=True)
class CostmapParams:
    """Costmap configuration: footprint, inflation and the scan's marking/clearing ranges [m]."""

    footprint_radius: float = FOOTPRINT_RADIUS  # [m]
    footprint_padding: float | None = None  # [m] None: half a cell, the rasterisation error of walls
    inflation_radius: float = INFLATION_RADIUS  # [m]
    cost_scaling_factor: float = COST_SCALING_FACTOR  # [1/m]
    obstacle_max_range: float = OBSTACLE_MAX_RANGE  # [m]
    raytrace_max_range: float = RAYTRACE_MAX_RANGE  # [m]
    use_scan: bool = True


def grid_arrays(grid: Any) -> tuple[np.ndarray, float, tuple[float, float]]:
    """The (H, W) int8 view, resolution [m] and origin (x, y) [m] of an occupancy grid.

    Accepts :class:`homing.mapping.grid.OccupancyGrid`, :class:`homing.map_server.MapData`
    or anything with the same attributes (``to_int8()``/``int8()``/``data``/``grid``,
    ``resolution``, ``origin`` as a Pose2 or a sequence). The origin's yaw must be 0.
    """
    data = None
    for attr in ("to_int8", "int8", "as_int8", "occupancy"):
        f = getattr(grid, attr, None)
        if callable(f):
            data = f()
            break
    if data is None:
        for attr in ("data", "grid", "values"):
            v = getattr(grid, attr, None)
            if isinstance(v, np.ndarray):
                data = v
                break
    if data is None:
        raise TypeError(f"cannot read an occupancy array from {type(grid).__name__}")
    origin = grid.origin
    if isinstance(origin, Pose2):
        ox, oy, oyaw = origin.x, origin.y, origin.theta
    else:
        seq = tuple(float(v) for v in origin)
        ox, oy, oyaw = seq[0], seq[1], (seq[2] if len(seq) > 2 else 0.0)
    if abs(oyaw) > 1e-9:
        raise ValueError("costmaps need a grid whose origin has zero yaw")
    return np.asarray(data), float(grid.resolution), (ox, oy)


class Costmap:
    """Static + obstacle + inflation layers over one (H, W) grid in the ``map`` frame.

    ``cost`` is (H, W) uint8 with Nav2's values; ``clearance`` is (H, W) float32,
    the distance [m] from each cell centre to the nearest lethal cell centre
    (exact up to the inflation radius; farther cells may after a scan update
    keep a value that is only a lower bound beyond it, see :meth:`_inflate`).
    Cell (r, c) has its centre at ``origin + ((c + ½)·res, (r + ½)·res)``.
    Call :meth:`update_static` with every new grid and :meth:`update_scan`
    with every new scan; both recompute the inflation.
    """

    def __init__(self, params: CostmapParams | None = None) -> None:
        self.params = params or CostmapParams()
        self.resolution = 0.05  # [m]
        self.origin = (0.0, 0.0)  # [m] lower-left corner of cell (0, 0)
        self.static: np.ndarray = np.zeros((0, 0), dtype=np.uint8)
        self.obstacles = np.zeros((0, 0), dtype=bool)
        self.cost: np.ndarray = np.zeros((0, 0), dtype=np.uint8)
        self.clearance = np.zeros((0, 0), dtype=np.float32)
        self.version = 0  # bumped whenever ``cost`` changes
        self._changes: list[tuple[int, tuple[int, int, int, int] | None]] = []  # (version, cells it changed)
        self.keepout: list[Keepout] = []
        self.bumps = BumpMarks()
        self.trail = Trail()  # where the robot's centre has been (map frame): it fits there (module doc)
        self.required: tuple[float, float, float, float] | None = None  # [m] box the costmap must span
        self._grid: tuple[np.ndarray, float, tuple[float, float]] | None = None  # the last static grid as given
        self._keepout_mask: np.ndarray | None = None
        self._keepout_key: tuple[object, ...] | None = None
        self._lut = np.zeros(0, dtype=np.uint8)
        self._lut_key: tuple[float, ...] | None = None
        # The grid update_static took last (a weak reference) and its version then: its changes since are read
        self._static_from: tuple[weakref.ReferenceType[Any], int] | None = None

    # -- geometry -----------------------------------------------------------------
    @property
    def shape(self) -> tuple[int, int]:
        return (int(self.static.shape[0]), int(self.static.shape[1]))

    @property
    def inscribed_radius(self) -> float:
        """Centre distance [m] to a lethal cell centre under which the robot touches it."""
        pad = self.params.footprint_padding
        if pad is None:  # the one rule of homing.mapping.navigable
            return inscribed_radius(self.resolution, self.params.footprint_radius)
        return self.params.footprint_radius + pad

    def world_to_cell(self, xy: np.ndarray) -> np.ndarray:
        """(N, 2) map-frame points [m] → (N, 2) int (row, col), possibly outside the grid."""
        p = np.asarray(xy, dtype=float).reshape(-1, 2)
        col = np.floor((p[:, 0] - self.origin[0]) / self.resolution).astype(np.int64)
        row = np.floor((p[:, 1] - self.origin[1]) / self.resolution).astype(np.int64)
        return np.column_stack([row, col])

    def cell_to_world(self, rc: np.ndarray) -> np.ndarray:
        """(N, 2) (row, col) cells (float allowed) → (N, 2) map-frame points of their centres [m]."""
        c = np.asarray(rc, dtype=float).reshape(-1, 2)
        x = self.origin[0] + (c[:, 1] + 0.5) * self.resolution
        y = self.origin[1] + (c[:, 0] + 0.5) * self.resolution
        return np.column_stack([x, y])

    def inside(self, rc: np.ndarray) -> np.ndarray:
        """(N,) bool: which (row, col) cells lie in the grid."""
        rc = np.asarray(rc).reshape(-1, 2)
        h, w = self.shape
        return (rc[:, 0] >= 0) & (rc[:, 0] < h) & (rc[:, 1] >= 0) & (rc[:, 1] < w)

    def cost_at(self, xy: np.ndarray) -> np.ndarray:
        """(N,) uint8 costs at map-frame points [m]; ``NO_INFORMATION`` outside the grid."""
        rc = self.world_to_cell(xy)
        out = np.full(len(rc), NO_INFORMATION, dtype=np.uint8)
        ok = self.inside(rc)
        out[ok] = self.cost[rc[ok, 0], rc[ok, 1]]
        return out

    def changed_since(self, version: int) -> tuple[int, int, int, int] | None:
        """(r0, r1, c0, c1): a box holding every cell whose ``cost`` or ``clearance`` changed after ``version``
        (empty when none did), or None when that is not known (the whole costmap was redone, or ``version`` is
        older than the changes kept): what a reader caching arrays derived cell by cell must redo."""
        if version >= self.version:
            return (0, 0, 0, 0)
        since = [box for v, box in self._changes if v > version]
        if len(since) != self.version - version or any(b is None for b in since):
            return None
        boxes = [b for b in since if b is not None]
        return (min(b[0] for b in boxes), max(b[1] for b in boxes), min(b[2] for b in boxes),
                max(b[3] for b in boxes))

    # -- layers -------------------------------------------------------------------
    def update_static(self, grid: Any) -> None:
        """Take a new occupancy grid as the static layer (see :func:`grid_arrays`).

        A grid that says where it changed (``version`` and ``changed_since``, as
        :class:`homing.mapping.grid.OccupancyGrid` does) and was the one taken last is read again only there.
        """
        data, res, origin = grid_arrays(grid)
        version = getattr(grid, "version", None)
        last, region = self._static_from, None
        source = last[0]() if last is not None else None
        if last is not None and source is not None and source is grid and version is not None:
            region = getattr(source, "changed_since", lambda _: None)(last[1])
        self._set_static(data, res, origin, region)
        self._static_from = (weakref.ref(grid), version) if version is not None else None

    def set_static(self, data: np.ndarray, resolution: float, origin: tuple[float, float]) -> None:
        """Static layer from an (H, W) int8 grid (≥ 50 lethal, < 0 unknown), resolution [m], origin (x, y) [m].

        If the grid moved or grew, obstacle marks are carried over at their map positions.
        While :attr:`required` reaches beyond the grid, the layer is padded with unknown cells to span it.
        """
        self._static_from = None  # not a grid update_static knows the changes of
        self._set_static(data, resolution, origin)

    def _set_static(self, data: np.ndarray, resolution: float, origin: tuple[float, float],
                    region: tuple[int, int, int, int] | None = None) -> None:
        """:meth:`set_static`; ``region`` (row0, row1, col0, col1) of ``data``: the only cells that can differ
        from the data taken last (None: any)."""
        data = np.asarray(data)
        self._grid = (data, float(resolution), (float(origin[0]), float(origin[1])))
        given = (float(origin[0]), float(origin[1]))
        data, origin = self._pad_to_required(data, float(resolution), given)
        same = (
            data.shape == self.static.shape
            and resolution == self.resolution
            and origin == self.origin
        )
        if same and region is not None:
            # Only the cells the grid changed since: classified again there alone (on a large floor, a window).
            below = int(round((given[1] - origin[1]) / resolution))
            left = int(round((given[0] - origin[0]) / resolution))
            r0, r1, c0, c1 = region[0] + below, region[1] + below, region[2] + left, region[3] + left
            if r1 <= r0 or c1 <= c0:
                return
            window = data[r0:r1, c0:c1]
            static = np.zeros(window.shape, dtype=np.uint8)
            static[window < 0] = NO_INFORMATION
            static[window >= 50] = LETHAL
            changed = self.static[r0:r1, c0:c1] != static
            if changed.any():
                self.static[r0:r1, c0:c1] = static
                rows, cols = np.flatnonzero(changed.any(axis=1)), np.flatnonzero(changed.any(axis=0))
                self._inflate((r0 + int(rows[0]), r0 + int(rows[-1]) + 1, c0 + int(cols[0]), c0 + int(cols[-1]) + 1))
            return
        old_pts = self.cell_to_world(np.argwhere(self.obstacles)) if not same and self.obstacles.any() else None
        static = np.zeros(data.shape, dtype=np.uint8)
        static[data < 0] = NO_INFORMATION
        static[data >= 50] = LETHAL
        old, self.static = self.static, static
        if not same:
            self.resolution = float(resolution)
            self.origin = (float(origin[0]), float(origin[1]))
            self.obstacles = np.zeros(data.shape, dtype=bool)
            if old_pts is not None:
                self._mark(old_pts)
            self._inflate()
            return
        # The same lattice: only the cells whose static value changed (the few metres a second of mapping
        # touches) are re-inflated, round the box that holds them, not the whole floor.
        changed = old != static
        if changed.any():
            rows, cols = np.flatnonzero(changed.any(axis=1)), np.flatnonzero(changed.any(axis=0))
            self._inflate((int(rows[0]), int(rows[-1]) + 1, int(cols[0]), int(cols[-1]) + 1))

    def require(self, xmin: float, ymin: float, xmax: float, ymax: float) -> None:
        """Make the costmap span the box [m] (``map``) as well as the grid; cells beyond the grid are unknown."""
        box = (float(xmin), float(ymin), float(xmax), float(ymax))
        if box != self.required:
            self.required = box
            if self._grid is not None:
                self._set_static(*self._grid)

    def release(self) -> None:
        """Drop the :meth:`require` box: the costmap shrinks back to the grid at the next static update."""
        if self.required is not None:
            self.required = None
            if self._grid is not None:
                self._set_static(*self._grid)

    def _pad_to_required(self, data: np.ndarray, res: float,
                         origin: tuple[float, float]) -> tuple[np.ndarray, tuple[float, float]]:
        """Pad ``data`` with unknown (−1) on the grid's own lattice so that it spans :attr:`required`."""
        if self.required is None:
            return data, origin
        xmin, ymin, xmax, ymax = self.required
        h, w = data.shape
        ox, oy = origin
        left = max(0, math.ceil((ox - xmin) / res - 1e-9))
        below = max(0, math.ceil((oy - ymin) / res - 1e-9))
        right = max(0, math.ceil((xmax - (ox + w * res)) / res - 1e-9))
        above = max(0, math.ceil((ymax - (oy + h * res)) / res - 1e-9))
        if not (left or below or right or above):
            return data, origin
        padded = np.pad(data, ((below, above), (left, right)), constant_values=-1)
        return padded, (ox - left * res, oy - below * res)

    def set_keepout(self, zones: object) -> None:
        """Replace the keep-out zones (:func:`homing.navigation.layers.parse_keepout` spellings, ``map`` frame)."""
        parsed = parse_keepout(zones)
        if len(parsed) == len(self.keepout) and all(
                a.radius == b.radius and np.array_equal(a.points, b.points)
                for a, b in zip(parsed, self.keepout, strict=True)):
            return
        self.keepout = parsed
        self._keepout_key = None
        if self.static.size:
            self._inflate()

    def mark_bumpers(self, bumpers: Bumpers, pose_in_map: Pose2, stamp: float) -> bool:
        """Mark the rim arcs of the pressed bumpers of a robot at ``pose_in_map``; whether any was pressed."""
        pts = bumper_arc(bumpers, pose_in_map)
        if len(pts) == 0:
            return False
        self.bumps.add(pts, stamp)
        if self.static.size:
            self._inflate()
        return True

    def forget_bumps(self, now: float) -> None:
        """Drop bumper marks older than their memory at ``now`` [s]."""
        if self.bumps.forget(now) and self.static.size:
            self._inflate()

    def mark_trail(self, pose_in_map: Pose2) -> bool:
        """The robot's centre is at ``pose_in_map``: add its cell (and the line from the last pose) to the trail;
        whether a cell's cost changed. Cheap in open space: only new trail cells within the padding of a wall
        are costed again (module doc), round them alone."""
        if self.static.size:
            self.trail.anchor(self.origin, self.resolution)
        box = self.trail.mark(pose_in_map.x, pose_in_map.y)
        if box is None or not self.static.size:
            return False
        lo = self.world_to_cell(np.array([box[0], box[1]]) + 0.5 * self.resolution)[0]
        hi = self.world_to_cell(np.array([box[2], box[3]]) - 0.5 * self.resolution)[0]
        h, w = self.shape
        r0, r1 = max(int(lo[0]), 0), min(int(hi[0]) + 1, h)
        c0, c1 = max(int(lo[1]), 0), min(int(hi[1]) + 1, w)
        if r1 <= r0 or c1 <= c0 or not (self.cost[r0:r1, c0:c1] == INSCRIBED).any():
            return False
        before = self.cost[r0:r1, c0:c1].copy()
        self._inflate((r0, r1, c0, c1))
        return bool((before != self.cost[r0:r1, c0:c1]).any())

    def virtual_points(self, pose: Pose2, radius: float) -> np.ndarray:
        """(M, 2) [m] ``map`` points of what the lidar cannot see (keep-out edges, bumper marks) within ``radius``."""
        return near([*(z.edge() for z in self.keepout), self.bumps.points], pose, radius)

    def update_scan(self, scan: Scan, pose_in_map: Pose2) -> None:
        """Clear the obstacle layer along the scan's rays and mark their end points (map frame)."""
        if not self.params.use_scan or self.static.size == 0:
            return
        ok = scan.valid()
        if not ok.any():
            return
        sensor = pose_in_map.compose(scan.laser_pose)
        ang = scan.angles[ok] + sensor.theta
        rng = scan.ranges[ok].astype(float)
        # Everything this scan can change lies within its reach of the sensor: a window, not the whole map.
        box = self._window(sensor.x, sensor.y, max(self.params.raytrace_max_range, self.params.obstacle_max_range))
        r0, r1, c0, c1 = box
        before = self.obstacles[r0:r1, c0:c1].copy()
        # Clearing: every cell a ray crosses before its end point is free of obstacles. The rays sweep a
        # star-shaped polygon round the sensor (a ray with no return closes it back to the sensor), so the
        # cleared cells are those whose centres the polygon covers: one raster fill instead of ray sampling.
        reach = np.where(ok, np.minimum(scan.ranges.astype(float), self.params.raytrace_max_range) - self.resolution,
                         0.0)
        reach = np.maximum(reach, 0.0)
        all_ang = scan.angles + sensor.theta
        px = (sensor.x + reach * np.cos(all_ang) - self.origin[0]) / self.resolution - 0.5 - c0
        py = (sensor.y + reach * np.sin(all_ang) - self.origin[1]) / self.resolution - 0.5 - r0
        poly = np.round(np.column_stack([px, py]) * (1 << FILL_SHIFT)).astype(np.int32)
        cleared = np.zeros((r1 - r0, c1 - c0), dtype=np.uint8)
        cv2.fillPoly(cleared, [poly], 1, lineType=cv2.LINE_8, shift=FILL_SHIFT)
        self.obstacles[r0:r1, c0:c1][cleared.astype(bool)] = False
        # Marking: end points within the marking range.
        near = rng <= self.params.obstacle_max_range
        ends = np.column_stack([sensor.x + rng * np.cos(ang), sensor.y + rng * np.sin(ang)])[near]
        self._mark(ends)
        # Only a change of the lethal cells changes the cost: a mark on a wall the static layer already has
        # changes nothing, and the inflation is redone round the cells that did change, not the whole window.
        changed = (before != self.obstacles[r0:r1, c0:c1]) & (self.static[r0:r1, c0:c1] != LETHAL)
        if changed.any():
            rows = np.flatnonzero(changed.any(axis=1))
            cols = np.flatnonzero(changed.any(axis=0))
            self._inflate((r0 + int(rows[0]), r0 + int(rows[-1]) + 1, c0 + int(cols[0]), c0 + int(cols[-1]) + 1))

    def _window(self, x: float, y: float, reach: float) -> tuple[int, int, int, int]:
        """(r0, r1, c0, c1): the cells within ``reach`` [m] of (x, y) [m], clipped to the costmap."""
        h, w = self.shape
        n = int(math.ceil(reach / self.resolution)) + 1
        rc = self.world_to_cell(np.array([x, y]))[0]
        return (max(int(rc[0]) - n, 0), min(int(rc[0]) + n + 1, h), max(int(rc[1]) - n, 0), min(int(rc[1]) + n + 1, w))

    def clear(self) -> None:
        """Empty the obstacle layer and the bumper marks (Nav2's ClearEntireCostmap); static and keep-out stay."""
        self.bumps.clear()
        if self.obstacles.size:
            self.obstacles[:] = False
            self._inflate()

    def clear_region(self, x: float, y: float, size: float, inside: bool = True) -> int:
        """Clear the obstacle layer in (or outside) a ``size`` [m] square centred on (x, y) [m] ``map``.

        Nav2's ``clear_around_*`` / ``clear_except_*`` costmap services
        (``nav2_costmap_2d/clear_costmap_service.cpp``): the square's sides are
        ``size`` long, ``size / 2`` either side of the point, axis-aligned in
        ``map``; a cell belongs to it when its centre does. ``inside=True``
        clears the square (ClearCostmapAroundRobot/AroundPose),
        ``inside=False`` everything but the square (ClearCostmapExceptRegion).
        Like Nav2's services, only the layers the sensors fill are cleared
        (obstacle marks and bumper marks); the static map and keep-out zones
        stay. Returns how many obstacle cells were cleared.
        """
        half = max(float(size), 0.0) / 2.0
        if self.bumps.points.size:
            p = self.bumps.points
            within = (np.abs(p[:, 0] - x) <= half) & (np.abs(p[:, 1] - y) <= half)
            keep = ~within if inside else within
            self.bumps.points, self.bumps.stamps = p[keep], self.bumps.stamps[keep]
        if not self.obstacles.size:
            return 0
        h, w = self.shape
        cx = self.origin[0] + (np.arange(w) + 0.5) * self.resolution
        cy = self.origin[1] + (np.arange(h) + 0.5) * self.resolution
        square = (np.abs(cy - y) <= half)[:, None] & (np.abs(cx - x) <= half)[None, :]
        target = self.obstacles & (square if inside else ~square)
        cleared = int(target.sum())
        self.obstacles[target] = False
        self._inflate()
        return cleared

    def _mark(self, pts: np.ndarray) -> None:
        rc = self.world_to_cell(pts)
        rc = rc[self.inside(rc)]
        self.obstacles[rc[:, 0], rc[:, 1]] = True

    def _inflate(self, box: tuple[int, int, int, int] | None = None) -> None:
        """Combine the layers and inflate lethal cells by the footprint and the decay.

        With ``box`` (r0, r1, c0, c1), only the lethal cells in it changed:
        the cells within ``CLEARANCE_HORIZON`` of it are recomputed, from the
        layers within twice that, which holds every lethal cell that can be
        nearer to them than the horizon. Beyond the horizon ``clearance`` is
        then only known to be at least the horizon (inflation ends before it).
        """
        h, w = self.shape
        changed: tuple[int, int, int, int] | None = None
        if box is None or self.clearance.shape != (h, w):
            self.clearance, self.cost = self._inflated(0, h, 0, w)
        else:
            n = int(math.ceil(self._horizon() / self.resolution)) + 1
            r0, r1, c0, c1 = box
            a = (max(r0 - n, 0), min(r1 + n, h), max(c0 - n, 0), min(c1 + n, w))  # cells to update
            b = (max(a[0] - n, 0), min(a[1] + n, h), max(a[2] - n, 0), min(a[3] + n, w))  # layers they depend on
            d, cost = self._inflated(*b)
            inner = (slice(a[0] - b[0], a[1] - b[0]), slice(a[2] - b[2], a[3] - b[2]))
            self.clearance[a[0]:a[1], a[2]:a[3]] = d[inner]
            self.cost[a[0]:a[1], a[2]:a[3]] = cost[inner]
            changed = a
        self.version += 1
        self._changes.append((self.version, changed))
        del self._changes[:-CHANGES_KEPT]

    def _horizon(self) -> float:
        """[m] how far a lethal cell's influence on cost and on the controllers' clearance checks reaches."""
        return max(self.params.inflation_radius, self.inscribed_radius + CLEARANCE_MARGIN)

    def _inflated(self, r0: int, r1: int, c0: int, c1: int) -> tuple[np.ndarray, np.ndarray]:
        """(clearance [m] float32, cost uint8) over the cells [r0:r1, c0:c1] from the layers there."""
        window = (slice(r0, r1), slice(c0, c1))
        static = self.static[window]
        unseen = self._unseen_layer(window)
        lethal = (static == LETHAL) | self.obstacles[window] | unseen
        if lethal.any():
            # The exact Euclidean distance to the nearest lethal cell, so the squared distance in cells is an
            # integer: the cost is a table lookup, not an exponential per cell. (The squared distance itself
            # indexes the table: the distance squared and rounded again gives it back, exactly, up to 2^22 cells²,
            # far past the table's end.)
            squared = squared_distance_cells((~lethal).view(np.uint8))
            lut = self._cost_table()
            cost = lut[np.minimum(squared, len(lut) - 1).astype(np.intp)]
            d = np.sqrt(squared) * np.float32(self.resolution)
            self._lift_trail(window, cost, d, unseen)
        else:
            d = np.full(lethal.shape, np.inf, dtype=np.float32)
            cost = np.zeros(lethal.shape, dtype=np.uint8)
        # Unknown cells stay unknown unless the robot would touch something there.
        cost[(static == NO_INFORMATION) & (cost < INSCRIBED)] = NO_INFORMATION
        return d, cost

    def _lift_trail(self, window: tuple[slice, slice], cost: np.ndarray, d: np.ndarray, unseen: np.ndarray) -> None:
        """On the trail (module doc), ``INSCRIBED`` cells whose centre lies farther than the footprint's radius from
        every lethal cell (``d`` [m]) and farther than the inscribed radius from every keep-out or bumper cell
        (``unseen``) cost ``MAX_NON_OBSTACLE``: the robot's centre has been there, so the half cell of padding the
        wall's rasterisation asks for is not needed; the footprint itself stays (a wall or an obstacle drawn
        within it, since or before, is contact). ``cost`` and ``d`` over ``window``, changed in place."""
        inscribed = cost == INSCRIBED
        if not self.trail.version or not inscribed.any():
            return
        h, w = cost.shape
        origin = (self.origin[0] + (window[1].start or 0) * self.resolution,
                  self.origin[1] + (window[0].start or 0) * self.resolution)
        lift = inscribed & (d > self.params.footprint_radius) & self.trail.mask(origin, self.resolution, (h, w))
        if lift.any() and unseen.any():
            lift &= ~cv2.dilate(unseen.astype(np.uint8), disc(self.inscribed_radius / self.resolution)).astype(bool)
        cost[lift] = MAX_NON_OBSTACLE

    def _cost_table(self) -> np.ndarray:
        """Cost by squared distance in cells (Nav2's inflation), cached for the costmap's parameters."""
        key = (self.resolution, self.inscribed_radius, self.params.inflation_radius, self.params.cost_scaling_factor)
        if self._lut_key != key:
            n = int(math.ceil(self.params.inflation_radius / self.resolution)) + 2
            d = np.sqrt(np.arange(n * n + 1, dtype=np.float64)) * self.resolution
            self._lut = inflation_cost(d, *key[1:])
            self._lut_key = key
        return self._lut

    def _unseen_layer(self, window: tuple[slice, slice]) -> np.ndarray:
        """(h, w) bool over ``window``: keep-out zones (cached per geometry) and bumper marks."""
        key = (self.shape, self.resolution, self.origin)
        if self._keepout_key != key:
            self._keepout_mask = (rasterise_keepout(self.keepout, self.shape, self.resolution, self.origin)
                                  if self.keepout else np.zeros(self.shape, dtype=bool))
            self._keepout_key = key
        assert self._keepout_mask is not None
        layer = self._keepout_mask[window]
        if not len(self.bumps):
            return layer
        layer = layer.copy()
        rc = self.world_to_cell(self.bumps.points) - np.array([window[0].start, window[1].start])
        ok = (rc[:, 0] >= 0) & (rc[:, 0] < layer.shape[0]) & (rc[:, 1] >= 0) & (rc[:, 1] < layer.shape[1])
        layer[rc[ok, 0], rc[ok, 1]] = True
        return layer


def inflation_cost(distance: np.ndarray, inscribed_radius: float, inflation_radius: float,
                   scaling: float) -> np.ndarray:
    """Nav2's inflation cost of cells at ``distance`` [m] from the nearest lethal cell centre.

    0 → LETHAL; ≤ inscribed radius → INSCRIBED; up to ``inflation_radius`` →
    ``252·exp(−scaling·(d − r_inscribed))``; beyond → FREE. Returns uint8, same shape.
    """
    d = np.asarray(distance, dtype=np.float64)
    decay = np.floor(MAX_NON_OBSTACLE * np.exp(-scaling * np.maximum(d - inscribed_radius, 0.0)))
    cost = np.where(d <= inflation_radius, decay, FREE).astype(np.uint8)
    cost[d <= inscribed_radius] = INSCRIBED
    cost[d <= 0.0] = LETHAL
    return cost
