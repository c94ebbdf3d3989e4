"""Walls extruded from a map_server grid as one static triangle mesh (boundary faces only).

DESIGN.md (pybullet lessons): merging occupied cells into boxes gives ~500
bodies for a floor plan with diagonal walls and makes every step and scan
3–15× slower, so the walls here are *one* static concave triangle mesh. Only
the vertical faces between a free cell and a solid cell are built, and
collinear neighbouring faces are merged into one quad, so a 25 m × 25 m plan
becomes a few hundred to a few thousand triangles whatever the walls' shape.
Tops are not built: the lidar and camera sit far below them.

What counts as solid: every cell that is not FREE (occupied *and* unknown;
in a floor plan, unknown is the outside of the building), and everything
beyond the image's border, so a robot can never leave the map.

Frames: grid row 0 is the lowest y (``homing.map_server``); the map's origin
(x, y, yaw) places cell (0, 0)'s lower-left corner in the world. Faces are
wound counter-clockwise seen from the free side (the tiny renderer culls back
faces), so normals point into the room.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from homing.map_server import FREE, MapData

WALL_HEIGHT = 1.2  # [m] taller than the lidar (0.5 m): rays at a wall's exact top height miss it
MAX_MESH_VERTICES = 131072  # Bullet's limit for one mesh shape (B3_MAX_NUM_VERTICES): larger ones fail to load
PIECE_TILE = 10.0  # [m] a mesh too large for one shape is cut into pieces of whole tiles this size, row by row


@dataclass(frozen=True)
class WallMesh:
    """Triangle mesh of the walls in the world frame.

    ``vertices`` (V, 3) float64 [m], ``indices`` (T·3,) int32, ``normals``
    (V, 3) unit vectors pointing into free space, ``n_quads`` faces merged.
    """

    vertices: np.ndarray
    indices: np.ndarray
    normals: np.ndarray
    n_quads: int

    def pieces(self, max_vertices: int = MAX_MESH_VERTICES) -> list[WallMesh]:
        """The mesh cut into meshes of at most ``max_vertices`` each, every quad whole in one of them.

        A floor plan's walls fit one shape. A real building's SLAM map does not
        (ACES' corrected log, mapped at 5 cm: 181 000 vertices; Edmonton's
        over a million, its rays' streaks into unknown each a corridor of faces),
        and Bullet refuses a mesh shape over ``MAX_MESH_VERTICES``. The quads
        are ordered by the ``PIECE_TILE`` tile their first corner lies in, row
        of tiles by row, so each piece is a compact band of the building and
        a ray meets few pieces' bounding boxes.
        """
        per = max(1, max_vertices // 4)  # four corners a quad
        if self.n_quads <= per:
            return [self]
        corner = self.vertices[0::4, :2]
        tile = np.floor((corner - corner.min(axis=0)) / PIECE_TILE).astype(np.int64)
        order = np.lexsort((tile[:, 0], tile[:, 1]))  # by tile row, then tile column
        out = []
        for start in range(0, self.n_quads, per):
            quads = order[start:start + per]
            v = (quads[:, None] * 4 + np.arange(4)).reshape(-1)
            n = len(quads)
            idx = (np.arange(n)[:, None] * 4 + np.array([0, 2, 1, 0, 3, 2])).reshape(-1).astype(np.int32)
            out.append(WallMesh(self.vertices[v], idx, self.normals[v], n))
        return out


def solid_mask(data: MapData) -> np.ndarray:
    """(H, W) bool: cells the simulator treats as solid (everything not FREE)."""
    return np.asarray(data.grid) != FREE


def cell_to_world(data: MapData, rows: np.ndarray, cols: np.ndarray) -> np.ndarray:
    """(N, 2) world [m] of cell centres (row 0 = lowest y), honouring the origin's yaw."""
    u = (np.asarray(cols, dtype=float) + 0.5) * data.resolution
    v = (np.asarray(rows, dtype=float) + 0.5) * data.resolution
    return _local_to_world(data, np.column_stack([u, v]))


def world_to_cell(data: MapData, xy: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(rows, cols) int arrays of the cells holding world points ``xy`` (N, 2) [m]; may be out of range."""
    ox, oy, oyaw = data.origin
    p = np.asarray(xy, dtype=float).reshape(-1, 2) - np.array([ox, oy])
    c, s = math.cos(oyaw), math.sin(oyaw)
    u = c * p[:, 0] + s * p[:, 1]
    v = -s * p[:, 0] + c * p[:, 1]
    return (np.floor(v / data.resolution).astype(int), np.floor(u / data.resolution).astype(int))


def _local_to_world(data: MapData, uv: np.ndarray) -> np.ndarray:
    ox, oy, oyaw = data.origin
    c, s = math.cos(oyaw), math.sin(oyaw)
    uv = np.asarray(uv, dtype=float).reshape(-1, 2)
    return np.column_stack([ox + c * uv[:, 0] - s * uv[:, 1], oy + s * uv[:, 0] + c * uv[:, 1]])


def _runs(mask: np.ndarray) -> list[tuple[int, int, int]]:
    """Runs of True along axis 1 of a 2-D bool array: (line, start, stop) with stop exclusive."""
    out: list[tuple[int, int, int]] = []
    padded = np.zeros((mask.shape[0], mask.shape[1] + 2), dtype=np.int8)
    padded[:, 1:-1] = mask
    d = np.diff(padded, axis=1)
    for line in np.nonzero(np.any(mask, axis=1))[0]:
        starts = np.nonzero(d[line] == 1)[0]
        stops = np.nonzero(d[line] == -1)[0]
        out.extend((int(line), int(a), int(b)) for a, b in zip(starts, stops, strict=True))
    return out


def build_mesh(data: MapData, height: float = WALL_HEIGHT) -> WallMesh:
    """Boundary faces between free and solid cells, merged along straight runs."""
    solid = np.pad(solid_mask(data), 1, constant_values=True)  # beyond the border is solid
    res = data.resolution
    quads: list[tuple[tuple[float, float], tuple[float, float]]] = []  # (a, b): free side on the left of a→b
    # Faces at x = const between padded columns j and j+1 (grid column j−1 | j).
    left_solid = solid[:, :-1] & ~solid[:, 1:]  # solid on −x side, free on +x: face looks +x
    right_solid = ~solid[:, :-1] & solid[:, 1:]  # free on −x side: face looks −x
    for col, r0, r1 in _runs(left_solid.T):
        x = col * res  # edge between padded columns col, col+1 = grid edge index col
        quads.append(((x, (r1 - 1) * res), (x, (r0 - 1) * res)))
    for col, r0, r1 in _runs(right_solid.T):
        x = col * res
        quads.append(((x, (r0 - 1) * res), (x, (r1 - 1) * res)))
    # Faces at y = const between padded rows i and i+1.
    below_solid = solid[:-1, :] & ~solid[1:, :]  # face looks +y
    above_solid = ~solid[:-1, :] & solid[1:, :]  # face looks −y
    for row, c0, c1 in _runs(below_solid):
        y = row * res
        quads.append((((c0 - 1) * res, y), ((c1 - 1) * res, y)))
    for row, c0, c1 in _runs(above_solid):
        y = row * res
        quads.append((((c1 - 1) * res, y), ((c0 - 1) * res, y)))
    # The edge between padded lines k and k+1 is the grid edge at k·res; padded cell k spans
    # grid cell k−1, hence the −1 on the run axis above.
    if not quads:
        return WallMesh(np.zeros((0, 3)), np.zeros(0, np.int32), np.zeros((0, 3)), 0)
    ends = np.asarray(quads, dtype=float)  # (Q, 2 ends, 2)
    a = _local_to_world(data, ends[:, 0])
    b = _local_to_world(data, ends[:, 1])
    d = b - a
    n = np.stack([-d[:, 1], d[:, 0]], axis=1) / np.maximum(np.hypot(d[:, 0], d[:, 1]), 1e-12)[:, None]
    q = len(quads)
    # Four corners a quad: a, b on the floor, b, a at the top; the free side is left of a→b.
    xy = np.stack([a, b, b, a], axis=1)  # (Q, 4, 2)
    z = np.broadcast_to(np.array([0.0, 0.0, height, height]), (q, 4))
    verts = np.concatenate([xy, z[:, :, None]], axis=2).reshape(-1, 3)
    norms = np.concatenate([np.repeat(n[:, None, :], 4, axis=1), np.zeros((q, 4, 1))], axis=2).reshape(-1, 3)
    # (a, b, b_top) has normal (b−a)×up, to the right of a→b: reverse it to face the free side.
    idx = (np.arange(q)[:, None] * 4 + np.array([0, 2, 1, 0, 3, 2])).reshape(-1).astype(np.int32)
    return WallMesh(
        verts,
        idx,
        norms,
        len(quads),
    )
