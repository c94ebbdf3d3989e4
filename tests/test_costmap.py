"""Costmap layers against geometry: inflation radii and decay, scan marking and clearing, clear, grid growth."""

from __future__ import annotations

import math

import numpy as np
from homing.navigation.costmap import (
    INSCRIBED,
    LETHAL,
    MAX_NON_OBSTACLE,
    NO_INFORMATION,
    Costmap,
    CostmapParams,
)
from homing.robot import Pose2, Scan
from homing.robot.turtlebot import FOOTPRINT_RADIUS

RES = 0.05  # [m]


def _single_obstacle() -> Costmap:
    g = np.zeros((81, 81), dtype=np.int8)
    g[40, 40] = 100
    cm = Costmap()
    cm.set_static(g, RES, (0.0, 0.0))
    return cm


def test_inflation_follows_the_footprint_and_the_decay() -> None:
    cm = _single_obstacle()
    rr, cc = np.indices(cm.shape)
    d = np.hypot(rr - 40, cc - 40) * RES  # exact centre distance to the obstacle cell
    r_in = FOOTPRINT_RADIUS + 0.5 * RES
    assert cm.cost[40, 40] == LETHAL
    assert np.all(cm.cost[(d > 0) & (d <= r_in)] == INSCRIBED)
    ring = (d > r_in) & (d < 0.55 - 1e-6)  # away from the float32 edge at exactly 0.55
    want = np.floor(MAX_NON_OBSTACLE * np.exp(-5.0 * (d[ring] - r_in)))
    assert np.array_equal(cm.cost[ring], want.astype(np.uint8))
    assert np.all(cm.cost[d > 0.55 + 1e-6] == 0)
    assert np.allclose(cm.clearance, d, atol=1e-4)
    # Decay is monotone: farther is never costlier.
    order = np.argsort(d[ring])
    assert np.all(np.diff(cm.cost[ring][order].astype(int)) <= 0)


def test_unknown_stays_unknown_unless_the_footprint_would_touch() -> None:
    g = np.full((40, 40), -1, dtype=np.int8)
    g[:, :20] = 0
    g[20, 18] = 100
    cm = Costmap()
    cm.set_static(g, RES, (0.0, 0.0))
    assert cm.cost[5, 35] == NO_INFORMATION
    assert cm.cost[20, 20] == INSCRIBED  # unknown, but 2 cells from the obstacle
    assert cm.cost[5, 5] == 0


def _scan_with_point_ahead(rng_ahead: float, stamp: float = 0.0) -> Scan:
    ranges = np.full(360, np.inf, dtype=np.float32)
    ranges[180] = rng_ahead  # angle 0: straight ahead
    return Scan(stamp, -math.pi, math.radians(1.0), ranges, 0.15, 6.0)


def test_scan_marks_and_later_rays_clear() -> None:
    cm = Costmap()
    cm.set_static(np.zeros((80, 80), dtype=np.int8), RES, (0.0, 0.0))
    pose = Pose2(1.0, 2.0, 0.0)
    cm.update_scan(_scan_with_point_ahead(1.02), pose)
    rc = cm.world_to_cell(np.array([2.02, 2.0]))[0]
    assert cm.cost[rc[0], rc[1]] == LETHAL
    assert cm.obstacles.sum() == 1
    # The obstacle went away: a ray now passes through its cell to a far point.
    cm.update_scan(_scan_with_point_ahead(2.0, stamp=0.2), pose)
    assert cm.cost[rc[0], rc[1]] < INSCRIBED
    assert cm.obstacles.sum() == 1  # only the new end point


def test_marks_beyond_the_marking_range_are_ignored() -> None:
    cm = Costmap(CostmapParams(obstacle_max_range=2.5))
    cm.set_static(np.zeros((100, 100), dtype=np.int8), RES, (0.0, 0.0))
    cm.update_scan(_scan_with_point_ahead(3.0), Pose2(0.5, 2.5, 0.0))
    assert cm.obstacles.sum() == 0


