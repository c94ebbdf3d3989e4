"""The live view's small map: the occupancy grid in braille, with the robot, its path, its goal and the frontiers.

Each character is a 2 × 4 braille block of "dots", each dot a k × k block
of grid cells (k chosen so the known part of the map fits the panel):

- a dot is lit where its cells hold a wall (white), a frontier cell
  (magenta) or the planned path (cyan), in that order of priority within a
  character (a character has one colour);
- a character's background is dark grey where any of its cells is free
  (the floor), black where all are unknown;
- the goal is ``◎`` (green), the robot an arrow along its heading (bold
  red), drawn over everything.

Frames: the grid, pose, path and goal are all in ``map``; row 0 of the grid
is the lowest y, so it is drawn at the bottom.

Cost: the downsampled grid is cached on the grid's ``version`` (grid SLAM
publishes a new snapshot about once a second of adapter time), and the
frontiers — the thesis's smoothed segments, :func:`homing.mapping.frontier.smoothed_frontiers`,
a few milliseconds on a 500 × 500 grid — are recomputed at most once per
``FRONTIER_PERIOD`` of real time, so a redraw costs about a millisecond.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np
from rich.style import Style
from rich.text import Text

from homing.map_server import FREE, UNKNOWN

FRONTIER_PERIOD = 1.0  # [s] real time between frontier computations, at most
OCCUPIED_AT = 65  # map_server values ≥ this are walls
# Braille dot bits of a 2-wide × 4-high block, indexed [row from the top][column] (Unicode's dot numbering).
BRAILLE_BITS = np.array([[0x01, 0x08], [0x02, 0x10], [0x04, 0x20], [0x40, 0x80]], dtype=np.int32)
ARROWS = "→↗↑↖←↙↓↘"  # heading 0, 45°, 90°, … counter-clockwise
WALL, FRONTIER, PATH = "white", "magenta", "cyan"
FLOOR_BG, GOAL, ROBOT = "grey19", "bold green", "bold red"
# Style of a character by 2 × layer (0 none, 1 wall, 2 frontier, 3 path, 4 goal, 5 robot) + (on the floor).
_STYLES = [Style.parse(fg) + Style(bgcolor=bg) if bg else Style.parse(fg)
           for fg in ("none", WALL, FRONTIER, PATH, GOAL, ROBOT) for bg in (None, FLOOR_BG)]


@dataclass
class _Layout:
    """Which grid cells the panel shows: k cells per dot, the (row, col) of the panel's lower-left dot."""

    k: int
    row0: int
    col0: int
    rows: int  # dots high
    cols: int  # dots wide


def block_any(mask: np.ndarray, k: int, rows: int, cols: int) -> np.ndarray:
    """(rows, cols) bool: any True in each k × k block of ``mask`` (cut or padded to rows·k × cols·k)."""
    out = np.zeros((rows * k, cols * k), dtype=bool)
    h, w = min(mask.shape[0], rows * k), min(mask.shape[1], cols * k)
    out[:h, :w] = mask[:h, :w]
    return np.asarray(out.reshape(rows, k, cols, k).any(axis=(1, 3)), dtype=bool)


def braille(dots: np.ndarray) -> np.ndarray:
    """(R, C) int code points of the braille characters showing the (4R, 2C) bool ``dots`` (row 0 at the top)."""
    r, c = dots.shape[0] // 4, dots.shape[1] // 2
    blocks = dots[: 4 * r, : 2 * c].reshape(r, 4, c, 2)
    return 0x2800 + np.einsum("iajb,ab->ij", blocks.astype(np.int32), BRAILLE_BITS)


