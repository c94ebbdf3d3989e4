"""The robot's trail: the map cells its (localised, ``map``-frame) centre has occupied, so it can go back the way it came.

Where the robot's centre has physically been, the robot fits. The one rule
of :mod:`homing.mapping.navigable` pads the footprint's radius by half a
cell (the rasterisation error of walls), so a passage must be drawn at least
9 free cells wide on the 5 cm map; the floor generator's 0.5 m doors (10
cells) are often drawn 8 (a jamb face on a cell boundary, a pose a few
centimetres off). Seen on ``floor:2`` seed 0 (bench explore, nearest): the
robot entered a 7.4 m² closet while the map drew its door 9 cells wide;
from inside, the map redrew it 8, every frontier of the rest of the floor
was "narrower than the robot (way in 0.38 m)", and exploration said done:
a false done, at 0.77 coverage of the navigable area on 98445f2. With the
trail it went back out and mapped the floor: 0.97 at the session's end.

On a trail cell, the costmap (:class:`homing.navigation.costmap.Costmap`)
and the explorer's map check (:func:`homing.mapping.reachable.frontier_report`)
drop the half cell of padding, never the footprint itself: a trail cell
counts as a place the robot fits only while its centre lies farther than the
bare footprint radius from every wall or obstacle cell's centre (and, in
the costmap, the full inscribed radius from keep-out zones and bumper
marks, which no scan redraws). That keeps a trail kept for days safe: an
obstacle placed later on it, once mapped or seen, puts the trail's cells
near it back within the footprint, and they are refused as any other; the
trail never lifts a cell a wall is drawn on or next to, so it cannot join
two rooms through a wall, whatever pose error put it there.

The trail is a bool grid on the costmap's lattice (anchored once, so a grid
that grows by whole cells keeps it in place), grown in blocks of
``BLOCK`` cells as the robot goes, and never larger than ``MAX_CELLS``
(about a 200 m square at 5 cm: 16 MB): marks beyond it are dropped. Each
new pose is joined to the last by a 4-connected line of cells (the planners'
and the distance fields' own connectivity) unless the pose jumped more than
``MAX_STEP`` (a relocalisation: the robot did not drive there).
Deterministic: it depends on the poses given, in order, alone.
"""

from __future__ import annotations

import math

import cv2
import numpy as np

MAX_STEP = 0.3  # [m] a pose this far from the last (a relocalisation jump) is not joined to it by a line
BLOCK = 64  # [cells] the grid grows by at least this much a side (3.2 m at 5 cm), so it rarely regrows
MAX_CELLS = 1 << 24  # cells at most (a 205 m square at 5 cm, 16 MB): marks beyond are dropped


