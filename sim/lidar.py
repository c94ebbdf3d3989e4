"""The RPLIDAR A1 as the thesis used it: 360 rays by ``rayTestBatch`` with range noise and dropouts.

Rays leave the laser (``LASER_POSE`` in base_link, ``LIDAR_HEIGHT`` above the
floor) at 1° steps counter-clockwise from straight ahead, and return the
distance to the first collision shape (walls, fault obstacles; not tags,
not the dock, which is lower than the laser). Noise model, per ray,
independent and seeded:

- range noise: Gaussian, σ = ``RANGE_SIGMA`` [m];
- dropout: no return (``inf``) with probability ``DROPOUT_P``, and more at
  grazing incidence: + ``GRAZING_DROPOUT_P`` · s, where s rises linearly from 0
  at ``GRAZING_START`` to 1 at 90° between the ray and the surface normal;
- no return beyond ``LIDAR_RANGE_MAX`` or under ``LIDAR_RANGE_MIN`` (``inf``).

A scan is taken instantly at one pose (no motion skew). When NOT to use:
a 3-D obstacle below or above the scan plane is invisible to it, as on the robot.
"""

from __future__ import annotations

import math

import numpy as np
from homing.robot.turtlebot import LIDAR_HEIGHT, LIDAR_RANGE_MAX, LIDAR_RANGE_MIN, LIDAR_RAYS
from homing.robot.types import Pose2, Scan
from homing.sim.scene import Scene

LASER_POSE = Pose2(0.0, 0.0, 0.0)  # laser in base_link (on the top plate, centred)
RANGE_SIGMA = 0.01  # [m] range noise standard deviation
DROPOUT_P = 0.005  # probability a ray returns nothing
GRAZING_DROPOUT_P = 0.5  # extra dropout probability at 90° incidence
GRAZING_START = math.radians(70.0)  # [rad] incidence where grazing dropouts begin


class SimLidar:
    """Casts one scan at a time from a :class:`Scene`."""

    def __init__(self, scene: Scene, rays: int = LIDAR_RAYS, range_max: float = LIDAR_RANGE_MAX):
        self.scene = scene
        self.n = rays
        self.range_max = range_max
        self.increment = 2 * math.pi / rays
        a = np.arange(rays) * self.increment
        self._dirs = np.column_stack([np.cos(a), np.sin(a)])
        self._next, self._prev = np.roll(np.arange(rays), -1), np.roll(np.arange(rays), 1)

    def true_ranges(self, pose: Pose2) -> tuple[np.ndarray, np.ndarray]:
        """(N,) noise-free ranges [m] (inf: no hit within range_max) and (N,) incidence angles [rad]."""
        laser = pose.compose(LASER_POSE)
        c, s = math.cos(laser.theta), math.sin(laser.theta)
        d = self._dirs @ np.array([[c, s], [-s, c]])  # rotate ray directions into the world
        start = np.empty((self.n, 3))
        start[:] = (laser.x, laser.y, LIDAR_HEIGHT)
        end = start.copy()
        end[:, :2] += d * self.range_max
        frac, ids = self.scene.rays(start, end)
        ranges = np.where((ids >= 0) & (frac < 1.0), frac * self.range_max, np.inf)
        return ranges, self._incidence(d, ranges, laser)

    def _incidence(self, d: np.ndarray, ranges: np.ndarray, laser: Pose2) -> np.ndarray:
        """(N,) angle [rad] between each ray and the surface normal where it hit (0 where unknown).

        Neighbouring hit points give the surface's direction; the normal is ⟂ to it.
        """
        with np.errstate(invalid="ignore", divide="ignore"):
            hits = d * ranges[:, None] + (laser.x, laser.y)  # (N, 2) hit points in the world
            tangent = hits[self._next] - hits[self._prev]
            tangent /= np.sqrt(np.add.reduce(tangent * tangent, axis=1))[:, None]
            cos_ray_tangent = np.abs(np.add.reduce(tangent * d, axis=1))
        np.nan_to_num(cos_ray_tangent, copy=False, nan=0.0)
        return np.arcsin(np.clip(cos_ray_tangent, 0.0, 1.0, out=cos_ray_tangent))

    def scan(self, pose: Pose2, stamp: float, rng: np.random.Generator, extra_dropout: float = 0.0) -> Scan:
        """One noisy scan at the true ``pose``; ``extra_dropout`` (0..1) adds a fault's burst of lost rays."""
        ranges, incidence = self.true_ranges(pose)
        noise = rng.standard_normal(self.n) * RANGE_SIGMA
        u = rng.random(self.n)
        grazing = np.clip((incidence - GRAZING_START) / (math.pi / 2 - GRAZING_START), 0.0, 1.0)
        p_drop = np.clip(DROPOUT_P + GRAZING_DROPOUT_P * grazing + extra_dropout, 0.0, 1.0)
        r = ranges + noise
        r[(u < p_drop) | (r < LIDAR_RANGE_MIN) | (r > self.range_max)] = np.inf
        return Scan(stamp, 0.0, self.increment, r.astype(np.float32), LIDAR_RANGE_MIN, self.range_max, LASER_POSE)