def test_clear_empties_the_obstacle_layer_but_keeps_the_static_map() -> None:
    g = np.zeros((80, 80), dtype=np.int8)
    g[10, 10] = 100
    cm = Costmap()
    cm.set_static(g, RES, (0.0, 0.0))
    cm.update_scan(_scan_with_point_ahead(1.0), Pose2(1.0, 2.0, 0.0))
    assert cm.obstacles.any()
    cm.clear()
    assert not cm.obstacles.any()
    assert cm.cost[10, 10] == LETHAL
    assert (cm.cost == LETHAL).sum() == 1


def test_obstacle_marks_survive_the_grid_growing() -> None:
    cm = Costmap()
    cm.set_static(np.zeros((40, 40), dtype=np.int8), RES, (0.0, 0.0))
    cm.update_scan(_scan_with_point_ahead(1.0), Pose2(0.5, 1.0, 0.0))
    before = cm.cost_at(np.array([[1.5, 1.0]]))[0]
    cm.set_static(np.zeros((60, 60), dtype=np.int8), RES, (-0.5, -0.5))  # grew left and down
    assert before == LETHAL and cm.cost_at(np.array([[1.5, 1.0]]))[0] == LETHAL
    assert cm.obstacles.sum() == 1


def test_rotated_scan_lands_in_the_map_frame() -> None:
    cm = Costmap()
    cm.set_static(np.zeros((80, 80), dtype=np.int8), RES, (0.0, 0.0))
    cm.update_scan(_scan_with_point_ahead(1.0), Pose2(2.0, 1.0, math.pi / 2))  # facing +y
    assert cm.cost_at(np.array([[2.0, 2.0]]))[0] == LETHAL


def test_updating_after_each_scan_gives_the_costmap_a_full_recomputation_gives() -> None:
    # The scan update re-inflates only round the lethal cells that changed; the result must be the same
    # as inflating the whole map from the layers, scan after scan (random rooms, poses and clutter).
    rng = np.random.default_rng(7)
    g = np.zeros((120, 160), dtype=np.int8)
    g[0, :] = g[-1, :] = g[:, 0] = g[:, -1] = 100
    g[60, 20:90] = 100  # an inner wall the scans' marks partly fall on
    cm = Costmap()
    cm.set_static(g, RES, (0.0, 0.0))
    n = 360
    for k in range(25):
        pose = Pose2(float(rng.uniform(1.0, 7.0)), float(rng.uniform(0.5, 2.5)), float(rng.uniform(-3, 3)))
        ranges = rng.uniform(0.3, 5.0, n).astype(np.float32)
        ranges[rng.random(n) < 0.2] = np.inf  # no return
        scan = Scan(stamp=0.2 * (k + 1), angle_min=-math.pi, angle_increment=2 * math.pi / n, ranges=ranges,
                    range_min=0.15, range_max=6.0)
        cm.update_scan(scan, pose)
        cost, clearance = cm.cost.copy(), cm.clearance.copy()
        cm._inflate()  # the whole map from the layers
        horizon = cm._horizon()
        assert np.array_equal(cost, cm.cost), f"scan {k}: cost differs from a full inflation"
        near = cm.clearance < horizon
        assert np.allclose(clearance[near], cm.clearance[near]), f"scan {k}: clearance differs"
        assert (clearance[~near] >= horizon - 1e-6).all()