class MiniMap:
    """Renders ``/map/grid`` with the robot, path, goal and frontiers into ``width`` × ``height`` characters.

    ``frontiers(grid_data, resolution) -> list of (N, 2) cell arrays``
    defaults to the smoothed frontier segments; ``clock`` is the real-time
    clock the frontier throttle uses (tests pass their own).
    """

    def __init__(self, frontiers: Callable[[np.ndarray, float], list[np.ndarray]] | None = None,
                 clock: Callable[[], float] = time.monotonic):
        self.frontier_fn = frontiers or _smoothed
        self.clock = clock
        self._frontier_version: int | None = None
        self._frontier_at = -math.inf
        self._frontier_cells: np.ndarray = np.zeros((0, 2), np.int64)
        self.frontier_count = 0
        self.frontier_runs = 0  # how many times the frontiers were computed (the view's cost)
        self._cache_key: tuple[Any, ...] | None = None
        self._cache: tuple[_Layout, np.ndarray, np.ndarray] | None = None

    # -- what to draw ------------------------------------------------------------------------------
    def frontiers(self, grid: Any) -> np.ndarray:
        """(N, 2) frontier cells of ``grid``: recomputed when its version changed and FRONTIER_PERIOD has passed."""
        now = self.clock()
        if grid.version != self._frontier_version and now - self._frontier_at >= FRONTIER_PERIOD:
            segments = self.frontier_fn(grid.data, grid.resolution)
            self._frontier_cells = np.concatenate(segments) if segments else np.zeros((0, 2), np.int64)
            self.frontier_count = len(segments)
            self._frontier_version, self._frontier_at = grid.version, now
            self.frontier_runs += 1
        return self._frontier_cells

    def _layout(self, data: np.ndarray, rows: int, cols: int, pose: Any, cell_of: Callable[..., Any]) -> _Layout:
        known = data != UNKNOWN
        r_any, c_any = np.flatnonzero(known.any(axis=1)), np.flatnonzero(known.any(axis=0))
        if r_any.size == 0:
            r_lo = r_hi = c_lo = c_hi = 0
        else:
            r_lo, r_hi, c_lo, c_hi = int(r_any[0]), int(r_any[-1]), int(c_any[0]), int(c_any[-1])
        if pose is not None:  # the robot is always in view
            pr, pc = (int(v) for v in cell_of(pose.x, pose.y))
            r_lo, r_hi, c_lo, c_hi = min(r_lo, pr), max(r_hi, pr), min(c_lo, pc), max(c_hi, pc)
        k = max(1, math.ceil(max((r_hi - r_lo + 1) / rows, (c_hi - c_lo + 1) / cols)))
        # centre the known box in the panel
        row0 = (r_lo + r_hi + 1) // 2 - rows * k // 2
        col0 = (c_lo + c_hi + 1) // 2 - cols * k // 2
        return _Layout(k, row0, col0, rows, cols)

    def _base(self, grid: Any, rows: int, cols: int, pose: Any) -> tuple[_Layout, np.ndarray, np.ndarray]:
        """Layout, wall dots and floor dots (row 0 at the bottom), cached on the grid's version and the panel."""
        key = (id(grid), grid.version, rows, cols)
        if key == self._cache_key and self._cache is not None:
            layout = self._cache[0]
            if pose is None or self._dot(layout, grid, pose.x, pose.y) is not None:
                return self._cache
        data = grid.data
        layout = self._layout(data, rows, cols, pose, grid.world_to_cell)
        window = _window(data, layout)
        walls = block_any(window >= OCCUPIED_AT, layout.k, rows, cols)
        floor = block_any(window == FREE, layout.k, rows, cols)
        self._cache_key, self._cache = key, (layout, walls, floor)
        return self._cache

    @staticmethod
    def _dot(layout: _Layout, grid: Any, x: float, y: float) -> tuple[int, int] | None:
        r, c = grid.world_to_cell(x, y)
        dr, dc = (int(r) - layout.row0) // layout.k, (int(c) - layout.col0) // layout.k
        if 0 <= dr < layout.rows and 0 <= dc < layout.cols:
            return dr, dc
        return None

    # -- drawing -----------------------------------------------------------------------------------
    def render(self, grid: Any, width: int, height: int, pose: Any = None, path: np.ndarray | None = None,
               goal: Any = None) -> list[Text]:
        """``height`` lines of ``width`` characters (an empty panel without a grid)."""
        if grid is None or width < 4 or height < 2:
            return [Text(" " * width) for _ in range(height)]
        rows, cols = 4 * height, 2 * width
        layout, walls, floor = self._base(grid, rows, cols, pose)
        front = np.zeros_like(walls)
        cells = self.frontiers(grid)
        if len(cells):
            _mark(front, layout, cells[:, 0], cells[:, 1])
        trail = np.zeros_like(walls)
        if path is not None and len(path):
            pts = _densify(np.asarray(path, float), grid.resolution * layout.k / 2)
            r, c = grid.world_to_cell(pts[:, 0], pts[:, 1])
            _mark(trail, layout, np.asarray(r), np.asarray(c))
        # Characters, top line first: flip the dot rows (row 0 is the lowest y).
        code = braille(walls[::-1] | front[::-1] | trail[::-1])
        layer = np.zeros((height, width), np.int8)  # the topmost layer with a dot colours the character
        for i, mask in ((1, walls), (2, front), (3, trail)):
            layer[braille(mask[::-1]) != 0x2800] = i
        bg = np.asarray(floor[::-1].reshape(height, 4, width, 2).any(axis=(1, 3)), dtype=bool)
        chars = np.where(layer > 0, code, ord(" ")).astype(np.int32)
        for at, char, style in ((goal, "◎", 4), (pose, None, 5)):
            cell = self._dot(layout, grid, at.x, at.y) if at is not None else None
            if cell is not None:
                i, j = height - 1 - cell[0] // 4, cell[1] // 2
                chars[i, j] = ord(char if char else ARROWS[int(round(at.theta / (math.pi / 4))) % 8])
                layer[i, j] = style
        lines = []
        for i in range(height):
            line = Text(no_wrap=True, overflow="crop")
            keys = layer[i].astype(np.int32) * 2 + bg[i]
            start = 0
            for j in range(1, width + 1):  # one span per run of characters of the same style
                if j == width or keys[j] != keys[start]:
                    line.append("".join(map(chr, chars[i, start:j])), _STYLES[int(keys[start])])
                    start = j
            lines.append(line)
        return lines

    def scale(self) -> float | None:
        """Cells per dot of the last drawing (None before the first)."""
        return None if self._cache is None else float(self._cache[0].k)


