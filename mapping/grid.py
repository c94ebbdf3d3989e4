"""Log-odds occupancy grid with vectorised ray tracing (Moravec & Elfes 1985; Thrun et al., Probabilistic Robotics ch. 9).

Each cell holds the log-odds of being occupied. A scan taken from a known
pose lowers the log-odds of every cell its rays cross and raises it at each
ray's end point; a cell is updated at most once per scan (so a cell near the
robot is not cleared 50 times by one sweep). Rays are traced all at once by
sampling every ray at half-cell steps — a (rays × samples) array, no Python
loop over cells or rays.

The grid either grows (its extent doubles in chunks when a scan reaches past
an edge, like gmapping's growing map) or keeps a fixed extent and drops what
falls outside. :meth:`OccupancyGrid.data` is the map_server / ROS
``OccupancyGrid`` view: (H, W) int8, ``FREE`` 0, ``OCCUPIED`` 100,
``UNKNOWN`` −1, row 0 at the lowest y, origin at the lower-left corner of
cell (0, 0), no rotation.

Do not use this for 3-D or for sonar-like wide beams: the inverse sensor model
here is a thin ray.
"""

from __future__ import annotations

import math

import numpy as np
from homing.robot import Pose2, Scan

from homing.map_server import FREE, OCCUPIED, UNKNOWN, MapData

L_OCC = 0.85  # log-odds added at a ray's end point (p ≈ 0.70)
L_FREE = -0.25  # log-odds added to a cell a ray passes through (p ≈ 0.44)
# A wall seen only along it, as a robot driving beside it sees it far ahead, gets a return every metre or so, and
# the rays to those returns cross its cells between them (a 5 cm cell is 70 cm of ray at 4°, and tracking draws the
# wall a centimetre or two off from scan to scan): a return must outweigh a few such crossings. At -0.40 (hit to
# miss 2.1 : 1; GMapping's count threshold is about 3 : 1, Cartographer's 0.55 / 0.49 odds about 5 : 1) a hall's
# wall seen that way was worn to free in seconds (atrium:3, nearest, seed 1): the scans then misfit at the right pose,
# the robot was counted lost, the whole map's look put it 9 m away and turned, and exploration said done at 15 %.
L_MIN = -4.0  # clamp, so a cell can still change its mind (p ≈ 0.018)
L_MAX = 4.0  # clamp (p ≈ 0.982)
T_OCC = 0.40  # log-odds above which a cell reads OCCUPIED
T_FREE = -0.20  # log-odds below which a cell reads FREE
GROW_CHUNK = 4.0  # [m] margin added on each side that needs to grow
NO_RETURN_NEIGHBOURS = 2  # rays each side whose returns bound how far a no-return ray clears
MIN_RETURN_SHARE = 0.5  # in a scan with fewer returns, rays without return clear only up to the map's walls,
OPEN_REACH = 2.0  # [m] ... and no farther than this from the lidar
WALL_MARGIN = 0.1  # [m] ... stopping this short of the first wall the map holds on their way ...
DROPOUT_SHARE = 0.5  # ... unless the scan lost more than this share of the returns the map expects: nothing
CHANGES_KEPT = 16  # changes whose extent is remembered (OccupancyGrid.changed_since)
NOTHING = (math.inf, math.inf, -math.inf, -math.inf)  # the extent of a change that changed no cell's value


