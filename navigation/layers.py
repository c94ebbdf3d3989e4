"""Obstacles the lidar cannot see: keep-out zones and bumper marks (Nav2's keepout filter, kobuki's bumper2pc).

The lidar sits at 0.5 m; the dock (0.12 m tall) and any low obstacle are
below its plane, so the scan never marks them. Two layers fill that gap in
:class:`homing.navigation.costmap.Costmap`:

- **keep-out zones** (Nav2's ``KeepoutFilter``, here given as shapes rather
  than a mask image): static discs and polygons in the ``map`` frame that no
  path may cross — e.g. the dock, whose pose the mission knows because the
  robot started on it (:func:`dock_keepout`). They are never cleared.
- **bumper marks** (kobuki's ``kobuki_bumper2pc``, which publishes a point
  per pressed bumper at 0.25 m from the centre for the obstacle layer): here
  every pressed sector marks its whole arc on the bumper's rim, because the
  contact may lie anywhere on it; marks live ``BUMP_MEMORY`` seconds and a
  clear-costmap recovery drops them. The lidar's clearing rays do not touch
  them (they cannot see what was bumped).

Both give :meth:`boundary_points` for the local controllers, which check
points, not cells: a keep-out zone's edge sampled every ``EDGE_STEP``.
Do not use keep-out zones for things the lidar sees (walls): the scan keeps
those up to date.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from typing import Any

import cv2
import numpy as np
from homing.robot import Bumpers, Pose2
from homing.robot.turtlebot import (
    BASE_RADIUS,
    BUMPER_CENTRE_HALF,
    BUMPER_SIDE_LIMIT,
    DOCK_DEPTH,
    DOCK_WIDTH,
)

BUMP_MEMORY = 60.0  # [s] a bumper mark is forgotten after this (Nav2 would keep it until cleared)
BUMP_ARC_STEP = math.radians(5.0)  # [rad] sampling of a pressed sector's arc
BUMP_RIM = BASE_RADIUS + 0.01  # [m] marks sit just beyond the bumper's rim, where the obstacle is
MAX_BUMP_MARKS = 2000  # the oldest marks go first beyond this
EDGE_STEP = 0.02  # [m] sampling of a keep-out zone's edge for the controllers
DOCK_MARGIN = 0.03  # [m] the zone is grown by this for the pose's uncertainty

# Bumper sectors [rad] in base_link as (first, last) angle, kobuki's convention (robot/turtlebot.py).
SECTORS = {
    "left": (BUMPER_CENTRE_HALF, BUMPER_SIDE_LIMIT),
    "centre": (-BUMPER_CENTRE_HALF, BUMPER_CENTRE_HALF),
    "right": (-BUMPER_SIDE_LIMIT, -BUMPER_CENTRE_HALF),
}


@dataclass(frozen=True)
class Keepout:
    """A zone no path may enter, in ``map``: a disc (``radius`` > 0, ``points`` its (1, 2) centre) or a polygon.

    ``points`` is (N, 2) [m]; a polygon needs N ≥ 3 vertices in order (either way round).
    """

    points: np.ndarray
    radius: float = 0.0  # [m]

    def __post_init__(self) -> None:
        pts = np.asarray(self.points, dtype=float).reshape(-1, 2)
        object.__setattr__(self, "points", pts)
        if self.radius > 0.0 and len(pts) != 1:
            raise ValueError("a keep-out disc has one centre")
        if self.radius <= 0.0 and len(pts) < 3:
            raise ValueError("a keep-out polygon needs at least 3 vertices")
        # The edge by step, worked out once: the controllers ask for it every tick (a zone never changes).
        object.__setattr__(self, "_edges", {})

    @classmethod
    def disc(cls, x: float, y: float, radius: float) -> Keepout:
        """A disc of ``radius`` [m] centred at (x, y) [m]."""
        if radius <= 0.0:
            raise ValueError("a keep-out disc needs a positive radius")
        return cls(np.array([[x, y]]), float(radius))

    def edge(self, step: float = EDGE_STEP) -> np.ndarray:
        """(M, 2) [m] points along the zone's boundary, at most ``step`` apart (read-only: kept for the next call)."""
        edges: dict[float, np.ndarray] = self._edges  # type: ignore[attr-defined]
        if step not in edges:
            edges[step] = self._edge(step)
            edges[step].flags.writeable = False
        return edges[step]

    def _edge(self, step: float) -> np.ndarray:
        if self.radius > 0.0:
            n = max(8, int(math.ceil(2 * math.pi * self.radius / step)))
            a = np.linspace(0.0, 2 * math.pi, n, endpoint=False)
            return self.points[0] + self.radius * np.column_stack([np.cos(a), np.sin(a)])
        closed = np.vstack([self.points, self.points[:1]])
        out = []
        for a, b in zip(closed[:-1], closed[1:], strict=True):
            k = max(1, int(math.ceil(float(np.hypot(*(b - a))) / step)))
            out.append(a + np.linspace(0.0, 1.0, k, endpoint=False)[:, None] * (b - a))
        return np.vstack(out)

    def contains(self, xy: np.ndarray) -> np.ndarray:
        """(N,) bool: which (N, 2) map points [m] lie inside the zone (on the edge counts)."""
        p = np.asarray(xy, dtype=float).reshape(-1, 2)
        if self.radius > 0.0:
            return np.hypot(*(p - self.points[0]).T) <= self.radius + 1e-9
        contour = self.points.astype(np.float32).reshape(-1, 1, 2)
        return np.array([cv2.pointPolygonTest(contour, (float(x), float(y)), False) >= 0 for x, y in p], dtype=bool)