def _window(data: np.ndarray, layout: _Layout) -> np.ndarray:
    """The cells under the panel (UNKNOWN where the panel reaches past the grid)."""
    h, w = layout.rows * layout.k, layout.cols * layout.k
    out = np.full((h, w), UNKNOWN, dtype=data.dtype)
    r0, c0 = max(layout.row0, 0), max(layout.col0, 0)
    r1, c1 = min(layout.row0 + h, data.shape[0]), min(layout.col0 + w, data.shape[1])
    if r1 > r0 and c1 > c0:
        out[r0 - layout.row0 : r1 - layout.row0, c0 - layout.col0 : c1 - layout.col0] = data[r0:r1, c0:c1]
    return out


def _mark(dots: np.ndarray, layout: _Layout, rows: np.ndarray, cols: np.ndarray) -> None:
    dr, dc = (rows - layout.row0) // layout.k, (cols - layout.col0) // layout.k
    ok = (dr >= 0) & (dr < layout.rows) & (dc >= 0) & (dc < layout.cols)
    dots[dr[ok], dc[ok]] = True


def _densify(path: np.ndarray, step: float) -> np.ndarray:
    """(M, 2) points along the (N, 2) polyline no farther apart than ``step`` [m] (so it draws unbroken)."""
    if len(path) < 2:
        return path.reshape(-1, 2)
    seg = np.diff(path, axis=0)
    n = np.maximum(1, np.ceil(np.hypot(seg[:, 0], seg[:, 1]) / max(step, 1e-6)).astype(int))
    parts = [path[i] + seg[i] * (np.arange(n[i])[:, None] / n[i]) for i in range(len(seg))]
    return np.vstack([*parts, path[-1:]])


def _smoothed(data: np.ndarray, resolution: float) -> list[np.ndarray]:
    from homing.mapping.frontier import smoothed_frontiers

    return [s.cells for s in smoothed_frontiers(data, resolution)]