class OccupancyGrid:
    """A 2-D log-odds occupancy grid in the ``map`` frame.

    ``resolution`` [m/cell]; ``origin`` (x, y) [m] of the lower-left corner
    of cell (row 0, col 0); ``shape`` (H, W) cells. ``grow=True`` enlarges the
    grid when a scan reaches past its edge (the origin moves; world
    coordinates of what is already mapped never change); ``grow=False``
    ignores what falls outside.
    """

    def __init__(
        self,
        resolution: float = 0.05,
        origin: tuple[float, float] = (-5.0, -5.0),
        shape: tuple[int, int] = (200, 200),
        grow: bool = True,
    ) -> None:
        if resolution <= 0:
            raise ValueError("resolution must be positive")
        self.resolution = float(resolution)
        self.origin = (float(origin[0]), float(origin[1]))
        self.grow = grow
        self.logodds = np.zeros(shape, dtype=np.float32)
        self.version = 0  # bumped on every change, so readers can cache derived arrays
        self._data: np.ndarray | None = None
        self._data_key = (0, self.origin)  # (version, origin) _data was computed at
        self._old: tuple[np.ndarray, int, tuple[float, float]] | None = None  # the last _data, its version, origin
        # (version, extent (xmin, ymin, xmax, ymax) [m, map] of the cells the change may have changed, or None: any)
        self._changes: list[tuple[int, tuple[float, float, float, float] | None]] = []

    # ------------------------------------------------------------------ views
    @property
    def shape(self) -> tuple[int, int]:
        return (int(self.logodds.shape[0]), int(self.logodds.shape[1]))

    @property
    def data(self) -> np.ndarray:
        """(H, W) int8 map_server view: FREE 0, OCCUPIED 100, UNKNOWN −1 (cached until the next update).

        A new array after each update (an array read before is never changed), recomputed only where the
        updates since the last one were (:meth:`changed_since`).
        """
        if self._data is None:
            old, region = self._old, None
            if old is not None and old[0].shape == self.logodds.shape and old[2] == self.origin:
                region = self.changed_since(old[1])
            if old is None or region is None:
                out = _classify(self.logodds)
            else:
                out = old[0].copy()
                r0, r1, c0, c1 = region
                out[r0:r1, c0:c1] = _classify(self.logodds[r0:r1, c0:c1])
            self._data, self._data_key, self._old = out, (self.version, self.origin), None
        return self._data

    def changed_extent(self, version: int) -> tuple[float, float, float, float] | None:
        """(xmin, ymin, xmax, ymax) [m, map] holding every cell changed since ``version`` (None: not known;
        xmin > xmax: none)."""
        if version >= self.version:
            return NOTHING
        since = [box for v, box in self._changes if v > version]
        boxes = [box for box in since if box is not None]
        if len(since) != self.version - version or len(boxes) != len(since):
            return None
        return (min(b[0] for b in boxes), min(b[1] for b in boxes), max(b[2] for b in boxes), max(b[3] for b in boxes))

    def changed_since(self, version: int) -> tuple[int, int, int, int] | None:
        """Cells (row0, row1, col0, col1), as slices' bounds, holding every cell changed since ``version``.

        None when that is not known (a change from outside, or too long ago): assume any cell changed. The
        bounds are in the grid's present cells: a grid that grew since has a new origin and shape.
        """
        extent = self.changed_extent(version)
        if extent is None:
            return None
        xmin, ymin, xmax, ymax = extent
        if xmin > xmax or ymin > ymax:
            return (0, 0, 0, 0)
        h, w = self.shape
        r0, c0 = self.world_to_cell(xmin, ymin)
        r1, c1 = self.world_to_cell(xmax, ymax)
        # A cell more each side: a point on a cell's boundary may have been rounded into either.
        return (min(max(int(r0) - 1, 0), h), min(max(int(r1) + 2, 0), h),
                min(max(int(c0) - 1, 0), w), min(max(int(c1) + 2, 0), w))

    def probability(self) -> np.ndarray:
        """(H, W) float32 occupancy probability (0.5 where never observed)."""
        return (1.0 / (1.0 + np.exp(-self.logodds))).astype(np.float32)

    def to_map_data(self) -> MapData:
        """The map_server view with its resolution and origin, for :mod:`homing.map_server`."""
        return MapData(self.data.copy(), self.resolution, (self.origin[0], self.origin[1], 0.0))

    @classmethod
    def from_map_data(cls, m: MapData, grow: bool = True) -> OccupancyGrid:
        """A grid whose cells read as ``m`` does (log-odds set to the clamps); ``m``'s yaw must be 0."""
        if abs(m.origin[2]) > 1e-9:
            raise ValueError("rotated map origins are not supported")
        g = cls(m.resolution, (m.origin[0], m.origin[1]), m.grid.shape, grow)
        g.logodds[m.grid == FREE] = L_MIN
        g.logodds[m.grid >= 65] = L_MAX
        g._touch()
        return g

    def copy(self) -> OccupancyGrid:
        """An independent grid with the same cells, version and change history; its map_server view is this
        grid's (worked out here only where it changed, and shared: a view handed out is never changed)."""
        g = OccupancyGrid(self.resolution, self.origin, self.shape, self.grow)
        g.logodds[:] = self.logodds
        g.version = self.version
        g._data, g._data_key = self.data, self._data_key
        g._changes = list(self._changes)
        return g

    # ------------------------------------------------------- coordinates
    def world_to_cell(self, x: np.ndarray | float, y: np.ndarray | float) -> tuple[np.ndarray, np.ndarray]:
        """(row, col) int64 arrays of the cells holding world points (x, y) [m, map]; may be out of bounds."""
        col = np.floor((np.asarray(x, dtype=float) - self.origin[0]) / self.resolution).astype(np.int64)
        row = np.floor((np.asarray(y, dtype=float) - self.origin[1]) / self.resolution).astype(np.int64)
        return row, col

    def cell_to_world(self, row: np.ndarray | float, col: np.ndarray | float) -> tuple[np.ndarray, np.ndarray]:
        """(x, y) [m, map] of cell centres; rows/cols may be fractional."""
        x = self.origin[0] + (np.asarray(col, dtype=float) + 0.5) * self.resolution
        y = self.origin[1] + (np.asarray(row, dtype=float) + 0.5) * self.resolution
        return x, y

    def in_bounds(self, row: np.ndarray, col: np.ndarray) -> np.ndarray:
        h, w = self.shape
        return (row >= 0) & (row < h) & (col >= 0) & (col < w)

    def value_at(self, x: float, y: float) -> int:
        """The map_server value (FREE/OCCUPIED/UNKNOWN) at a world point; UNKNOWN outside the grid."""
        r, c = self.world_to_cell(x, y)
        if not self.in_bounds(r, c):
            return UNKNOWN
        return int(self.data[int(r), int(c)])

    # ------------------------------------------------------------ extent
    def ensure_contains(self, xmin: float, ymin: float, xmax: float, ymax: float) -> None:
        """Grow the grid (by at least ``GROW_CHUNK`` on each side that needs it) to hold the box [m]."""
        h, w = self.shape
        res = self.resolution
        ox, oy = self.origin
        pad_l = math.ceil((ox - xmin) / res) if xmin < ox else 0
        pad_b = math.ceil((oy - ymin) / res) if ymin < oy else 0
        pad_r = math.ceil((xmax - (ox + w * res)) / res) + 1 if xmax >= ox + w * res else 0
        pad_t = math.ceil((ymax - (oy + h * res)) / res) + 1 if ymax >= oy + h * res else 0
        if not (pad_l or pad_b or pad_r or pad_t):
            return
        chunk = int(round(GROW_CHUNK / res))
        pad_l, pad_b, pad_r, pad_t = (p + chunk if p else 0 for p in (pad_l, pad_b, pad_r, pad_t))
        self.logodds = np.pad(self.logodds, ((pad_b, pad_t), (pad_l, pad_r)))
        self.origin = (ox - pad_l * res, oy - pad_b * res)
        self._touch(NOTHING)  # new cells, all unknown: no cell's value changed

    # ------------------------------------------------------------ update
    def integrate(self, scan: Scan, pose: Pose2) -> None:
        """Fuse one scan taken with ``base_link`` at ``pose`` (map frame) into the grid.

        Rays with a return mark their end cell occupied and the cells before
        it free. A ray with no return (``inf``) clears up to the nearest
        return of its neighbours (or ``range_max`` if they have none either):
        an isolated dropout pointing at a wall must not clear the wall.
        Past that, a no-return ray is open space beyond the lidar's reach.
        In a scan where half the rays or more returned (a room) it clears
        that reach. In a scan where fewer did (the middle of a hall, or a
        lidar dropout) it clears ``OPEN_REACH`` round the robot, up to
        ``WALL_MARGIN`` short of the first wall the map holds on its way,
        and clears no wall; past ``OPEN_REACH``, up to the lidar's reach,
        it clears only cells no ray has touched yet (what the map holds there,
        a wall half drawn, an obstacle seen once, is left as it is); and if the scan
        lost more than ``DROPOUT_SHARE`` of the returns the map expects (the
        rays that returned, and those without return that cross a wall the
        map holds within reach), a blanked lidar, it clears nothing.

        Measured before this rule (no-return rays cleared nothing in scans
        where fewer than half the rays returned): in atrium:2's hall 89 % of
        the scans returned fewer than half (median 25 %), the hall's middle
        stayed unknown round the robot, and frontier_travel flipped between
        two goals in a 3 m patch of unknown for 135 s. Stopping at the map's
        walls in every scan never cleared an obstacle taken away from a room
        (a day on floor:1: coverage 0.987); clearing through walls in every
        scan that was no dropout mapped the outside of floor:1 through its
        walls (grazing dropouts along them): 3141 m² on a 2000 m² floor;
        clearing through walls the map is not sure of, fading the first one
        it is sure of a step, lost agreement over a day (0.925), and so did
        this rule with the lidar's whole reach (0.937). With ``OPEN_REACH``
        the day keeps it (0.981, coverage 0.997) and atrium:2 and atrium:3
        end with no patch of the hall unseen (bench explore, two seeds).
        Past it, unseen cells only: the halls' time to 95 % 590 → 440 s in
        median (atria 1–4, two seeds), with the tracking search's heading
        held as on a room's scan (grid_slam.TRACKING_PRIOR_POINTS); without
        that, faster routes through the halls' middles drifted.
        """
        sensor = pose.compose(scan.laser_pose)
        ranges = np.asarray(scan.ranges, dtype=float)
        hit = scan.valid()
        wraps = abs(abs(scan.angle_increment) * len(ranges) - 2 * math.pi) < 2 * abs(scan.angle_increment)
        clear = _clear_lengths(ranges, hit, scan.range_max, wraps)
        angles = scan.angles + sensor.theta
        open_rays = None  # rays out into open space that stop at the map's walls: in a scan that mostly did not return
        if len(ranges) and hit.mean() < MIN_RETURN_SHARE:
            open_rays = ~hit & (clear >= scan.range_max)
        self.integrate_rays(np.array([sensor.x, sensor.y]), angles, clear, hit, open_rays=open_rays,
                            open_reach=OPEN_REACH)

    def integrate_rays(self, origin: np.ndarray, angles: np.ndarray, lengths: np.ndarray, hit: np.ndarray,
                       open_rays: np.ndarray | None = None, open_reach: float = math.inf) -> None:
        """Trace (N,) rays from ``origin`` (2,) [m, map] at ``angles`` [rad, map] of ``lengths`` [m].

        ``hit`` (N,) bool says which rays end on an obstacle (their end cell
        is marked occupied); the others only clear. ``open_rays`` (N,) bool:
        rays without return that stop short of the map's walls, or clear
        nothing in a dropout, as :meth:`integrate` says; beyond ``open_reach``
        [m] they clear only cells no ray has touched yet.
        """
        ox, oy = float(origin[0]), float(origin[1])
        ends_x = ox + lengths * np.cos(angles)
        ends_y = oy + lengths * np.sin(angles)
        if self.grow and len(lengths):
            self.ensure_contains(
                min(ox, float(ends_x.min())), min(oy, float(ends_y.min())),
                max(ox, float(ends_x.max())), max(oy, float(ends_y.max())),
            )
        h, w = self.shape
        res = self.resolution
        step = 0.5 * res
        n_steps = int(math.ceil(float(lengths.max(initial=0.0)) / step)) + 1
        t = np.arange(n_steps, dtype=float) * step  # (K,)
        # Free samples stop half a cell short of the end so the end cell is not cleared by its own ray: ray i
        # takes the samples t[k] < its length (less a step if it hit), counted by a search in the sorted t, and
        # only those are made (not the whole rays × K block).
        counts = np.searchsorted(t, lengths - np.where(hit, step, 0.0), side="left")
        ray = np.repeat(np.arange(len(lengths)), counts)
        # Sample k of a ray lies t[k] = k·step along it (t's own numbers: whole numbers of steps, times step).
        tk = (np.arange(len(ray)) - np.repeat(np.cumsum(counts) - counts, counts)) * step
        # The samples' cells, as world_to_cell gives them for the points ox + cos·t, oy + sin·t (the same
        # operations, in place: these arrays hold tens of thousands of samples).
        cells = []
        for o, trig, corner in ((ox, np.cos(angles), self.origin[0]), (oy, np.sin(angles), self.origin[1])):
            v = trig[ray]
            v *= tk
            v += o
            v -= corner
            v /= res
            cells.append(np.floor(v, out=v).astype(np.int64))
        if open_rays is not None and open_rays.any() and ray.size:
            keep = self._up_to_walls(cells[1], cells[0], ray, counts, open_rays, int(np.count_nonzero(hit)))
            if keep is not None:
                cells, ray, tk = [cells[0][keep], cells[1][keep]], ray[keep], tk[keep]
            far = open_rays[ray] & (tk > open_reach)
            if far.any():
                keep = ~far
                keep[far] = self._untouched(cells[1][far], cells[0][far])
                cells, ray = [cells[0][keep], cells[1][keep]], ray[keep]
        free_idx = _flat_cells(cells[1], cells[0], h, w)
        # A ray's samples are half a cell apart, so most fall in the cell of the one before: those repeats
        # change nothing (a cell is updated once per scan) and are dropped before the rest of the work.
        if free_idx.size:
            free_idx = free_idx[np.r_[True, free_idx[1:] != free_idx[:-1]]]
        hr, hc = self.world_to_cell(ends_x[hit], ends_y[hit])
        hit_idx = _flat_cells(hr, hc, h, w)
        flat = self.logodds.reshape(-1)
        if hit_idx.size and free_idx.size:
            # End points win over rays grazing past them in the same scan (marked in the span of cells the scan
            # touched, not over the whole floor).
            lo = min(int(free_idx.min()), int(hit_idx.min()))
            is_hit = np.zeros(max(int(free_idx.max()), int(hit_idx.max())) - lo + 1, dtype=bool)
            is_hit[hit_idx - lo] = True
            free_idx = free_idx[~is_hit[free_idx - lo]]
        # Fancy-index assignment applies once per distinct index: each cell is updated once per scan, and kept
        # within the clamps (only the cells updated can have left them; the two sets share no cell).
        flat[free_idx] = np.clip(flat[free_idx] + L_FREE, L_MIN, L_MAX)
        flat[hit_idx] = np.clip(flat[hit_idx] + L_OCC, L_MIN, L_MAX)
        if len(lengths):
            self._touch((min(ox, float(ends_x.min())), min(oy, float(ends_y.min())),
                         max(ox, float(ends_x.max())), max(oy, float(ends_y.max()))))
        else:
            self._touch(NOTHING)

    def _up_to_walls(self, rows: np.ndarray, cols: np.ndarray, ray: np.ndarray, counts: np.ndarray,
                     open_rays: np.ndarray, returned: int) -> np.ndarray | None:
        """(S,) bool: the samples to keep of rays whose samples are ``rows``, ``cols`` (cells) and ``ray`` (each
        sample's ray; a ray's samples contiguous and in order, ``counts`` per ray): all those of rays not in
        ``open_rays``; of those in it, the samples before the first that lies within ``WALL_MARGIN`` of a wall
        the map holds — none in a dropout (``returned`` rays came back; :meth:`integrate`). None: keep all."""
        h, w = self.shape
        sel = open_rays[ray] & (rows >= 0) & (rows < h) & (cols >= 0) & (cols < w)
        wall = np.zeros(rows.size, dtype=bool)
        wall[sel] = self.logodds[rows[sel], cols[sel]] > T_OCC
        if not wall.any():
            return None
        crossing = int(np.count_nonzero(np.bincount(ray[wall], minlength=len(counts))))
        if crossing > DROPOUT_SHARE * (crossing + returned):  # a blanked lidar: its open rays clear nothing
            return ~open_rays[ray]
        m = int(math.ceil(WALL_MARGIN / (0.5 * self.resolution)))  # samples are half a cell apart
        seen = np.cumsum(wall)  # walls among the samples up to each one
        first = np.cumsum(counts) - counts  # each ray's first sample
        before = seen[first] - wall[first]  # walls before each ray's first sample (other rays')
        ahead = np.minimum(np.arange(rows.size) + m, (first + counts - 1)[ray])  # the last sample within m ahead
        return seen[ahead] - before[ray] == 0

    def _untouched(self, rows: np.ndarray, cols: np.ndarray) -> np.ndarray:
        """(S,) bool: which cells (``rows``, ``cols``) lie in the grid with log-odds no ray has moved from 0."""
        h, w = self.shape
        inside = (rows >= 0) & (rows < h) & (cols >= 0) & (cols < w)
        out = np.zeros(rows.size, dtype=bool)
        out[inside] = self.logodds[rows[inside], cols[inside]] == 0.0
        return out

    def clear(self) -> None:
        """Forget everything (all cells unknown)."""
        self.logodds[:] = 0.0
        self._touch()

    def clear_cache(self, extent: tuple[float, float, float, float] | None = None) -> None:
        """The log-odds were changed from outside (read back from a file): drop what was derived from them.

        ``extent`` (xmin, ymin, xmax, ymax) [m, map]: the changed cells all lie in it (None: anywhere).
        """
        self._touch(extent)

    def _touch(self, extent: tuple[float, float, float, float] | None = None) -> None:
        if self._data is not None:
            self._old = (self._data, self._data_key[0], self._data_key[1])
        self._data = None
        self.version += 1
        self._changes.append((self.version, extent))
        del self._changes[:-CHANGES_KEPT]


