"""Grid accuracy against a true map: cell agreement on observed cells, coverage of the navigable area (evaluation code only).

The robot's ``map`` frame is its ``odom`` frame at start, so comparing needs
``world_from_map``: the true pose of the map frame in the true map's frame
(the robot's true start pose, which only the simulator knows). Every cell of
the grid is looked up in the truth at its centre's world position (nearest
cell). Nothing here may run on the robot: it reads ground truth.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import cv2
import numpy as np
from homing.mapping.blocks import block_any
from homing.mapping.grid import OccupancyGrid
from homing.mapping.navigable import (
    MAP_MARGIN,
    MAP_RESOLUTION,
    Navigable,
    disc,
    inscribed_radius,
    navigable,
)
from homing.robot import Pose2

from homing.map_server import FREE, UNKNOWN, MapData

OCCUPIED_AT = 65  # map_server values ≥ this are walls


def truth_under_grid(grid: OccupancyGrid, truth: MapData, world_from_map: Pose2 | None = None) -> np.ndarray:
    """(H, W) int8: the true map's value under each grid cell's centre (UNKNOWN outside the truth)."""
    world_from_map = world_from_map or Pose2()
    h, w = grid.shape
    key = (h, w, grid.origin, grid.resolution, world_from_map)
    if _LOOKUP.get("key") != key or _LOOKUP.get("truth") is not truth.grid:
        # Which truth cell lies under each grid cell changes only when the grid grows: a run samples coverage
        # every few seconds on a grid of a million cells, so the lookup is kept (it holds the truth it indexes).
        rows, cols = np.mgrid[0:h, 0:w]
        x, y = grid.cell_to_world(rows.ravel(), cols.ravel())
        pts = world_from_map.transform_points(np.column_stack([x, y]))
        tc = np.floor((pts[:, 0] - truth.origin[0]) / truth.resolution).astype(np.int64)
        tr = np.floor((pts[:, 1] - truth.origin[1]) / truth.resolution).astype(np.int64)
        th, tw = truth.grid.shape
        ok = (tr >= 0) & (tr < th) & (tc >= 0) & (tc < tw)
        _LOOKUP.update(key=key, truth=truth.grid, ok=ok, flat=tr[ok] * tw + tc[ok])
    out = np.full(h * w, UNKNOWN, dtype=np.int8)
    out[_LOOKUP["ok"]] = truth.grid.ravel()[_LOOKUP["flat"]]
    return out.reshape(h, w)


_LOOKUP: dict[str, Any] = {}  # truth_under_grid's last lookup: its key, the truth grid, the in-truth mask, flat indices


def cell_agreement(grid: OccupancyGrid, truth: MapData, world_from_map: Pose2 | None = None, tolerance: int = 1) -> float:
    """Fraction of observed grid cells (free or occupied, over known truth) whose class matches the truth.

    An occupied cell agrees if the truth has a wall within ``tolerance``
    grid cells (walls are one truth cell thick and a lidar end point lands on
    their face); a free cell agrees if the truth is free there.
    """
    data = grid.data
    t = truth_under_grid(grid, truth, world_from_map)
    observed = (data != UNKNOWN) & (t != UNKNOWN)
    if not observed.any():
        return float("nan")
    t_occ = (t >= OCCUPIED_AT).astype(np.uint8)
    if tolerance > 0:
        t_occ_near = cv2.dilate(t_occ, np.ones((2 * tolerance + 1,) * 2, np.uint8)).astype(bool)
    else:
        t_occ_near = t_occ.astype(bool)
    agree_occ = (data >= OCCUPIED_AT) & t_occ_near
    agree_free = (data == FREE) & (t == FREE)
    return float((agree_occ | agree_free)[observed].mean())


ALIGN_REACH = (0.10, math.radians(0.6))  # [m, rad] the largest correction aligned_agreement searches


def aligned_agreement(grid: OccupancyGrid, truth: MapData, world_from_map: Pose2 | None = None, tolerance: int = 1,
                      reach: tuple[float, float] = ALIGN_REACH) -> tuple[float, Pose2]:
    """:func:`cell_agreement` after the small rigid correction of the map frame that maximises it, and that correction.

    ``cell_agreement`` pins the map to the robot's true start pose. A map built
    with its heading 0.3° off in the first minutes (gyro drift before its
    walls settle) then disagrees along every far wall and round every object
    by a cell or two, however consistently the robot lives in it afterwards.
    Map evaluations align the two maps before they compare them; this searches
    shifts within ``reach[0]`` [m] and turns within ``reach[1]`` [rad] about the
    map's origin, on a coarse lattice (half the reach) and then a fine one
    (a quarter) round the best. The correction is in the map frame:
    ``world_from_map.compose(correction)`` is the aligned pose of the map.
    """
    world_from_map = world_from_map or Pose2()
    data = grid.data
    rows, cols = np.nonzero(data != UNKNOWN)
    if not rows.size:
        return float("nan"), Pose2()
    x, y = grid.cell_to_world(rows, cols)
    xy = np.column_stack([x, y])
    occ, free = data[rows, cols] >= OCCUPIED_AT, data[rows, cols] == FREE
    t_occ = (truth.grid >= OCCUPIED_AT).astype(np.uint8)
    near = cv2.dilate(t_occ, np.ones((2 * tolerance + 1,) * 2, np.uint8)).astype(bool) if tolerance > 0 else t_occ > 0
    th, tw = truth.grid.shape

    def score(c: Pose2) -> float:
        pts = world_from_map.compose(c).transform_points(xy)
        tc = np.floor((pts[:, 0] - truth.origin[0]) / truth.resolution).astype(np.int64)
        tr = np.floor((pts[:, 1] - truth.origin[1]) / truth.resolution).astype(np.int64)
        ok = (tr >= 0) & (tr < th) & (tc >= 0) & (tc < tw)
        tv = np.full(len(pts), UNKNOWN, np.int8)
        tv[ok] = truth.grid[tr[ok], tc[ok]]
        seen = tv != UNKNOWN
        if not seen.any():
            return float("nan")
        hit = np.zeros(len(pts), bool)
        hit[ok] = near[tr[ok], tc[ok]]
        return float(((occ & hit) | (free & (tv == FREE)))[seen].mean())

    best, best_c = score(Pose2()), Pose2()
    centre = best_c
    for step in (0.5, 0.25):
        dxy, dth = reach[0] * step, reach[1] * step
        for i in (-2, -1, 0, 1, 2) if step == 0.5 else (-1, 0, 1):
            for j in (-2, -1, 0, 1, 2) if step == 0.5 else (-1, 0, 1):
                for k in (-2, -1, 0, 1, 2) if step == 0.5 else (-1, 0, 1):
                    c = Pose2(centre.x + i * dxy, centre.y + j * dxy, centre.theta + k * dth)
                    a = score(c)
                    if a > best:
                        best, best_c = a, c
        centre = best_c
    return best, best_c


def reachable_free(truth: MapData, start_xy: tuple[float, float]) -> np.ndarray:
    """(H, W) bool over the truth: free cells 8-connected to the free cell at ``start_xy`` [m, truth frame]."""
    free = (truth.grid == FREE).astype(np.uint8)
    _, labels = cv2.connectedComponents(free, connectivity=8)
    c = int(np.floor((start_xy[0] - truth.origin[0]) / truth.resolution))
    r = int(np.floor((start_xy[1] - truth.origin[1]) / truth.resolution))
    lab = labels[r, c]
    if lab == 0:  # started on a wall cell's edge: take the nearest free label
        rr, cc = np.nonzero(labels)
        i = int(np.argmin((rr - r) ** 2 + (cc - c) ** 2))
        lab = labels[rr[i], cc[i]]
    return labels == lab


_NAVIGABLE: dict[str, Any] = {}  # navigable_truth's last answer: its key, the truth grid it holds, the answer


def navigable_truth(truth: MapData, start_xy: tuple[float, float]) -> Navigable:
    """The navigable area of the true map from ``start_xy`` [m, truth frame] (:mod:`homing.mapping.navigable`:
    the costmap's rule on the plan as the robot's map can draw it, ``MAP_MARGIN``), and the places behind
    passages narrower than the robot. A plan coarser than the robot's grid is worked on at the grid's cells
    (a 0.1 m plan's 0.5 and 0.6 m passages are both 5 cells wide from their middle: only the robot's cells
    tell them apart) and its mask and region given back on the plan's cells. The last answer is kept (a run asks every few seconds)."""
    key = (truth.grid.shape, truth.resolution, tuple(truth.origin[:2]), tuple(start_xy))
    if _NAVIGABLE.get("key") != key or _NAVIGABLE.get("truth") is not truth.grid:
        free, origin = truth.grid == FREE, (truth.origin[0], truth.origin[1])
        k = int(round(truth.resolution / MAP_RESOLUTION))
        if k < 2 or abs(k * MAP_RESOLUTION - truth.resolution) > 1e-9:  # as fine as the grid, or no multiple
            value = navigable(free, truth.resolution, origin, start_xy, margin=MAP_MARGIN)
        else:
            fine = navigable(np.repeat(np.repeat(free, k, axis=0), k, axis=1), MAP_RESOLUTION, origin, start_xy,
                             margin=MAP_MARGIN)
            h, w = free.shape  # the mask: half a cell's parts or more (its centre, near enough); the region: any
            mask = (fine.mask.reshape(h, k, w, k).mean(axis=(1, 3)) >= 0.5) & free
            value = Navigable(mask, block_any(fine.region, k) & free, float(mask.sum()) * truth.resolution**2,
                              fine.blocked)
        _NAVIGABLE.update(key=key, truth=truth.grid, value=value)
    return _NAVIGABLE["value"]


