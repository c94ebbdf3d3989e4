"""Known rooms for the simulator's tests: rectangles whose wall distances are analytic."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from homing.map_server import FREE, OCCUPIED, UNKNOWN, MapData, save_map

RES = 0.05  # [m/cell]
MARGIN = 0.5  # [m] around the room, outside the walls
WALL = 0.10  # [m]


def box_room(folder: Path, width: float, height: float, name: str = "room") -> Path:
    """Write a map_server map of an empty room [0, width] × [0, height] [m]; returns its YAML."""
    n_w = round((width + 2 * MARGIN) / RES)
    n_h = round((height + 2 * MARGIN) / RES)
    grid = np.full((n_h, n_w), UNKNOWN, dtype=np.int8)
    w0 = round((MARGIN - WALL) / RES)
    grid[w0 : n_h - w0, w0 : n_w - w0] = OCCUPIED
    i0 = round(MARGIN / RES)
    grid[i0 : n_h - i0, i0 : n_w - i0] = FREE
    return save_map(folder / f"{name}.yaml", MapData(grid, RES, (-MARGIN, -MARGIN, 0.0)))


def world_file(folder: Path, text: str, name: str = "world") -> Path:
    path = folder / f"{name}.yaml"
    path.write_text(text)
    return path


def range_to_box(x: float, y: float, angle: float, width: float, height: float) -> float:
    """Distance [m] from (x, y) inside [0, width] × [0, height] to its boundary along ``angle``."""
    c, s = math.cos(angle), math.sin(angle)
    ts = []
    if c > 1e-12:
        ts.append((width - x) / c)
    if c < -1e-12:
        ts.append(-x / c)
    if s > 1e-12:
        ts.append((height - y) / s)
    if s < -1e-12:
        ts.append(-y / s)
    return min(ts)