def parse_keepout(spec: Any) -> list[Keepout]:
    """Keep-out zones from a mission's spelling: a list of ``[x, y, r]`` discs and ``[[x, y], …]`` polygons.

    Also accepts :class:`Keepout` objects as they are, and None (no zones).
    Raises ``ValueError`` naming the bad entry.
    """
    if spec is None:
        return []
    if isinstance(spec, Keepout):
        return [spec]
    out: list[Keepout] = []
    for i, item in enumerate(spec):
        if isinstance(item, Keepout):
            out.append(item)
            continue
        try:
            arr = np.asarray(item, dtype=float)
        except (TypeError, ValueError) as err:
            raise ValueError(f"keepout[{i}]: not numbers ({err})") from None
        if arr.shape == (3,):
            out.append(Keepout.disc(float(arr[0]), float(arr[1]), float(arr[2])))
        elif arr.ndim == 2 and arr.shape[1] == 2 and len(arr) >= 3:
            out.append(Keepout(arr))
        else:
            raise ValueError(f"keepout[{i}]: expected [x, y, r] or a list of ≥ 3 [x, y] vertices, got shape {arr.shape}")
    return out


def dock_keepout(docked: Pose2, margin: float = DOCK_MARGIN) -> Keepout:
    """The Kobuki dock's box as a keep-out polygon, from the docked robot's base_link pose in ``map``.

    The docked robot faces the dock; the box spans ``BASE_RADIUS`` to
    ``BASE_RADIUS + DOCK_DEPTH`` ahead of it and ``DOCK_WIDTH`` across, grown
    by ``margin`` [m] on every side but the robot's (the docked robot sits
    against it and must be able to plan away).
    """
    x0, x1 = BASE_RADIUS + 0.005, BASE_RADIUS + DOCK_DEPTH + margin
    h = DOCK_WIDTH / 2 + margin
    corners = np.array([[x0, -h], [x1, -h], [x1, h], [x0, h]])
    return Keepout(docked.transform_points(corners))


def rasterise_keepout(zones: Sequence[Keepout], shape: tuple[int, int], resolution: float,
                      origin: tuple[float, float]) -> np.ndarray:
    """(H, W) bool: cells whose centre lies in a zone or that a zone's edge crosses (so thin zones still mark)."""
    mask = np.zeros(shape, dtype=np.uint8)
    for z in zones:
        if z.radius > 0.0:
            c = (z.points[0] - np.asarray(origin)) / resolution - 0.5
            # cv2.circle draws on integer pixels; use 4 bits of sub-pixel precision.
            cv2.circle(mask, (int(round(c[0] * 16)), int(round(c[1] * 16))), int(round(z.radius / resolution * 16)),
                       1, thickness=-1, shift=4)
        else:
            poly = (z.points - np.asarray(origin)) / resolution - 0.5
            cv2.fillPoly(mask, [np.round(poly * 16).astype(np.int32)], 1, shift=4)
        edge = np.floor((z.edge(0.5 * resolution) - np.asarray(origin)) / resolution).astype(np.int64)
        ok = (edge[:, 1] >= 0) & (edge[:, 1] < shape[0]) & (edge[:, 0] >= 0) & (edge[:, 0] < shape[1])
        mask[edge[ok, 1], edge[ok, 0]] = 1
    return mask.astype(bool)


def bumper_arc(bumpers: Bumpers, pose: Pose2, radius: float = BUMP_RIM, step: float = BUMP_ARC_STEP) -> np.ndarray:
    """(M, 2) [m] map points on the rim arcs of the pressed bumpers of a robot at ``pose`` (``map``)."""
    arcs = []
    for side in ("left", "centre", "right"):
        if getattr(bumpers, side):
            a0, a1 = SECTORS[side]
            n = max(2, int(math.ceil((a1 - a0) / step)) + 1)
            a = np.linspace(a0, a1, n)
            arcs.append(radius * np.column_stack([np.cos(a), np.sin(a)]))
    if not arcs:
        return np.zeros((0, 2))
    return pose.transform_points(np.vstack(arcs))


class BumpMarks:
    """Map points where bumpers fired, with their times; forgotten after ``memory`` seconds or on :meth:`clear`."""

    def __init__(self, memory: float = BUMP_MEMORY, capacity: int = MAX_BUMP_MARKS) -> None:
        self.memory = memory  # [s]
        self.capacity = capacity
        self.points = np.zeros((0, 2))  # [m] map
        self.stamps = np.zeros(0)  # [s]

    def __len__(self) -> int:
        return len(self.points)

    def add(self, pts: np.ndarray, stamp: float) -> None:
        pts = np.asarray(pts, dtype=float).reshape(-1, 2)
        if len(pts) == 0:
            return
        self.points = np.vstack([self.points, pts])[-self.capacity :]
        self.stamps = np.concatenate([self.stamps, np.full(len(pts), stamp)])[-self.capacity :]

    def forget(self, now: float) -> bool:
        """Drop marks older than ``memory`` at ``now`` [s]; whether any went."""
        keep = self.stamps > now - self.memory
        if keep.all():
            return False
        self.points, self.stamps = self.points[keep], self.stamps[keep]
        return True

    def clear(self) -> None:
        self.points, self.stamps = np.zeros((0, 2)), np.zeros(0)


def near(points: Iterable[np.ndarray], centre: Pose2, radius: float) -> np.ndarray:
    """(M, 2) the points of all arrays within ``radius`` [m] of ``centre``, still in ``map``."""
    arrs = [np.asarray(p, dtype=float).reshape(-1, 2) for p in points]
    if not arrs:
        return np.zeros((0, 2))
    allp = np.vstack(arrs)
    return allp[np.hypot(allp[:, 0] - centre.x, allp[:, 1] - centre.y) <= radius]
