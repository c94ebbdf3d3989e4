"""The covering route behind the exploration bound: what a lidar sees, the greedy cover, and the route along a
corridor against its geometry."""

from __future__ import annotations

import numpy as np
import pytest
from homing.benchmarks.explore_bound import LIDAR_RANGE, greedy_cover, route, visible_cells

from homing.map_server import FREE, OCCUPIED, MapData

RES = 0.1  # [m]


def test_a_lidar_sees_its_room_and_not_through_the_wall():
    """Two 3 m × 3 m rooms side by side, a solid wall between: from the first room's middle every cell of it is
    seen, none of the second."""
    free = np.zeros((32, 63), bool)
    free[1:31, 1:31] = True
    free[1:31, 32:62] = True
    seen = np.zeros(free.size, bool)
    seen[visible_cells(free, RES, np.array([[15, 15]]))[0]] = True
    seen = seen.reshape(free.shape)
    assert seen[1:31, 1:31].all()
    assert not seen[:, 31:].any()


def test_on_a_fine_map_a_viewpoint_sees_every_cell_in_its_reach():
    """At 5 cm, 360 rays pass 10 cm apart 6 m out: a viewpoint would miss every other cell there, and the bound
    would charge viewpoints for them. Every cell of an empty hall within the lidar's reach is seen."""
    res = 0.05
    n = int(2 * LIDAR_RANGE / res) + 21
    free = np.ones((n, n), bool)
    c = n // 2
    seen = np.zeros(free.size, bool)
    seen[visible_cells(free, res, np.array([[c, c]]))[0]] = True
    yy, xx = np.mgrid[0:n, 0:n]
    within = np.hypot(yy - c, xx - c) * res <= LIDAR_RANGE - 2 * res
    assert seen.reshape(free.shape)[within].all()
    assert not seen.reshape(free.shape)[np.hypot(yy - c, xx - c) * res > LIDAR_RANGE + 2 * res].any()


def test_greedy_cover_takes_the_start_then_the_largest_gain():
    sets = [np.array([0, 1, 2]), np.array([2, 3]), np.array([3, 4, 5]), np.array([5])]
    assert greedy_cover(sets, 6, 0) == [0, 2]
    assert greedy_cover(sets, 4, 3) == [3, 0]  # then {3, 4, 5} adds 2, {0, 1, 2} adds 3


def test_the_route_along_a_corridor_goes_as_far_as_the_lidar_needs_and_no_farther():
    """A 20 m × 1.4 m corridor entered at its west end: 95 % of it is seen from a point no more than the lidar's
    range from its east end (so at least 20 − 1 − 6 m from the start), and no route need be longer than the
    corridor."""
    g = np.full((16, 202), OCCUPIED, np.int8)
    g[1:15, 1:201] = FREE
    truth = MapData(g, RES, (0.0, 0.0, 0.0))
    area, viewpoints, length = route(truth, (0.5, 0.8))
    assert area == pytest.approx(20.0 * 1.4, abs=0.1)  # the footprint sweeps all but the four corners
    assert viewpoints >= 2
    assert 20.0 - 0.05 * 20.0 - LIDAR_RANGE - 0.5 - 0.5 <= length <= 20.0
