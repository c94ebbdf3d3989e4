"""Deterministic placement on a bare floor plan: the dock against a wall, tags on walls, reachability.

A bare map_server map says nothing about a dock or tags, so they are placed
from the grid alone, the same way every time:

- the **dock** goes against a straight stretch of wall (solid for
  ``DOCK_WALL_HALF`` either side) with a clear rectangle in front of it
  (``CLEAR_HALF`` wide each side, ``CLEAR_DEPTH`` deep, all free and in the
  largest free component), choosing the candidate nearest the centroid of
  that component;
- **tags** (``tags: {auto: N}``) go on straight stretches of wall at least a
  tag wide with free floor in front, spread by farthest-point sampling that
  starts from the dock, never within ``TAG_DOCK_GAP`` of it;
- **reachable free area**: free cells 4-connected to the start cell.

Grids are (H, W) with row 0 at the lowest y (``homing.map_server``). A wall
candidate is a free cell whose neighbour *behind* (opposite the facing
direction) is solid; the dock's or tag's wall face is their shared edge.
"""

from __future__ import annotations

import math

import numpy as np
from homing.robot.types import Pose2
from homing.sim.walls import _local_to_world, solid_mask, world_to_cell
from scipy import ndimage

from homing.map_server import MapData

DOCK_WALL_HALF = 0.30  # [m] wall behind the dock, each side of its centre line
CLEAR_HALF = 0.60  # [m] clear floor each side of the dock's centre line
CLEAR_DEPTH = 1.6  # [m] clear floor in front of the wall (dock 0.12 + robot 0.35 + ~1 m staging)
TAG_CLEAR_DEPTH = 1.0  # [m] free floor in front of an auto-placed tag…
TAG_CLEAR_HALF = 0.5  # [m] …this wide each side of it (keeps tags out of corners)
TAG_DOCK_GAP = 1.0  # [m] no auto tag closer than this to the dock
# Facing directions in (row, col) steps and their yaw: +x, +y, −x, −y.
_DIRS = (((0, 1), 0.0), ((1, 0), math.pi / 2), ((0, -1), math.pi), ((-1, 0), -math.pi / 2))


def main_component(free: np.ndarray) -> np.ndarray:
    """(H, W) bool: the largest 4-connected component of ``free``."""
    labels, n = ndimage.label(free)
    if n == 0:
        return np.zeros_like(free)
    sizes = np.bincount(labels.ravel())
    sizes[0] = 0
    return labels == int(np.argmax(sizes))


def reachable_from(data: MapData, x: float, y: float) -> np.ndarray:
    """(H, W) bool: free cells 4-connected to the cell holding (x, y) [m] (nearest free cell if solid)."""
    free = ~solid_mask(data)
    labels, _ = ndimage.label(free)
    rows, cols = world_to_cell(data, np.array([[x, y]]))
    r, c = int(rows[0]), int(cols[0])
    h, w = free.shape
    if not (0 <= r < h and 0 <= c < w and free[r, c]):
        fr, fc = np.nonzero(free)
        if fr.size == 0:
            return np.zeros_like(free)
        k = int(np.argmin((fr - r) ** 2 + (fc - c) ** 2))
        r, c = int(fr[k]), int(fc[k])
    return labels == labels[r, c]


class _Box:
    """O(1) counts of True cells in axis-aligned rectangles (summed-area table); outside counts as True."""

    def __init__(self, mask: np.ndarray):
        self.h, self.w = mask.shape
        dtype = np.int32 if mask.size < 2**31 else np.int64  # counts up to H·W: half the memory on any real map
        self.sat = np.zeros((self.h + 1, self.w + 1), dtype=dtype)
        np.cumsum(mask, axis=0, dtype=dtype, out=self.sat[1:, 1:])
        np.cumsum(self.sat[1:, 1:], axis=1, out=self.sat[1:, 1:])

    def all_true(self, r0: int, r1: int, c0: int, c1: int) -> bool:
        """Whether every cell of rows [r0, r1], cols [c0, c1] (inclusive) is True (False if off-grid)."""
        if r0 < 0 or c0 < 0 or r1 >= self.h or c1 >= self.w:
            return False
        s = self.sat
        total = s[r1 + 1, c1 + 1] - s[r0, c1 + 1] - s[r1 + 1, c0] + s[r0, c0]
        return int(total) == (r1 - r0 + 1) * (c1 - c0 + 1)


def _rect(i: int, j: int, f: tuple[int, int], a0: int, a1: int, half: int) -> tuple[int, int, int, int]:
    """Bounds of cells (i, j) + a·f + b·l, a ∈ [a0, a1], b ∈ [−half, half], l ⟂ f."""
    li, lj = -f[1], f[0]
    rows = [i + a * f[0] + b * li for a in (a0, a1) for b in (-half, half)]
    cols = [j + a * f[1] + b * lj for a in (a0, a1) for b in (-half, half)]
    return min(rows), max(rows), min(cols), max(cols)


