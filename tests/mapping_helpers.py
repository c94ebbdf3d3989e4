"""Test helpers for mapping: lidar scans ray-cast against a known map, and drifting odometry along a path.

These stand in for the simulator only inside the mapping unit tests, so the
algorithms can be checked against exact geometry without pybullet.
"""

from __future__ import annotations

import math

import numpy as np
from homing.robot import Odometry, Pose2, Scan, Twist2

from homing.map_server import OCCUPIED, MapData
from tests.floor_plans import plan

RANGE_MAX = 6.0  # [m] RPLIDAR A1 as the thesis used it
RANGE_MIN = 0.15  # [m]
SCAN_RATE = 5.5  # [Hz]


def truth(name: str) -> MapData:
    """One of the floor plans drawn for the tests (:mod:`tests.floor_plans`)."""
    return plan(name)


def _solid(world: MapData) -> np.ndarray:
    """Wall cells, with diagonal wall steps closed (a sampled ray would slip between two corner-touching cells)."""
    occ = world.grid == OCCUPIED
    out = occ.copy()
    out[:-1, 1:] |= occ[:-1, :-1] & occ[1:, 1:] & ~occ[:-1, 1:] & ~occ[1:, :-1]
    out[:-1, :-1] |= occ[:-1, 1:] & occ[1:, :-1] & ~occ[:-1, :-1] & ~occ[1:, 1:]
    return out


def cast_scan(
    world: MapData,
    pose: Pose2,
    stamp: float = 0.0,
    rng: np.random.Generator | None = None,
    noise: float = 0.01,
    dropout: float = 0.0,
    rays: int = 360,
) -> Scan:
    """A 360° scan from ``pose`` (laser = base_link, in the world map's frame): first occupied cell along each ray."""
    res = world.resolution
    angles = -math.pi + np.arange(rays) * (2 * math.pi / rays)
    step = res / 4
    t = np.arange(step, RANGE_MAX + step, step)
    a = angles + pose.theta
    xs = pose.x + np.cos(a)[:, None] * t[None, :]
    ys = pose.y + np.sin(a)[:, None] * t[None, :]
    col = np.floor((xs - world.origin[0]) / res).astype(int)
    row = np.floor((ys - world.origin[1]) / res).astype(int)
    h, w = world.grid.shape
    inside = (row >= 0) & (row < h) & (col >= 0) & (col < w)
    occ = np.zeros(xs.shape, dtype=bool)
    occ[inside] = _solid(world)[row[inside], col[inside]]
    first = np.argmax(occ, axis=1)
    ranges = np.where(occ.any(axis=1), t[first], np.inf)
    if rng is not None:
        ranges = ranges + rng.normal(0.0, noise, rays)
        if dropout:
            ranges[rng.random(rays) < dropout] = np.inf
    ranges[(ranges < RANGE_MIN) | (ranges > RANGE_MAX)] = np.inf
    return Scan(stamp, -math.pi, 2 * math.pi / rays, ranges.astype(np.float32), RANGE_MIN, RANGE_MAX)


def path_poses(waypoints: list[tuple[float, float]], speed: float = 0.4, rate: float = SCAN_RATE) -> list[Pose2]:
    """Poses sampled at ``rate`` [Hz] driving at ``speed`` [m/s] through waypoints, heading along each leg."""
    out: list[Pose2] = []
    ds = speed / rate
    for (x0, y0), (x1, y1) in zip(waypoints[:-1], waypoints[1:], strict=False):
        length = math.hypot(x1 - x0, y1 - y0)
        th = math.atan2(y1 - y0, x1 - x0)
        n = max(1, int(length / ds))
        # turn on the spot first, a few steps
        if out:
            prev = out[-1].theta
            d = math.atan2(math.sin(th - prev), math.cos(th - prev))
            for k in range(1, 6):
                out.append(Pose2(x0, y0, prev + d * k / 5))
        for i in range(n):
            f = i / n
            out.append(Pose2(x0 + f * (x1 - x0), y0 + f * (y1 - y0), th))
    return out


def drifting_odometry(
    poses: list[Pose2], rng: np.random.Generator, bias: float = 0.03, noise: float = 0.02
) -> list[Pose2]:
    """Odometry (starting at identity) from true poses, with a heading bias [rad/m] and noise proportional to motion."""
    odom = [Pose2()]
    for p0, p1 in zip(poses[:-1], poses[1:], strict=False):
        d = p0.between(p1)
        dist = math.hypot(d.x, d.y)
        dth = d.theta + bias * dist + rng.normal(0, noise * (dist + 0.3 * abs(d.theta)))
        dx = d.x * (1 + rng.normal(0, noise))
        odom.append(odom[-1].compose(Pose2(dx, d.y, dth)))
    return odom


def odometry_msg(stamp: float, pose: Pose2) -> Odometry:
    return Odometry(stamp, pose, Twist2())


def travel_distance(grid: np.ndarray, resolution: float, start: tuple[int, int], robot_radius: float = 0.19) -> np.ndarray:
    """(H, W) travel distance [m] from ``start`` (row, col) through cells the robot fits in (scikit-fmm), inf elsewhere.

    Stands in for navigation's ``distance_map`` in mapping's tests.
    """
    import skfmm
    from homing.mapping.frontier import accessible_mask

    ok = accessible_mask(grid, resolution, robot_radius)
    ok[start] = True
    phi = np.ones(grid.shape)
    phi[start] = -1.0
    d = skfmm.distance(np.ma.MaskedArray(phi, ~ok), dx=resolution)
    out = np.asarray(d.filled(np.inf), dtype=float) + 0.5 * resolution
    out[start] = 0.0
    # keep only the component connected to the start
    import cv2

    _, labels = cv2.connectedComponents(ok.astype(np.uint8), connectivity=8)
    out[labels != labels[start]] = np.inf
    return out
