"""Exact geometry for the navigation tests: rectangle worlds, their rasterisation, the true shortest path, a lidar.

Independent of homing.navigation: the shortest path comes from a visibility
graph over the walls dilated by the robot's radius (exact segment–rectangle
distances), and scans from exact ray–rectangle intersection.
"""

from __future__ import annotations

import math

import numpy as np
from homing.robot import Scan
from homing.robot.types import Pose2
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import dijkstra

# A 10 m × 10 m maze of axis-aligned walls (x0, y0, x1, y1) [m].
MAZE = np.array([
    (0.0, 0.0, 10.0, 0.1), (0.0, 9.9, 10.0, 10.0), (0.0, 0.0, 0.1, 10.0), (9.9, 0.0, 10.0, 10.0),
    (2.0, 0.0, 2.1, 7.0),
    (4.0, 3.0, 4.1, 10.0),
    (6.0, 0.0, 6.1, 6.0),
    (6.1, 7.5, 8.5, 7.6),
    (8.0, 2.0, 10.0, 2.1),
])
MAZE_START = (1.0, 1.0)
MAZE_GOAL = (9.0, 1.0)


def rasterise(rects: np.ndarray, size: tuple[float, float], res: float) -> np.ndarray:
    """(H, W) int8 grid (row 0 = lowest y, origin (0, 0)): 100 where a cell overlaps a rectangle, else 0."""
    h, w = int(round(size[1] / res)), int(round(size[0] / res))
    g = np.zeros((h, w), dtype=np.int8)
    for x0, y0, x1, y1 in rects:
        c0, c1 = int(math.floor(x0 / res + 1e-9)), int(math.ceil(x1 / res - 1e-9))
        r0, r1 = int(math.floor(y0 / res + 1e-9)), int(math.ceil(y1 / res - 1e-9))
        g[max(r0, 0) : min(r1, h), max(c0, 0) : min(c1, w)] = 100
    return g


def point_rect_distance(p: np.ndarray, rects: np.ndarray) -> np.ndarray:
    """(N, R) distances [m] from (N, 2) points to R rectangles (0 inside)."""
    p = np.asarray(p, dtype=float).reshape(-1, 2)
    dx = np.maximum(np.maximum(rects[None, :, 0] - p[:, None, 0], 0), p[:, None, 0] - rects[None, :, 2])
    dy = np.maximum(np.maximum(rects[None, :, 1] - p[:, None, 1], 0), p[:, None, 1] - rects[None, :, 3])
    return np.hypot(dx, dy)


