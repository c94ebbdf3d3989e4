"""Exploration scoring against a true map (homing.mapping.evaluate): coverage counts observed places, agreement counts right ones."""

from __future__ import annotations

import numpy as np
import pytest
from homing.mapping.evaluate import (
    aligned_agreement,
    cell_agreement,
    coverage,
    navigable_truth,
    reachable_free,
)
from homing.mapping.grid import OccupancyGrid
from homing.robot import Pose2

from homing.map_server import FREE, OCCUPIED, UNKNOWN, MapData


def two_rooms() -> MapData:
    """4 m × 2 m at 0.1 m: two 2 m × 2 m rooms joined by a 1 m door, plus a sealed closet (not reachable)."""
    g = np.full((20, 40), FREE, np.int8)
    g[0, :] = g[-1, :] = g[:, 0] = g[:, -1] = OCCUPIED
    g[:, 20] = OCCUPIED
    g[5:15, 20] = FREE  # the door
    g[2:6, 30:36] = OCCUPIED  # closet walls
    g[3:5, 31:35] = FREE  # ... sealed inside
    return MapData(g, 0.1, (0.0, 0.0, 0.0))


def test_reachable_free_excludes_the_sealed_closet() -> None:
    truth = two_rooms()
    reach = reachable_free(truth, (1.0, 1.0))
    assert not reach[3:5, 31:35].any()
    assert reach[10, 20] and reach[10, 30]
    assert reach.sum() == (truth.grid == FREE).sum() - 8
    # The navigable area: the free cells the footprint sweeps; every free cell but the closet's and the
    # rooms' corners, which no 0.19 m disc between the walls reaches.
    nav = navigable_truth(truth, (1.0, 1.0))
    assert nav.mask[10, 20] and nav.mask[10, 30] and not nav.mask[3:5, 31:35].any() and not nav.blocked
    assert not nav.mask[1, 1] and 0.9 * reach.sum() < nav.mask.sum() < reach.sum()


def grid_from(values: np.ndarray, resolution: float = 0.1) -> OccupancyGrid:
    return OccupancyGrid.from_map_data(MapData(values, resolution, (0.0, 0.0, 0.0)), grow=False)


def test_coverage_counts_observed_cells_and_free_coverage_only_free_ones() -> None:
    truth = two_rooms()
    seen = np.full(truth.grid.shape, UNKNOWN, np.int8)
    seen[:, :21] = truth.grid[:, :21]  # the left room and the door's wall column
    reach = navigable_truth(truth, (1.0, 1.0)).mask  # what coverage counts
    left = reach[:, :21].sum() / reach.sum()
    cov = coverage(grid_from(seen), truth, (1.0, 1.0))
    assert cov.coverage == pytest.approx(left)
    assert cov.free_coverage == pytest.approx(left)
    assert cov.area == pytest.approx((seen == FREE).sum() * 0.01)
    assert cov.agreement == pytest.approx(1.0)

    # The same map with a row of the left room's free cells drawn as wall (a wall face two cells off, beyond
    # agreement's one-cell tolerance): still every place observed, so coverage stays; fewer cells free, and
    # the agreement drops.
    shifted = seen.copy()
    shifted[2, 1:20] = OCCUPIED
    cov2 = coverage(grid_from(shifted), truth, (1.0, 1.0))
    assert cov2.coverage == pytest.approx(left)
    assert cov2.free_coverage == pytest.approx(left - 19 / reach.sum())
    assert cov2.agreement < 1.0


def test_coverage_follows_the_grid_as_it_moves_and_grows() -> None:
    # Which truth cell lies under each grid cell is kept between calls (a run samples coverage every few
    # seconds): two grids of the same shape at different origins, then a grown one, must each read their own.
    truth = two_rooms()
    reach = navigable_truth(truth, (1.0, 1.0)).mask  # what coverage counts
    halves = []
    for c0 in (20, 0):
        g = OccupancyGrid(0.1, (c0 * 0.1, 0.0), (20, 20), grow=False)
        g.data[:] = truth.grid[:, c0 : c0 + 20]
        halves.append(coverage(g, truth, (1.0, 1.0)))
    assert [h.coverage for h in halves] == [pytest.approx(reach[:, 20:].sum() / reach.sum()),
                                            pytest.approx(reach[:, :20].sum() / reach.sum())]
    assert [h.agreement for h in halves] == [1.0, 1.0]
    for origin, at in (((0.0, 0.0), (0, 0)), ((-0.5, -0.3), (3, 5))):  # grown up and right; then down and left
        grown = OccupancyGrid(0.1, origin, (26, 45), grow=False)
        grown.data[at[0] : at[0] + 20, at[1] : at[1] + 20] = truth.grid[:, :20]
        assert coverage(grown, truth, (1.0, 1.0)) == halves[1]