class Trail:
    """Cells the robot's centre has occupied, on a lattice of ``resolution`` [m] anchored at the first mark."""

    def __init__(self, resolution: float = 0.05, max_cells: int = MAX_CELLS) -> None:
        self.resolution = float(resolution)
        self.max_cells = int(max_cells)
        self.cells = np.zeros((0, 0), dtype=bool)  # (H, W), row 0 at the lowest y
        self.origin: tuple[float, float] | None = None  # [m] lower-left corner of cells[0, 0], map frame
        self.version = 0  # bumped whenever a cell is marked
        self._last: tuple[float, float] | None = None  # [m] the last pose marked

    def __len__(self) -> int:
        return int(self.cells.sum())

    def anchor(self, origin: tuple[float, float], resolution: float) -> None:
        """Put the trail's lattice on a map's (``origin`` [m] of its cell (0, 0), ``resolution`` [m]), before the first
        mark: the trail's cells are then that map's cells. Later calls change nothing."""
        if self.origin is None:
            self.resolution = float(resolution)
            self.origin = (float(origin[0]), float(origin[1]))

    def mark(self, x: float, y: float) -> tuple[float, float, float, float] | None:
        """The robot's centre is at (x, y) [m] (``map``): mark its cell and the line of cells from the last pose
        (unless it jumped more than ``MAX_STEP``). Returns the box (xmin, ymin, xmax, ymax) [m] of the cells newly
        marked, or None when none was."""
        last, self._last = self._last, (float(x), float(y))
        if not (math.isfinite(x) and math.isfinite(y)):
            self._last = None
            return None
        if self.origin is None:
            self.origin = (math.floor(x / self.resolution) * self.resolution,
                           math.floor(y / self.resolution) * self.resolution)
        ends = [(x, y)] if last is None or math.hypot(x - last[0], y - last[1]) > MAX_STEP else [last, (x, y)]
        if not self._cover(ends):
            return None
        res, (ox, oy) = self.resolution, self.origin
        rc = [(int(math.floor((py - oy) / res)), int(math.floor((px - ox) / res))) for px, py in ends]
        r0, c0 = min(r for r, _ in rc), min(c for _, c in rc)
        r1, c1 = max(r for r, _ in rc) + 1, max(c for _, c in rc) + 1
        # Drawn in the line's own box, not over the whole floor (this runs every tick).
        line = np.zeros((r1 - r0, c1 - c0), dtype=np.uint8)
        cv2.line(line, (rc[0][1] - c0, rc[0][0] - r0), (rc[-1][1] - c0, rc[-1][0] - r0), 1, lineType=cv2.LINE_4)
        window = self.cells[r0:r1, c0:c1]
        new = line.astype(bool) & ~window
        if not new.any():
            return None
        window |= new
        self.version += 1
        rows, cols = np.flatnonzero(new.any(axis=1)) + r0, np.flatnonzero(new.any(axis=0)) + c0
        return (ox + cols[0] * res, oy + rows[0] * res, ox + (cols[-1] + 1) * res, oy + (rows[-1] + 1) * res)

    def _cover(self, points: list[tuple[float, float]]) -> bool:
        """Grow the grid (by ``BLOCK`` cells a side at least) to hold ``points`` [m]; False if that would pass
        ``max_cells``."""
        assert self.origin is not None
        res, (ox, oy) = self.resolution, self.origin
        h, w = self.cells.shape
        rows = [int(math.floor((py - oy) / res)) for _, py in points]
        cols = [int(math.floor((px - ox) / res)) for px, _ in points]
        below, left = max(0, -min(rows)), max(0, -min(cols))
        above, right = max(0, max(rows) + 1 - h), max(0, max(cols) + 1 - w)
        if not (below or left or above or right):
            return True
        below, left, above, right = (BLOCK + n if n else 0 for n in (below, left, above, right))
        if (h + below + above) * (w + left + right) > self.max_cells:
            return False
        self.cells = np.pad(self.cells, ((below, above), (left, right)))
        self.origin = (ox - left * res, oy - below * res)
        return True

    def mask(self, origin: tuple[float, float], resolution: float, shape: tuple[int, int]) -> np.ndarray:
        """(H, W) bool: the trail on a map's cells (``origin`` [m] of its cell (0, 0), ``resolution`` [m],
        ``shape``): a cell is on it when its centre lies in a trail cell (the same cell, on the lattice the trail
        was anchored to)."""
        h, w = int(shape[0]), int(shape[1])
        out = np.zeros((h, w), dtype=bool)
        if self.origin is None or not self.cells.size or h == 0 or w == 0:
            return out
        res = self.resolution
        rows = np.floor((origin[1] + (np.arange(h) + 0.5) * resolution - self.origin[1]) / res).astype(np.int64)
        cols = np.floor((origin[0] + (np.arange(w) + 0.5) * resolution - self.origin[0]) / res).astype(np.int64)
        r_ok = (rows >= 0) & (rows < self.cells.shape[0])
        c_ok = (cols >= 0) & (cols < self.cells.shape[1])
        if r_ok.any() and c_ok.any():
            out[np.ix_(r_ok, c_ok)] = self.cells[np.ix_(rows[r_ok], cols[c_ok])]
        return out
