"""Where the robot can go: one rule for the costmap, the explorer and the benchmarks.

The robot is round, so whether it fits at a place is a question about its
centre: it may stand on a cell when the cell's centre lies farther than the
**inscribed radius** from every wall cell's centre — the footprint's radius
plus half a cell, the rasterisation error of a wall drawn into a grid (Nav2's
inflation layer marks cells nearer than that ``INSCRIBED``, and its planners
never enter them; homing's costmap does the same with this function). In
wall-face terms a passage lets the robot through when it is wider than the
footprint's diameter, with less than a cell to spare, so the rule decides
the cells a gap the width of the robot is drawn with: a 0.40 m corridor drawn
in 5 cm cells is 8 cells, and no cell of it is 0.215 m from both walls.

On a true floor plan (evaluation only: the benchmarks, ``world show``) the
rule gives the **navigable area**:

1. ``fits``: free cells where the centre fits (above);
2. the region: the 8-connected component of (1) the start is in (or the
   nearest one, for a start beside a wall);
3. the navigable area: the free cells the footprint sweeps from the region
   (within the inscribed radius of one of its cells) — what the robot can
   drive over, and the area exploration is scored on;
4. **blocked** places: the free space 8-connected to the start that (3)
   leaves out, by component of at least ``MIN_BLOCKED``, each with the
   width of the widest way in — the best bottleneck over every path from the
   region: the largest clearance ``t`` such that cells at least ``t`` from
   every wall still join the region to the place, reported as a wall-to-wall
   width ``2·t`` less half a cell (within half a cell of the drawn width).

On a true plan the rule is applied to the plan **as the robot's map can
draw it**: ``navigable(..., margin=MAP_MARGIN)`` widens the footprint by the
map's drawing error, one cell of the robot's 5 cm grid each side, on the
plan resampled to that grid (:func:`homing.mapping.evaluate.navigable_truth`).
A lidar map puts a wall face a cell into the room where the face lies on a
cell boundary (half the hits fall on the free side, and a hit outweighs a
pass) or where the poses the face was seen from were 3 cm off: measured on
``atrium:1`` seed 1 (bench explore, frontier_travel), a 0.50 m passage (10
cells, the rule wants 9) drawn 8 cells wide, one jamb a cell in at the
log-odds clamp. A passage within a cell each side of the rule may or may not
be passable on the robot's map, so the places behind it are no part of the
navigable area (no run is scored on them, nor called a false done for
leaving them) and are reported apart, ``marginal``, with their widths; a
robot that maps the passage wide enough still goes through and maps them.
What the margin alone leaves out in pieces smaller than ``MIN_MARGINAL``
(the least unseen area bench explore calls a place), an alcove or the
corner of a desk, stays navigable.

Grids are (H, W) with row 0 at the lowest y; distances between cell centres.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import cv2
import numpy as np
from homing.mapping.distance import distance_cells
from homing.robot.turtlebot import FOOTPRINT_RADIUS

MIN_BLOCKED = 0.25  # [m²] free space left out in smaller pieces is a corner or a crack, not a place
MAP_RESOLUTION = 0.05  # [m] the robot's grid (homing.mapping.grid)
MAP_MARGIN = MAP_RESOLUTION  # [m] how far into a passage the robot's map may draw each wall face (module doc)
MIN_MARGINAL = 1.0  # [m²] what the margin alone leaves out in smaller pieces (an alcove) stays navigable


def inscribed_radius(resolution: float, robot_radius: float = FOOTPRINT_RADIUS) -> float:
    """Centre distance [m] to a wall cell's centre under which the robot touches it: the footprint's radius
    plus half a cell (the rasterisation error of walls)."""
    return robot_radius + 0.5 * resolution


def centre_fits(solid: np.ndarray, resolution: float, robot_radius: float = FOOTPRINT_RADIUS) -> np.ndarray:
    """(H, W) bool: cells whose centre lies farther than the inscribed radius from every ``solid`` cell's centre
    (``solid`` (H, W) bool: walls; all True where there is no wall)."""
    if not solid.any():
        return np.ones(solid.shape, bool)
    return distance_cells(~solid) * resolution > inscribed_radius(resolution, robot_radius)


def disc(radius_cells: float) -> np.ndarray:
    """(2k+1, 2k+1) uint8 structuring element: cells whose centre lies within ``radius_cells`` of the middle."""
    k = max(0, int(math.ceil(radius_cells - 1e-9)))
    yy, xx = np.mgrid[-k : k + 1, -k : k + 1]
    return (xx * xx + yy * yy <= radius_cells * radius_cells + 1e-9).astype(np.uint8)


@dataclass(frozen=True)
class Blocked:
    """Free space joined to the start only through passages narrower than the robot: where (its centroid, [m],
    the map's frame), how much (``area`` [m²]) and the widest way in (``width`` [m], wall to wall).
    ``marginal``: the footprint fits through, but not with the map's margin (module doc)."""

    x: float
    y: float
    area: float
    width: float
    marginal: bool = False


@dataclass(frozen=True)
class Navigable:
    """The module doc's rule on a floor plan: the navigable area (``mask``, (H, W) bool, and ``area`` [m²]),
    the cells the robot's centre can reach (``region``) and the places passages too narrow keep it from."""

    mask: np.ndarray = field(repr=False)
    region: np.ndarray = field(repr=False)
    area: float
    blocked: tuple[Blocked, ...]

    @property
    def blocked_area(self) -> float:
        """[m²] free space behind passages narrower than the robot."""
        return sum(b.area for b in self.blocked)

    def summary(self) -> str:
        """One line: the navigable area and what the robot cannot reach, with the passages' widths."""
        text = f"navigable area {self.area:.1f} m²"
        for marginal, what in ((False, "narrower than the robot"),
                               (True, "a map may draw narrower than the robot (within a cell a side)")):
            places = [b for b in self.blocked if b.marginal is marginal]
            if places:
                text += f"; behind passages {what}: " + ", ".join(
                    f"{b.area:.1f} m² at ({b.x:.1f}, {b.y:.1f}) through {b.width:.2f} m" for b in places)
        return text


def navigable(free: np.ndarray, resolution: float, origin: tuple[float, float], start_xy: tuple[float, float],
              robot_radius: float = FOOTPRINT_RADIUS, margin: float = 0.0) -> Navigable:
    """The navigable area of a floor plan (module doc): ``free`` (H, W) bool, ``resolution`` [m], ``origin``
    (x, y) [m] of cell (0, 0)'s corner, the robot's start ``start_xy`` [m]; ``margin`` [m]: the map's drawing
    error, added to the footprint's radius (module doc)."""
    free = np.asarray(free, bool)
    h, w = free.shape
    sr = int(np.clip(math.floor((start_xy[1] - origin[1]) / resolution), 0, h - 1))
    sc = int(np.clip(math.floor((start_xy[0] - origin[0]) / resolution), 0, w - 1))
    empty = np.zeros_like(free)
    fits = free & centre_fits(~free, resolution, robot_radius + margin)
    if not fits.any():
        return Navigable(empty, empty, 0.0, ())
    region = _component_at(fits, (sr, sc))
    r_cells = inscribed_radius(resolution, robot_radius + margin) / resolution
    bare = inscribed_radius(resolution, robot_radius) / resolution  # [cells] the rule without the margin
    mask = cv2.dilate(region.astype(np.uint8), disc(r_cells)).astype(bool) & free
    if margin > 0:  # corners and alcoves the margin alone leaves out, each smaller than a place, stay in
        bare_fits = free & centre_fits(~free, resolution, robot_radius)
        swept = cv2.dilate(_component_at(bare_fits, (sr, sc)).astype(np.uint8), disc(bare)).astype(bool) & free
        n, labels, stats, _ = cv2.connectedComponentsWithStats((swept & ~mask).astype(np.uint8), connectivity=8)
        small = np.flatnonzero(stats[:, cv2.CC_STAT_AREA] * resolution**2 < MIN_MARGINAL)
        mask |= np.isin(labels, small[small > 0])
    connected = _component_at(free, (sr, sc))
    left_out = (connected & ~mask).astype(np.uint8)
    n, labels, stats, centroids = cv2.connectedComponentsWithStats(left_out, connectivity=8)
    clearance = distance_cells(free)  # [cells] to the nearest cell that is not free
    parts = [k for k in range(1, n) if float(stats[k, cv2.CC_STAT_AREA]) * resolution**2 >= MIN_BLOCKED]
    blocked = []
    cells = cells_by_label(labels, parts)
    for k, t in zip(parts, _bottlenecks(clearance, region, cells, r_cells), strict=True):
        area = float(stats[k, cv2.CC_STAT_AREA]) * resolution**2
        cx, cy = centroids[k]
        blocked.append(Blocked(origin[0] + (cx + 0.5) * resolution, origin[1] + (cy + 0.5) * resolution, area,
                               max(0.0, (2.0 * t - 0.5) * resolution), marginal=bool(t > bare)))
    blocked.sort(key=lambda b: -b.area)
    return Navigable(mask, region, float(mask.sum()) * resolution**2, tuple(blocked))


def way_in(free: np.ndarray, resolution: float, start: tuple[int, int], place: np.ndarray,
           robot_radius: float = FOOTPRINT_RADIUS) -> tuple[float, bool]:
    """The widest way from the cell ``start`` (row, col) to the cells ``place`` (H, W) bool through ``free``
    (H, W) bool cells: its width [m], wall to wall, and whether the robot fits through it by the module's rule
    (then the width is only known to be at least the robot's: the search stops there)."""
    return ways_in(free, resolution, start, [place], robot_radius)[0]


def ways_in(free: np.ndarray, resolution: float, start: tuple[int, int], places: list[np.ndarray],
            robot_radius: float = FOOTPRINT_RADIUS, narrow_widths: bool = True,
            known: np.ndarray | None = None) -> list[tuple[float, bool]]:
    """:func:`way_in` to each of several places at about the cost of one: the distance transforms and the region
    the robot's centre reaches are shared, a way the robot fits through costs nothing more, and a narrower one
    a bottleneck search (a few labellings of the grid) — or nothing, width ``nan``, without ``narrow_widths``.
    ``known`` (H, W) bool: the cells a way may go through, when fewer than ``free`` (a map's known free space:
    widths are still measured between what is not ``free``)."""
    fits = free & centre_fits(~free, resolution, robot_radius)
    clearance = distance_cells(free)  # [cells] to the nearest cell that is not free
    if known is not None:
        fits &= known
        clearance = np.where(known, clearance, 0.0)
    if not fits.any():
        return [(0.0, False)] * len(places)
    r_cells = inscribed_radius(resolution, robot_radius) / resolution
    region = _component_at(fits, start)
    # Every cell of the region clears more than r_cells: through it the bottleneck is the cap itself.
    cap = float(clearance[(clearance > 0) & (clearance <= r_cells)].max(initial=0.0))
    out: list[tuple[float, bool]] = []
    narrow: dict[int, np.ndarray] = {}  # index in places -> its free cells (flat indices), for the bottleneck search
    for i, place in enumerate(places):
        if not (place & free).any():
            out.append((0.0, False))
        elif region[place].any():
            out.append((max(0.0, (2.0 * cap - 0.5) * resolution), True))
        elif narrow_widths:
            out.append((math.nan, False))
            narrow[i] = np.flatnonzero(place & free)
        else:
            out.append((math.nan, False))
    if narrow:
        for i, t in zip(narrow, _bottlenecks(clearance, region, list(narrow.values()), r_cells), strict=True):
            out[i] = (max(0.0, (2.0 * t - 0.5) * resolution), False)
    return out


def _component_at(mask: np.ndarray, cell: tuple[int, int]) -> np.ndarray:
    """(H, W) bool: the 8-connected component of ``mask`` holding ``cell``, else the one nearest to it."""
    _, labels = cv2.connectedComponents(mask.astype(np.uint8), connectivity=8)
    lab = labels[cell]
    if lab == 0:
        rows, cols = np.nonzero(labels)
        i = int(np.argmin((rows - cell[0]) ** 2 + (cols - cell[1]) ** 2))
        lab = labels[rows[i], cols[i]]
    return labels == lab


def cells_by_label(labels: np.ndarray, wanted: list[int]) -> list[np.ndarray]:
    """The flat indices of the cells of each label in ``wanted``, in one pass over ``labels`` (H, W) int (a mask
    per label would hold the grid once per label: a 5000 × 5000 floor's places took gigabytes)."""
    flat = labels.ravel()
    idx = np.flatnonzero(np.isin(flat, wanted))
    lab = flat[idx]
    order = np.argsort(lab, kind="stable")
    idx, lab = idx[order], lab[order]
    starts = np.searchsorted(lab, wanted, side="left")
    ends = np.searchsorted(lab, wanted, side="right")
    return [idx[a:b] for a, b in zip(starts, ends, strict=True)]


def _bottlenecks(clearance: np.ndarray, region: np.ndarray, places: list[np.ndarray], at_most: float) -> list[float]:
    """[cells] for each of ``places`` (flat indices into the grid), the largest clearance t ≤ ``at_most`` such that
    cells of clearance ≥ t join ``region`` to it, 0 when nothing does.

    The clearances that occur up to ``at_most`` are few (a distance transform's values under the robot's radius
    in cells: a dozen), so they are tried from the largest down, one labelling each, for all places at once: the
    first that joins a place is its bottleneck (cells clear of t are clear of every smaller one). A binary search
    a place took six labellings each, and a real building's map has hundreds of places behind cracks (ACES' log:
    13 s to measure them)."""
    out = [0.0] * len(places)
    if not places:
        return out
    values = np.unique(clearance[(clearance > 0) & (clearance <= at_most)])[::-1]
    first = int(np.argmax(region))  # a cell of the region (argwhere would list all of them: 400 MB on 5000²)
    seed = (first // region.shape[1], first % region.shape[1])
    left = list(range(len(places)))
    for t in values:
        if not left:
            break
        joined = _component_at(clearance >= t, seed).ravel()  # the region's cells all clear t (t ≤ at_most)
        still = []
        for i in left:
            if joined[places[i]].any():
                out[i] = float(t)
            else:
                still.append(i)
        left = still
    return out