_CELLS: dict[str, Any] = {}  # _under_navigable's navigable cells: the answer they come from, rows, cols, centres


def _under_navigable(grid: OccupancyGrid, truth: MapData, start_xy: tuple[float, float],
                     world_from_map: Pose2 | None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The truth's navigable cells (rows, cols) and the grid's value under each one's centre (UNKNOWN off it)."""
    world_from_map = world_from_map or Pose2()
    nav = navigable_truth(truth, start_xy)
    if _CELLS.get("of") is not nav:  # the cells and their centres, kept with the answer they come from
        rows, cols = np.nonzero(nav.mask)
        xy = np.column_stack([truth.origin[0] + (cols + 0.5) * truth.resolution,
                              truth.origin[1] + (rows + 0.5) * truth.resolution])
        _CELLS.update({"of": nav, "rows": rows, "cols": cols, "xy": xy})
    rows, cols = _CELLS["rows"], _CELLS["cols"]
    pts = world_from_map.inverse().transform_points(_CELLS["xy"])
    gr, gc = grid.world_to_cell(pts[:, 0], pts[:, 1])
    ok = grid.in_bounds(gr, gc)
    value = np.full(len(rows), UNKNOWN, dtype=grid.data.dtype)
    value[ok] = grid.data[gr[ok], gc[ok]]
    return rows, cols, value


def unseen_places(grid: OccupancyGrid, truth: MapData, start_xy: tuple[float, float],
                  world_from_map: Pose2 | None = None, min_area: float = 1.0) -> list[float]:
    """Areas [m²], largest first, of the places in the navigable area the grid has not observed (unknown under
    their centres) that are at least ``min_area`` [m²]: the unseen cells the robot's footprint (its inscribed
    disc) fits in whole, by 8-connected piece (an opening), so a corner, or a strip along a wall the map draws
    a few cells off (a degree of misregistration over a 20 m wall), is no place."""
    rows, cols, value = _under_navigable(grid, truth, start_xy, world_from_map)
    unseen = np.zeros(truth.grid.shape, np.uint8)
    unseen[rows, cols] = value == UNKNOWN
    places = cv2.morphologyEx(unseen, cv2.MORPH_OPEN, disc(inscribed_radius(truth.resolution) / truth.resolution))
    _, _, stats, _ = cv2.connectedComponentsWithStats(places, connectivity=8)
    areas = stats[1:, cv2.CC_STAT_AREA].astype(float) * truth.resolution**2
    return sorted((float(a) for a in areas if a >= min_area), reverse=True)


@dataclass(frozen=True)
class Coverage:
    """Explored area [m²] (grid free cells), the fraction of the truth's navigable area the grid has observed
    (``coverage``) and has observed as free (``free_coverage``), and cell agreement on observed cells."""

    area: float
    coverage: float
    agreement: float
    free_coverage: float


def coverage(grid: OccupancyGrid, truth: MapData, start_xy: tuple[float, float], world_from_map: Pose2 | None = None) -> Coverage:
    """How much of the truth's navigable area from ``start_xy`` (:func:`navigable_truth`) the grid has observed.

    Computed on the truth's cells: a truth cell counts as covered if the grid
    cell under its centre is known (free or occupied). Exploration is about
    having looked at a place; whether the map got it right is
    :func:`cell_agreement`'s question. Counting only cells mapped FREE would
    charge a map's small misregistration (a wall face drawn one cell into the
    room, a 2 cm drift along a 20 m wall) to the exploration strategy:
    ``free_coverage`` keeps that stricter figure for reference.
    """
    rows, _, value = _under_navigable(grid, truth, start_xy, world_from_map)
    area = float((grid.data == FREE).sum()) * grid.resolution**2
    if not len(rows):
        return Coverage(area, float("nan"), cell_agreement(grid, truth, world_from_map or Pose2()), float("nan"))
    return Coverage(area, float((value != UNKNOWN).mean()), cell_agreement(grid, truth, world_from_map),
                    float((value == FREE).mean()))