def test_coverage_uses_the_map_frame_pose() -> None:
    """A grid built in a map frame rotated and moved from the world's reads through ``world_from_map``."""
    truth = two_rooms()
    world_from_map = Pose2(4.0, 2.0, np.pi)  # the map frame's origin at the far corner, facing back
    g = OccupancyGrid(0.1, (0.0, 0.0), (20, 40), grow=False)
    rows, cols = np.mgrid[0:20, 0:40]
    x, y = g.cell_to_world(rows.ravel(), cols.ravel())
    world = world_from_map.transform_points(np.column_stack([x, y]))
    tr = np.clip(np.floor(world[:, 1] / 0.1).astype(int), 0, 19)
    tc = np.clip(np.floor(world[:, 0] / 0.1).astype(int), 0, 39)
    values = truth.grid[tr, tc].reshape(20, 40)
    values[(world[:, 0] > 2.1).reshape(20, 40)] = UNKNOWN  # only the left room seen
    g2 = grid_from(values)
    reach = navigable_truth(truth, (1.0, 1.0)).mask  # what coverage counts
    left = reach[:, :21].sum() / reach.sum()
    assert coverage(g2, truth, (1.0, 1.0), world_from_map).coverage == pytest.approx(left)
    # Read without the transform, what was seen lands on the right room (and the closet's walls).
    assert coverage(g2, truth, (1.0, 1.0)).coverage == pytest.approx(reach[:, 19:].sum() / reach.sum())  # map cols ≥ 19
    assert cell_agreement(g2, truth, world_from_map) == pytest.approx(1.0)
    assert cell_agreement(g2, truth) < 0.95


def test_aligned_agreement_forgives_a_small_rigid_misregistration_and_finds_it() -> None:
    # A 6 m × 4 m floor at 5 cm with walls and a pillar; the robot's map of it is perfect but its frame sits
    # 5 cm and 0.3° off from where the truth says it started: pinned there, every wall face disagrees.
    g = np.full((80, 120), FREE, np.int8)
    g[:2, :] = g[-2:, :] = g[:, :2] = g[:, -2:] = OCCUPIED
    g[30:34, 20:100] = OCCUPIED
    g[55:62, 70:77] = OCCUPIED
    truth = MapData(g, 0.05, (0.0, 0.0, 0.0))
    start = Pose2(3.0, 1.0, 0.3)  # the robot's true start: the map frame
    error = Pose2(0.05, -0.025, np.radians(0.3))  # where its map frame really lies, seen from ``start``
    grid = OccupancyGrid(0.05, (-4.0, -3.0), (160, 200), grow=False)
    rows, cols = np.mgrid[0:160, 0:200]
    x, y = grid.cell_to_world(rows.ravel(), cols.ravel())
    world = start.compose(error).transform_points(np.column_stack([x, y]))
    tr = np.floor(world[:, 1] / 0.05).astype(int)
    tc = np.floor(world[:, 0] / 0.05).astype(int)
    inside = (tr >= 0) & (tr < 80) & (tc >= 0) & (tc < 120)
    values = np.full(160 * 200, UNKNOWN, np.int8)
    values[inside] = g[tr[inside], tc[inside]]
    values = values.reshape(160, 200)
    built = OccupancyGrid.from_map_data(MapData(values, 0.05, (-4.0, -3.0, 0.0)), grow=False)
    pinned = cell_agreement(built, truth, start)
    aligned, correction = aligned_agreement(built, truth, start)
    assert pinned < 0.99  # the misregistration is visible…
    assert aligned > 0.997 and aligned > pinned + 0.01  # …and aligned away
    assert abs(correction.x - error.x) <= 0.0125 and abs(correction.y - error.y) <= 0.0125
    assert abs(correction.theta - error.theta) <= np.radians(0.2)  # 0.15° turns a 3 m wall by less than a cell
    assert aligned_agreement(built, truth, start.compose(error))[0] == pytest.approx(cell_agreement(built, truth, start.compose(error)))