def wall_spots(data: MapData, wall_half: float, clear_half: float, clear_depth: float,
               region: np.ndarray) -> list[tuple[Pose2, int, int]]:
    """Every wall face with solid wall ``wall_half`` [m] each side and a clear rectangle in front.

    Returns (pose, row, col): the pose is on the wall face (cell edge), x
    pointing into the room; (row, col) is the free cell in front of it.
    """
    solid = solid_mask(data)
    res = data.resolution
    solid_box, clear_box = _Box(solid), _Box(region)
    kw = max(0, math.ceil(wall_half / res - 0.5))
    kc = max(0, math.ceil(clear_half / res - 0.5))
    depth = max(1, math.ceil(clear_depth / res))
    out: list[tuple[Pose2, int, int]] = []
    h, w = solid.shape
    for f, yaw in _DIRS:
        behind = np.zeros_like(solid)
        # free cell whose neighbour at −f is solid (off-grid counts as solid)
        shifted = np.ones_like(solid)
        src_r = slice(max(0, -f[0]), h - max(0, f[0]))
        dst_r = slice(max(0, f[0]), h - max(0, -f[0]))
        src_c = slice(max(0, -f[1]), w - max(0, f[1]))
        dst_c = slice(max(0, f[1]), w - max(0, -f[1]))
        shifted[dst_r, dst_c] = solid[src_r, src_c]
        behind = region & shifted
        for i, j in zip(*np.nonzero(behind), strict=True):
            i, j = int(i), int(j)
            if not solid_box.all_true(*_rect(i, j, f, -1, -1, kw)):
                continue
            if not clear_box.all_true(*_rect(i, j, f, 0, depth - 1, kc)):
                continue
            u = (j + 0.5 - 0.5 * f[1]) * res  # the shared edge with the solid neighbour
            v = (i + 0.5 - 0.5 * f[0]) * res
            xy = _local_to_world(data, np.array([[u, v]]))[0]
            out.append((Pose2(float(xy[0]), float(xy[1]), yaw + data.origin[2]), i, j))
    return out


def place_dock(data: MapData) -> Pose2:
    """The dock station's pose for a bare floor plan (on the wall face, x into the room).

    Raises ``ValueError`` if no wall has room for a dock.
    """
    region = main_component(~solid_mask(data))
    spots = wall_spots(data, DOCK_WALL_HALF, CLEAR_HALF, CLEAR_DEPTH, region)
    if not spots:
        raise ValueError("no straight wall with ~1.5 m of clear floor in front of it for the dock")
    # The component's centroid from its row and column counts (no index arrays over a large map).
    per_row, per_col = region.sum(axis=1), region.sum(axis=0)
    total = float(per_row.sum())
    row_mean = float(per_row @ np.arange(len(per_row))) / total
    col_mean = float(per_col @ np.arange(len(per_col))) / total
    centre = _local_to_world(data, np.array([[(col_mean + 0.5) * data.resolution,
                                              (row_mean + 0.5) * data.resolution]]))[0]
    best = min(spots, key=lambda s: (round(math.hypot(s[0].x - centre[0], s[0].y - centre[1]), 6), s[1], s[2]))
    return best[0]


def place_tags(data: MapData, n: int, tag_width: float, dock: Pose2, region: np.ndarray) -> list[Pose2]:
    """``n`` wall-face poses for tags, spread out by farthest-point sampling from the dock.

    ``tag_width`` [m] is the printed tag's full width (with its white border).
    May return fewer than ``n`` if the walls have too few places.
    """
    spots = [s[0] for s in wall_spots(data, tag_width / 2 + 0.05, max(tag_width / 2, TAG_CLEAR_HALF),
                                      TAG_CLEAR_DEPTH, region)]
    pts = np.array([[p.x, p.y] for p in spots]).reshape(-1, 2)
    if len(spots) == 0 or n <= 0:
        return []
    d = np.hypot(pts[:, 0] - dock.x, pts[:, 1] - dock.y)
    ok = d >= TAG_DOCK_GAP
    chosen: list[int] = []
    nearest = np.where(ok, d, -np.inf)
    for _ in range(n):
        k = int(np.argmax(nearest))
        if not np.isfinite(nearest[k]) or nearest[k] <= 0.0:
            break
        chosen.append(k)
        nearest = np.minimum(nearest, np.hypot(pts[:, 0] - pts[k, 0], pts[:, 1] - pts[k, 1]))
        nearest[~ok] = -np.inf
    return [spots[k] for k in chosen]
