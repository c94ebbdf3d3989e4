"""Frontier segments of an occupancy grid: the thesis's smoothed algorithm 1 (Mata 2017, §2.4.1) and the raw frontier of Yamauchi (1997).

Smoothed (:func:`smoothed_frontiers`, algorithm 1):

1. threshold the grid into unknown ``u``, occupied ``o`` and free masks;
2. dilate ``o`` by the robot's radius (where the robot's centre cannot go);
3. distance transform of the cells that are neither unknown nor dilated
   occupied: ``d`` = distance to the nearest of either;
4. contours (OpenCV) of the level set ``d > margin``: the boundary of the
   space the robot fits in with ``margin`` to spare. Thin free spikes left by
   single lidar rays into the unknown have no cell that far from their
   sides, so they vanish — this is the smoothing;
5. the contour points whose nearest blocker is unknown (not a wall) are
   frontier; consecutive runs of them along a contour are the segments;
6. segments shorter than ``min_size`` are dropped; :func:`keep_reachable`
   then keeps the cells the planner can reach.

Every goal cell of a smoothed segment is therefore at least
``robot_radius + margin`` from walls and ``margin`` from unknown space.

Raw (:func:`raw_frontiers`, the thesis's "pre-smoothing" variant): free cells
8-adjacent to unknown cells, grouped into 8-connected components. Goal cells
are the frontier cells themselves, which can be too close to walls to reach.

Grids are map_server views: (H, W) int8, FREE 0 / OCCUPIED 100 / UNKNOWN −1,
row 0 at the lowest y. Cells are (row, col) int arrays.
"""

from __future__ import annotations

import argparse
import math
from dataclasses import dataclass

import cv2
import numpy as np
from homing.mapping.distance import distance_cells
from homing.robot.turtlebot import FOOTPRINT_RADIUS

from homing.map_server import FREE, UNKNOWN

MARGIN = 0.10  # [m] clearance from unknown space (and beyond the footprint from walls) of smoothed goal cells
MIN_SEGMENT = 0.30  # [m] segments shorter than this are dropped (thesis: "drop small segments")
OCCUPIED_AT = 65  # map_server values ≥ this are walls


@dataclass(frozen=True)
class FrontierSegment:
    """One frontier segment: its candidate goal cells (N, 2) int (row, col), in order along the frontier."""

    cells: np.ndarray
    label: int

    @property
    def size(self) -> int:
        """Number of goal cells: the segment's weight in the thesis (§2.4.1)."""
        return int(len(self.cells))

    def centroid(self) -> np.ndarray:
        """(2,) float (row, col) mean of the cells (may fall off the frontier on a curved segment)."""
        return self.cells.mean(axis=0)

    def subset(self, keep: np.ndarray) -> FrontierSegment:
        return FrontierSegment(self.cells[keep], self.label)


def _disc(radius_cells: float) -> np.ndarray:
    r = max(0, int(math.ceil(radius_cells - 1e-9)))
    yy, xx = np.mgrid[-r : r + 1, -r : r + 1]
    return (xx * xx + yy * yy <= radius_cells * radius_cells + 1e-9).astype(np.uint8)


def _distance(mask_zero: np.ndarray) -> np.ndarray:
    """Distance [cells] from every cell to the nearest cell where ``mask_zero`` is True."""
    return distance_cells(~mask_zero)


def accessible_mask(grid: np.ndarray, resolution: float, robot_radius: float = FOOTPRINT_RADIUS) -> np.ndarray:
    """(H, W) bool: known-free cells at least ``robot_radius`` [m] from any wall (where the robot's centre fits)."""
    occ = grid >= OCCUPIED_AT
    dil = cv2.dilate(occ.astype(np.uint8), _disc(robot_radius / resolution)).astype(bool)
    return (grid == FREE) & ~dil


def smoothed_frontiers(
    grid: np.ndarray,
    resolution: float,
    robot_radius: float = FOOTPRINT_RADIUS,
    margin: float = MARGIN,
    min_size: float = MIN_SEGMENT,
) -> list[FrontierSegment]:
    """The thesis's algorithm 1 (module doc): segments of goal cells, each ≥ ``min_size`` [m] long."""
    unknown = grid == UNKNOWN
    occ = grid >= OCCUPIED_AT
    occ_dil = cv2.dilate(occ.astype(np.uint8), _disc(robot_radius / resolution)).astype(bool)
    blocked = unknown | occ_dil | (grid != FREE)
    d = _distance(blocked)
    k = max(1.0, margin / resolution)
    region = (d > k).astype(np.uint8)
    contours, _ = cv2.findContours(region, cv2.RETR_LIST, cv2.CHAIN_APPROX_NONE)
    if not contours:
        return []
    d_unknown = _distance(unknown)
    d_occ = _distance(occ_dil)
    min_cells = max(1, int(round(min_size / resolution)))
    segments: list[FrontierSegment] = []
    for contour in contours:
        pts = contour.reshape(-1, 2)[:, ::-1]  # OpenCV gives (x=col, y=row)
        rows, cols = pts[:, 0], pts[:, 1]
        du, do = d_unknown[rows, cols], d_occ[rows, cols]
        flag = (du <= do) & (du <= k + 2.0)
        for run in _cyclic_runs(flag):
            if len(run) >= min_cells:
                cells = np.unique(pts[run], axis=0) if len(run) > 1 else pts[run]
                if len(cells) >= min_cells:
                    segments.append(FrontierSegment(cells.astype(np.int64), len(segments)))
    return segments


