"""Floor plans drawn for the tests, so the suite needs nothing beside the repository.

Four 25 m × 25 m map_server maps at 0.1 m per cell, drawn from rectangles
and lines, in the shapes of the public Explore-Bench blueprints the
development checkout keeps in ``../shared/worlds`` (that folder is not part
of a clone, and the tests must pass without it):

- ``loop``: a 2.8 m corridor around a 14 m block (drawn to the blueprint's
  cells: outer wall ring at cells 25..224, inner ring at 54..195);
- ``room``: one large room with four pillars and a central block;
- ``corridor``: two rooms joined by a 2 m corridor;
- ``room_with_corner``: rooms behind a wall with a door, and diagonal walls.

Grids are (H, W) int8 with row 0 at the lowest y, origin (−12.5, −12.5):
``UNKNOWN`` outside the outer wall and inside solid blocks, ``OCCUPIED``
one-cell wall rings and lines, ``FREE`` elsewhere.
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import cv2
import numpy as np

from homing.map_server import FREE, OCCUPIED, UNKNOWN, MapData, save_map

SIZE = 250  # [cells] per side
RES = 0.1  # [m/cell]
ORIGIN = (-12.5, -12.5, 0.0)  # [m, m, rad] the lower-left cell's corner


def _ring(grid: np.ndarray, r0: int, r1: int, c0: int, c1: int, inside: int = FREE) -> None:
    """A one-cell wall around rows [r0, r1) × cols [c0, c1), the inside set to ``inside``."""
    grid[r0:r1, c0:c1] = inside
    grid[r0, c0:c1] = grid[r1 - 1, c0:c1] = OCCUPIED
    grid[r0:r1, c0] = grid[r0:r1, c1 - 1] = OCCUPIED


def _line(grid: np.ndarray, a: tuple[int, int], b: tuple[int, int]) -> None:
    """A one-cell (8-connected) wall from cell ``a`` to ``b``, both (row, col)."""
    img = np.zeros(grid.shape, np.uint8)
    cv2.line(img, (a[1], a[0]), (b[1], b[0]), 1, 1, lineType=cv2.LINE_8)
    grid[img > 0] = OCCUPIED


def _outer() -> np.ndarray:
    grid = np.full((SIZE, SIZE), UNKNOWN, np.int8)
    _ring(grid, 25, 225, 25, 225)
    return grid


def loop() -> np.ndarray:
    grid = _outer()
    _ring(grid, 54, 196, 54, 196, inside=UNKNOWN)
    return grid


def room() -> np.ndarray:
    grid = _outer()
    for r, c in ((62, 62), (62, 164), (164, 62), (164, 164)):
        _ring(grid, r, r + 24, c, c + 24, inside=UNKNOWN)
    _ring(grid, 94, 156, 94, 156, inside=UNKNOWN)
    return grid


def corridor() -> np.ndarray:
    grid = np.full((SIZE, SIZE), UNKNOWN, np.int8)
    _ring(grid, 25, 100, 25, 225)  # lower room
    _ring(grid, 150, 225, 25, 225)  # upper room
    _ring(grid, 99, 151, 115, 136)  # the corridor between them, opened into both
    grid[99, 116:135] = grid[150, 116:135] = FREE
    _ring(grid, 55, 66, 124, 135, inside=UNKNOWN)  # a pillar
    return grid


def room_with_corner() -> np.ndarray:
    grid = _outer()
    grid[130, 25:225] = OCCUPIED  # a wall across …
    grid[130, 60:72] = grid[130, 180:192] = FREE  # … with two doors
    _line(grid, (45, 140), (80, 110))  # a corner wall, diagonal
    _line(grid, (80, 110), (100, 120))
    _line(grid, (160, 150), (200, 190))  # upstairs, another diagonal
    _ring(grid, 150, 175, 60, 100, inside=UNKNOWN)  # a block
    return grid


PLANS: dict[str, Callable[[], np.ndarray]] = {
    "loop": loop, "room": room, "corridor": corridor, "room_with_corner": room_with_corner,
}  # fmt: skip


def plan(name: str) -> MapData:
    """One drawn floor plan as a :class:`MapData`."""
    return MapData(PLANS[name](), RES, ORIGIN)


def write_plans(folder: Path) -> Path:
    """Write every plan as ``folder/NAME.yaml`` + ``NAME.pgm``; returns ``folder``."""
    folder.mkdir(parents=True, exist_ok=True)
    for name in PLANS:
        save_map(folder / f"{name}.yaml", plan(name))
    return folder