def _flat_cells(rows: np.ndarray, cols: np.ndarray, h: int, w: int) -> np.ndarray:
    """Flat indices ``row·w + col`` of the cells (rows, cols) that lie in an (h, w) grid, in their order."""
    if rows.size and rows.min() >= 0 and rows.max() < h and cols.min() >= 0 and cols.max() < w:
        return rows * w + cols  # all inside (a growing grid holds every ray): no mask to make and apply
    inside = (rows >= 0) & (rows < h) & (cols >= 0) & (cols < w)
    return rows[inside] * w + cols[inside]


def _classify(logodds: np.ndarray) -> np.ndarray:
    """The map_server view (int8 FREE / OCCUPIED / UNKNOWN) of log-odds (H, W)."""
    out = np.full(logodds.shape, UNKNOWN, dtype=np.int8)
    out[logodds > T_OCC] = OCCUPIED
    out[logodds < T_FREE] = FREE
    return out


def _clear_lengths(ranges: np.ndarray, hit: np.ndarray, range_max: float, wraps: bool = True) -> np.ndarray:
    """(N,) how far each ray clears [m]: its range if it returned, else bounded by its neighbours' returns.

    ``wraps``: the scan covers the full circle, so its first and last rays are neighbours (a 180° scan's are not).
    """
    out = np.where(hit, ranges, np.inf)
    n = len(ranges)
    if n == 0:
        return out
    k_max = NO_RETURN_NEIGHBOURS
    padded = np.concatenate([out[-k_max:], out, out[:k_max]]) if wraps and n > k_max else \
        np.concatenate([np.full(k_max, np.inf), out, np.full(k_max, np.inf)])
    neighbour_min = np.full(n, np.inf)
    for k in range(1, k_max + 1):
        neighbour_min = np.minimum(neighbour_min, padded[k_max - k: k_max - k + n])
        neighbour_min = np.minimum(neighbour_min, padded[k_max + k: k_max + k + n])
    # A no-return ray among returns clears to just short of the nearest neighbouring return. One among other
    # no-return rays clears the sensor's reach (open space beyond range); in a scan that mostly did not return,
    # only up to the map's walls (OccupancyGrid.integrate): a lidar that dropped out does not erase the room.
    bounded = np.where(np.isfinite(neighbour_min), 0.9 * neighbour_min, range_max)
    return np.where(hit, ranges, np.minimum(bounded, range_max))