def _cyclic_runs(flag: np.ndarray) -> list[np.ndarray]:
    """Index arrays of the maximal runs of True in a cyclic boolean sequence."""
    n = len(flag)
    if n == 0 or not flag.any():
        return []
    if flag.all():
        return [np.arange(n)]
    # Rotate so the sequence starts just after a False: no run wraps around then.
    start = int(np.argmin(flag)) + 1
    idx = (np.arange(n) + start) % n
    f = flag[idx].astype(np.int8)
    edges = np.diff(np.concatenate([[0], f, [0]]))
    begins, ends = np.flatnonzero(edges == 1), np.flatnonzero(edges == -1)
    return [idx[b:e] for b, e in zip(begins, ends, strict=False)]


def raw_frontiers(grid: np.ndarray, resolution: float, min_size: float = MIN_SEGMENT) -> list[FrontierSegment]:
    """Yamauchi's frontier without smoothing: free cells 8-adjacent to unknown, 8-connected segments ≥ ``min_size`` [m]."""
    unknown = (grid == UNKNOWN).astype(np.uint8)
    near_unknown = cv2.dilate(unknown, np.ones((3, 3), np.uint8)).astype(bool)
    frontier = (grid == FREE) & near_unknown
    n, labels = cv2.connectedComponents(frontier.astype(np.uint8), connectivity=8)
    if n <= 1:
        return []
    rows, cols = np.nonzero(labels)
    lab = labels[rows, cols]
    order = np.argsort(lab, kind="stable")
    rows, cols, lab = rows[order], cols[order], lab[order]
    splits = np.flatnonzero(np.diff(lab)) + 1
    min_cells = max(1, int(round(min_size / resolution)))
    segments: list[FrontierSegment] = []
    for r, c in zip(np.split(rows, splits), np.split(cols, splits), strict=False):
        if len(r) >= min_cells:
            segments.append(FrontierSegment(np.column_stack([r, c]).astype(np.int64), len(segments)))
    return segments


def keep_reachable(segments: list[FrontierSegment], distance: np.ndarray) -> list[FrontierSegment]:
    """Keep each segment's cells with a finite travel distance (``distance`` (H, W) [m], inf = unreachable);
    drop segments left empty. Labels are kept, so segments stay recognisable."""
    out = []
    for seg in segments:
        keep = np.isfinite(distance[seg.cells[:, 0], seg.cells[:, 1]])
        if keep.any():
            out.append(seg.subset(keep))
    return out


def frontier_mask(segments: list[FrontierSegment], shape: tuple[int, int]) -> np.ndarray:
    """(H, W) int32 label image: segment label + 1 on its cells, 0 elsewhere."""
    out = np.zeros(shape, dtype=np.int32)
    for seg in segments:
        out[seg.cells[:, 0], seg.cells[:, 1]] = seg.label + 1
    return out


def demo_grid(resolution: float = 0.05) -> np.ndarray:
    """A hand-built partial map: a known room with a doorway and lidar spikes into the unknown."""
    g = np.full((160, 200), UNKNOWN, dtype=np.int8)
    g[20:120, 20:120] = FREE
    g[20:120, 20] = g[20:120, 119] = 100
    g[20, 20:120] = g[119, 20:120] = 100
    g[60:80, 119] = FREE  # doorway to the east
    g[60:80, 120:150] = FREE  # seen a bit beyond it
    g[100:119, 60:62] = FREE
    g[119, 60:62] = FREE
    g[120:150, 60:62] = FREE  # a thin lidar spike north: smoothing removes it
    return g


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--plot", metavar="PNG", help="write a picture of both frontier variants")
    args = parser.parse_args()
    g = demo_grid()
    smooth = smoothed_frontiers(g, 0.05)
    raw = raw_frontiers(g, 0.05)
    print(f"smoothed: {len(smooth)} segments {[s.size for s in smooth]}; raw: {len(raw)} segments {[s.size for s in raw]}")
    if args.plot:
        from homing.mapping.render import render_grid

        from homing.atomic import atomic_write

        left = render_grid(g, smooth, scale=3)
        right = render_grid(g, raw, scale=3)
        ok, png = cv2.imencode(".png", np.hstack([left, np.full((left.shape[0], 6, 3), 80, np.uint8), right]))
        atomic_write(args.plot, png.tobytes())
        print(f"wrote {args.plot} (left: smoothed, right: raw)")


if __name__ == "__main__":
    main()
