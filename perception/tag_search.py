"""Where to look for tags not yet seen: view poses facing the mapped walls, one camera footprint apart.

Tags hang on walls and are read only within ``max_range`` of the camera
(:class:`homing.perception.apriltag.TagFilter`), while the lidar maps a
corridor from tens of metres away: frontier exploration of a lidar-sized
world ends with most walls never seen by the camera. A wall-following
camera coverage (the "search" view points of active landmark SLAM, e.g.
Chen et al., "Active SLAM", T-RO 2022 survey, sec. IV) closes that gap:
free cells ``distance`` [m] from the nearest wall (a distance transform of
the grid), spaced ``spacing`` [m] apart along the walls, each facing the
wall (the distance field's descent). Not for: finding the tags themselves
(the detector does that) or planning the drive (navigation does).
"""

from __future__ import annotations

import math
from collections.abc import Iterable

import numpy as np
from homing.robot.types import Pose2
from scipy import ndimage

FREE, OCCUPIED = 0, 100  # map_server cell values (homing.mapping.grid)
VIEW_DISTANCE = 1.2  # [m] wall to view pose (tags read well at 1–1.5 m)
VIEW_TOLERANCE = 0.15  # [m] accepted band around VIEW_DISTANCE
VIEW_SPACING = 2.0  # [m] between view poses along a wall (the camera sees ≈ ±1 m of wall at 1.2 m)
CLEARANCE = 0.35  # [m] a view pose keeps this far from anything not free (unknown included)


def wall_views(data: np.ndarray, resolution: float, origin: tuple[float, float],
               distance: float = VIEW_DISTANCE, spacing: float = VIEW_SPACING) -> list[Pose2]:
    """View poses [m, rad, map] facing the walls of a map_server grid ``data`` (H, W; FREE 0, OCCUPIED 100, −1).

    Greedy thinning (row-major order, deterministic) keeps candidates at
    least ``spacing`` apart. A pose's heading points down the wall-distance
    gradient, at the nearest wall.
    """
    occupied = data >= OCCUPIED // 2
    if not occupied.any():
        return []
    d_wall = ndimage.distance_transform_edt(~occupied) * resolution
    d_other = ndimage.distance_transform_edt(data == FREE) * resolution  # to anything not free
    band = (data == FREE) & (np.abs(d_wall - distance) <= VIEW_TOLERANCE) & (d_other >= CLEARANCE)
    rows, cols = np.nonzero(band)
    if rows.size == 0:
        return []
    gy, gx = np.gradient(d_wall)
    # Greedy in row-major order: the first candidate left is kept and every candidate closer than ``spacing`` to
    # it goes (only rows within ``spacing`` can hold one); what is left after it was never near a kept pose.
    xs, ys = origin[0] + (cols + 0.5) * resolution, origin[1] + (rows + 0.5) * resolution
    left = np.ones(rows.size, bool)
    reach = int(math.ceil(spacing / resolution)) + 1
    min_sq = spacing * spacing
    kept: list[tuple[float, float, float]] = []
    i = 0
    while i < rows.size:
        r, c = int(rows[i]), int(cols[i])
        x, y = float(xs[i]), float(ys[i])
        kept.append((x, y, math.atan2(-gy[r, c], -gx[r, c])))
        lo, hi = np.searchsorted(rows, r - reach), np.searchsorted(rows, r + reach, side="right")
        near = (xs[lo:hi] - x) ** 2 + (ys[lo:hi] - y) ** 2 < min_sq
        left[lo:hi] &= ~near
        rest = np.flatnonzero(left[i + 1 :])
        i = i + 1 + int(rest[0]) if rest.size else rows.size
    return [Pose2(x, y, th) for x, y, th in kept]


def next_view(views: Iterable[Pose2], here: Pose2, visited: Iterable[Pose2], covered: float = VIEW_SPACING / 2) -> Pose2 | None:
    """The view nearest to ``here`` (straight-line [m]) farther than ``covered`` [m] from every visited one; None if none."""
    done = list(visited)
    todo = [v for v in views if all(v.distance_to(p) > covered for p in done)]
    return min(todo, key=here.distance_to) if todo else None
