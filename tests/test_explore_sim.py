"""Exploration end to end: the bundled mission, the runner and the pybullet TurtleBot in a small three-room world."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from homing.map_server import FREE, OCCUPIED, UNKNOWN, MapData, save_map

RES = 0.05  # [m]


def three_rooms(folder: Path) -> Path:
    """An 8 m × 4 m floor split into three rooms by walls at x = 2.7 m (door at the north end) and x = 5.3 m
    (door at the south end), so no room sees into the next but one; map_server YAML (the sim places the dock)."""
    margin, wall = 0.5, 0.10  # [m]
    w, h = 8.0, 4.0
    g = np.full((round((h + 2 * margin) / RES), round((w + 2 * margin) / RES)), UNKNOWN, dtype=np.int8)
    i0, i1 = round((margin - wall) / RES), round(margin / RES)
    g[i0:-i0, i0:-i0] = OCCUPIED
    g[i1:-i1, i1:-i1] = FREE
    for x, (y0, y1) in ((2.7, (2.8, 4.0)), (5.3, (0.0, 1.2))):
        c = round((margin + x) / RES)
        g[i1:-i1, c - 1 : c + 1] = OCCUPIED
        g[round((margin + y0) / RES) : round((margin + y1) / RES), c - 1 : c + 1] = FREE  # the door
    return save_map(folder / "three_rooms.yaml", MapData(g, RES, (-margin, -margin, 0.0)))


@pytest.mark.slow
@pytest.mark.parametrize("strategy", ["frontier_travel", "gain_rate"])
def test_explores_three_rooms_without_touching_anything(tmp_path: Path, strategy: str) -> None:
    from homing.benchmarks.explore import run_one
    from homing.mapping.map_io import load_grid

    world = three_rooms(tmp_path)
    saved = tmp_path / "final.yaml"
    r = run_one(str(world), strategy, seed=4, minutes=6.0, save_map=str(saved))
    assert r.done, "no frontier left before the time limit"
    assert r.coverage >= 0.95, r  # of the free area reachable from the dock, from the sim's truth
    assert r.bumps == 0
    assert r.agreement >= 0.95  # the grid agrees with the true floor plan (the matcher drifts ~2° here: see report)
    assert r.goals >= 3 and r.farthest > 2.0  # it drove through the doors, not just looked
    grid = load_grid(saved)
    assert abs((grid.data == FREE).sum() * grid.resolution**2 - r.area) < 0.01