def test_a_new_static_map_on_the_same_lattice_gives_what_a_full_recomputation_gives() -> None:
    # A new /map/grid snapshot re-inflates only round the cells whose static value changed (mapping touches
    # a few metres a second); the cost must be that of inflating the whole map, snapshot after snapshot:
    # walls appearing and vanishing, unknown cells becoming free, with scan marks in the obstacle layer.
    rng = np.random.default_rng(3)
    g = np.full((100, 140), -1, dtype=np.int8)
    g[40:60, 50:90] = 0
    cm = Costmap()
    cm.set_static(g, RES, (0.0, 0.0))
    cm._mark(np.array([[3.0, 2.5], [3.5, 2.6]]))
    cm._inflate()
    for k in range(20):
        r, c = int(rng.integers(5, 80)), int(rng.integers(5, 120))
        h, w = int(rng.integers(2, 20)), int(rng.integers(2, 20))
        g = g.copy()
        g[r:r + h, c:c + w] = rng.choice(np.array([-1, 0, 100], dtype=np.int8))
        if k % 3 == 0:
            g[r, c:c + w] = 100  # a wall drawn in a freed patch
        before = cm.version
        cm.set_static(g, RES, (0.0, 0.0))
        cost, clearance = cm.cost.copy(), cm.clearance.copy()
        cm._inflate()  # the whole map from the layers
        assert np.array_equal(cost, cm.cost), f"snapshot {k}: cost differs from a full inflation"
        near = cm.clearance < cm._horizon()
        assert np.allclose(clearance[near], cm.clearance[near]), f"snapshot {k}: clearance differs"
        assert cm.version > before  # readers of the cost see that it changed
    version = cm.version
    cm.set_static(g, RES, (0.0, 0.0))  # the same map again: nothing to redo
    assert cm.version == version


def test_a_grid_read_again_only_where_it_changed_gives_the_layers_of_the_whole_grid_read_afresh() -> None:
    from homing.mapping.grid import OccupancyGrid

    rng = np.random.default_rng(9)
    grid = OccupancyGrid(RES, (-2.0, -2.0), (80, 80))
    kept, afresh = Costmap(), Costmap()
    seen = 0
    for step in range(40):
        # A scan's worth of rays from a robot wandering east: the grid changes round it, and grows.
        origin = np.array([0.15 * step, 0.3 * math.sin(step / 5.0)])
        angles = np.linspace(-math.pi, math.pi, 180, endpoint=False)
        lengths = rng.uniform(0.5, 3.0, 180)
        grid.integrate_rays(origin, angles, lengths, rng.random(180) > 0.1)
        if step == 15:
            for cm in (kept, afresh):
                cm.require(6.0, -1.0, 9.0, 1.0)  # a goal beyond the grid: the layer padded to it
        if step == 30:
            for cm in (kept, afresh):
                cm.release()
        kept.update_static(grid)
        afresh.set_static(grid.data, grid.resolution, grid.origin)
        seen += kept._static_from is not None
        for name in ("static", "cost", "clearance", "obstacles"):
            assert np.array_equal(getattr(kept, name), getattr(afresh, name)), (step, name)
        assert kept.origin == afresh.origin
    assert seen == 40  # its changes known at every step: read in windows whenever the grid did not grow


def test_the_cost_looked_up_by_squared_distance_is_the_one_by_the_distance_squared_again() -> None:
    from homing.mapping.distance import distance_cells, squared_distance_cells

    rng = np.random.default_rng(13)
    cm = Costmap()
    for density in (0.0005, 0.01, 0.2):
        g = np.where(rng.random((150, 170)) < density, 100, 0).astype(np.int8)
        g[rng.random(g.shape) < 0.1] = -1
        cm.set_static(g, RES, (0.0, 0.0))
        # As first written: the distance, then its square rounded to index the table.
        cells = distance_cells(cm.static != LETHAL)
        lut = cm._cost_table()
        cost = lut[np.minimum(np.rint(cells * cells), len(lut) - 1).astype(np.intp)]
        cost[(cm.static == NO_INFORMATION) & (cost < INSCRIBED)] = NO_INFORMATION
        assert np.array_equal(cm.cost, cost)
        assert np.array_equal(cm.clearance, cells * np.float32(RES))
    # Far past the table: the squared distance read back from the distance is still the same whole number.
    n = np.arange(0, 1 << 22, dtype=np.float32)
    assert np.array_equal(np.rint(np.sqrt(n) * np.sqrt(n)), n)
    assert np.array_equal(np.sqrt(squared_distance_cells(np.ones((3, 3), bool))), distance_cells(np.ones((3, 3), bool)))