def _point_segment_distance(q: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """(S, C) distances from C points q (C, 2) to S segments a→b (S, 2)."""
    ab = b - a
    L2 = np.maximum((ab * ab).sum(1), 1e-18)
    t = np.clip(((q[None, :, :] - a[:, None, :]) * ab[:, None, :]).sum(2) / L2[:, None], 0, 1)
    foot = a[:, None, :] + t[..., None] * ab[:, None, :]
    return np.hypot(*(q[None, :, :] - foot).transpose(2, 0, 1))


def segment_rect_distance(a: np.ndarray, b: np.ndarray, rect: np.ndarray) -> np.ndarray:
    """(S,) exact distances [m] from S segments a→b to one rectangle (0 if they cross it)."""
    x0, y0, x1, y1 = rect
    # Liang–Barsky: does the segment meet the rectangle?
    d = b - a
    t0, t1 = np.zeros(len(a)), np.ones(len(a))
    for p, q in ((-d[:, 0], a[:, 0] - x0), (d[:, 0], x1 - a[:, 0]), (-d[:, 1], a[:, 1] - y0), (d[:, 1], y1 - a[:, 1])):
        par = np.abs(p) < 1e-15
        with np.errstate(divide="ignore", invalid="ignore"):
            r = q / p
        t0 = np.where(~par & (p < 0), np.maximum(t0, r), t0)
        t1 = np.where(~par & (p > 0), np.minimum(t1, r), t1)
        t1 = np.where(par & (q < 0), -1.0, t1)
    meets = t0 <= t1
    corners = np.array([(x0, y0), (x1, y0), (x1, y1), (x0, y1)])
    dist = np.minimum(point_rect_distance(a, rect[None])[:, 0], point_rect_distance(b, rect[None])[:, 0])
    dist = np.minimum(dist, _point_segment_distance(corners, a, b).min(axis=1))
    return np.where(meets, 0.0, dist)


def shortest_path_length(rects: np.ndarray, start: tuple[float, float], goal: tuple[float, float],
                         radius: float, per_quadrant: int = 8) -> tuple[float, float]:
    """Length [m] of the shortest path keeping ``radius`` from every rectangle, bracketed (lower, upper).

    Visibility graph over the vertices of polygons circumscribing each
    corner's radius-``radius`` arc (``per_quadrant`` per 90°): its shortest
    path is feasible (upper bound), and the true optimum is at most the
    circumscription factor shorter (lower bound).
    """
    dphi = 0.5 * math.pi / per_quadrant
    R = radius / math.cos(0.5 * dphi) + 1e-9
    verts = [np.array(start), np.array(goal)]
    for x0, y0, x1, y1 in rects:
        for (cx, cy), base in (((x1, y1), 0.0), ((x0, y1), 0.5 * math.pi), ((x0, y0), math.pi), ((x1, y0), 1.5 * math.pi)):
            for k in range(per_quadrant):
                phi = base + (k + 0.5) * dphi
                verts.append(np.array([cx + R * math.cos(phi), cy + R * math.sin(phi)]))
    V = np.array(verts)
    keep = point_rect_distance(V, rects).min(axis=1) >= radius - 1e-9
    keep[:2] = True
    V = V[keep]
    i, j = np.triu_indices(len(V), 1)
    ok = np.ones(len(i), bool)
    for rect in rects:
        ok &= segment_rect_distance(V[i], V[j], rect) >= radius - 1e-9
    w = np.hypot(*(V[i[ok]] - V[j[ok]]).T)
    g = coo_matrix((w, (i[ok], j[ok])), shape=(len(V), len(V))).tocsr()
    d = dijkstra(g, directed=False, indices=0)[1]
    return float(d * math.cos(0.5 * dphi)), float(d)


def polyline_clearance(path: np.ndarray, rects: np.ndarray, step: float = 0.01) -> float:
    """Smallest distance [m] from an (N, 2) polyline (sampled every ``step``) to the rectangles."""
    pts = [path[:1]]
    for a, b in zip(path[:-1], path[1:], strict=True):
        n = max(1, int(math.ceil(np.hypot(*(b - a)) / step)))
        pts.append(a + np.linspace(0, 1, n + 1)[1:, None] * (b - a))
    return float(point_rect_distance(np.concatenate(pts), rects).min())


def ray_rects(origin: np.ndarray, angles: np.ndarray, rects: np.ndarray, max_range: float) -> np.ndarray:
    """(N,) exact ranges [m] from ``origin`` along ``angles`` [rad] to the first rectangle; inf beyond ``max_range``."""
    d = np.column_stack([np.cos(angles), np.sin(angles)])
    best = np.full(len(angles), np.inf)
    with np.errstate(divide="ignore", invalid="ignore"):
        for x0, y0, x1, y1 in rects:
            tx0, tx1 = (x0 - origin[0]) / d[:, 0], (x1 - origin[0]) / d[:, 0]
            ty0, ty1 = (y0 - origin[1]) / d[:, 1], (y1 - origin[1]) / d[:, 1]
            tmin = np.maximum(np.minimum(tx0, tx1), np.minimum(ty0, ty1))
            tmax = np.minimum(np.maximum(tx0, tx1), np.maximum(ty0, ty1))
            hit = (tmax >= np.maximum(tmin, 0)) & np.isfinite(tmin)
            t = np.where(tmin > 0, tmin, 0.0)
            best = np.where(hit & (t < best), t, best)
    best[best > max_range] = np.inf
    return best


def scan_of(pose: Pose2, rects: np.ndarray, stamp: float = 0.0, rays: int = 360, max_range: float = 6.0) -> Scan:
    """An exact 360-ray scan from ``pose`` (laser at base_link) among the rectangles."""
    inc = 2 * math.pi / rays
    ang = -math.pi + inc * np.arange(rays)
    r = ray_rects(np.array([pose.x, pose.y]), ang + pose.theta, rects, max_range)
    r[r < 0.15] = np.inf
    return Scan(stamp, -math.pi, inc, r.astype(np.float32), 0.15, max_range)


def unicycle(pose: Pose2, v: float, omega: float, dt: float) -> Pose2:
    """Exact unicycle motion over ``dt`` [s]."""
    if abs(omega) < 1e-9:
        return Pose2(pose.x + v * dt * math.cos(pose.theta), pose.y + v * dt * math.sin(pose.theta), pose.theta)
    R = v / omega
    th = pose.theta + omega * dt
    return Pose2(pose.x + R * (math.sin(th) - math.sin(pose.theta)),
                 pose.y - R * (math.cos(th) - math.cos(pose.theta)), math.atan2(math.sin(th), math.cos(th)))
