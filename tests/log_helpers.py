"""Small synthetic laser logs for the log-format tests: a walled room, exact ray casting, a known trajectory."""

from __future__ import annotations

import math

import numpy as np
from homing.robot.types import Pose2

from tests.conftest import REPO

SHARED_CARMEN = REPO.parent / "shared" / "datasets" / "carmen"  # the five Radish logs (a dev checkout's)

# A 12 m × 8 m room with a pillar and a wall stub, so that scans pin every direction.
ROOM = [((0, 0), (12, 0)), ((12, 0), (12, 8)), ((12, 8), (0, 8)), ((0, 8), (0, 0)),
        ((5, 3), (6, 3)), ((6, 3), (6, 4)), ((6, 4), (5, 4)), ((5, 4), (5, 3)),
        ((9, 8), (9, 6))]


def cast(origin: Pose2, angles: np.ndarray, max_range: float, walls: list = ROOM) -> np.ndarray:
    """(N,) ranges [m] from ``origin`` (laser pose in the room) along ``angles`` [rad, laser frame]; inf: no hit."""
    a = origin.theta + np.asarray(angles, dtype=float)
    d = np.column_stack([np.cos(a), np.sin(a)])
    best = np.full(len(a), np.inf)
    o = np.array([origin.x, origin.y])
    for (x1, y1), (x2, y2) in walls:
        p, e = np.array([x1, y1], float), np.array([x2 - x1, y2 - y1], float)
        den = d[:, 0] * e[1] - d[:, 1] * e[0]
        with np.errstate(divide="ignore", invalid="ignore"):
            t = ((p[0] - o[0]) * e[1] - (p[1] - o[1]) * e[0]) / den
            u = ((p[0] - o[0]) * d[:, 1] - (p[1] - o[1]) * d[:, 0]) / den
        ok = (np.abs(den) > 1e-12) & (t > 0) & (u >= 0) & (u <= 1)
        best = np.where(ok & (t < best), t, best)
    return np.where(best <= max_range, best, np.inf)


def loop_trajectory(n: int) -> list[Pose2]:
    """``n`` poses around the pillar (a loop of ≈ 16 m), heading along the way."""
    out = []
    for i in range(n):
        s = 2 * math.pi * i / n
        x, y = 6 + 3.5 * math.cos(s), 3.5 + 2.2 * math.sin(s)
        out.append(Pose2(x, y, math.atan2(2.2 * math.cos(s), -3.5 * math.sin(s))))
    return out


def drifting_odometry(truth: list[Pose2], rng: np.random.Generator, sigma_xy: float = 0.03,
                      sigma_theta: float = math.radians(1.5)) -> list[Pose2]:
    """Odometry that integrates the true increments with noise (starts at the first true pose)."""
    odo = [truth[0]]
    for a, b in zip(truth, truth[1:], strict=False):
        d = a.between(b)
        noisy = Pose2(d.x + rng.normal(0, sigma_xy), d.y + rng.normal(0, sigma_xy), d.theta + rng.normal(0, sigma_theta))
        odo.append(odo[-1].compose(noisy))
    return odo


def flaser_line(ranges: np.ndarray, pose: Pose2, odom: Pose2, stamp: float, name: str = "FLASER") -> str:
    """A CARMEN FLASER line (``inf`` written as the no-return value 81.91)."""
    r = " ".join(f"{v:.3f}" if math.isfinite(v) else "81.91" for v in ranges)
    return (f"{name} {len(ranges)} {r} {pose.x:.6f} {pose.y:.6f} {pose.theta:.6f} "
            f"{odom.x:.6f} {odom.y:.6f} {odom.theta:.6f} {stamp:.6f} testhost {stamp:.6f}")


def odom_line(p: Pose2, stamp: float) -> str:
    return f"ODOM {p.x:.6f} {p.y:.6f} {p.theta:.6f} 0.3 0.1 0 {stamp:.6f} testhost {stamp:.6f}"
