"""Frontier segments on hand-built grids match their expected cells."""

from __future__ import annotations

import numpy as np
from homing.mapping.frontier import demo_grid, keep_reachable, raw_frontiers, smoothed_frontiers

from homing.map_server import FREE, OCCUPIED, UNKNOWN


def _room_open_north() -> np.ndarray:
    """Walls west, east and south of a free 40 × 60 block; unknown to the north."""
    g = np.full((80, 80), UNKNOWN, dtype=np.int8)
    g[10:50, 10:70] = FREE
    g[10:50, 10] = g[10:50, 69] = OCCUPIED
    g[10, 10:70] = OCCUPIED
    return g


def test_raw_frontier_is_free_cells_next_to_unknown():
    g = _room_open_north()
    segs = raw_frontiers(g, 0.05, min_size=0.1)
    assert len(segs) == 1
    cells = {tuple(c) for c in segs[0].cells}
    assert cells == {(49, c) for c in range(11, 69)}


def test_smoothed_frontier_keeps_clear_of_walls_and_unknown():
    g = _room_open_north()
    segs = smoothed_frontiers(g, 0.05, robot_radius=0.19, margin=0.10)
    assert len(segs) == 1
    rows, cols = segs[0].cells[:, 0], segs[0].cells[:, 1]
    # d > 2 cells from unknown (row 50): the contour is on row 47; 4-cell wall dilation + 2 margin from cols 10/69
    assert set(rows.tolist()) == {47}
    assert cols.min() >= 10 + 4 + 2 and cols.max() <= 69 - 4 - 2
    assert cols.max() - cols.min() + 1 == len(cols) >= 40


def test_smoothing_removes_a_thin_lidar_spike_raw_keeps_it():
    g = demo_grid()
    smooth = smoothed_frontiers(g, 0.05)
    raw = raw_frontiers(g, 0.05)
    spike = (slice(120, 150), slice(60, 62))
    in_spike = lambda seg: ((seg.cells[:, 0] >= 120) & (seg.cells[:, 1] >= 60) & (seg.cells[:, 1] < 62)).any()  # noqa: E731
    assert (g[spike] == FREE).all()
    assert any(in_spike(s) for s in raw)
    assert not any(in_spike(s) for s in smooth)
    # the doorway's frontier survives smoothing
    assert any((s.cells[:, 1] > 120).any() for s in smooth)


def test_keep_reachable_drops_unreachable_cells():
    g = _room_open_north()
    seg = smoothed_frontiers(g, 0.05)[0]
    dist = np.full(g.shape, np.inf)
    dist[:, :40] = 1.0
    kept = keep_reachable([seg], dist)
    assert len(kept) == 1 and (kept[0].cells[:, 1] < 40).all() and kept[0].size < seg.size
    assert keep_reachable([seg], np.full(g.shape, np.inf)) == []
