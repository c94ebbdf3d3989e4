"""Local controllers chosen by name: regulated pure pursuit (Macenski et al. 2023) with a scan-checked arc.

Regulated pure pursuit (S. Macenski, S. Singh, F. Martín, J. Ginés,
"Regulated Pure Pursuit for Robot Path Tracking", Autonomous Robots 2023;
Nav2's ``nav2_regulated_pure_pursuit_controller``) steers on the circle
through a carrot a speed-scaled lookahead ahead on the path, and lowers the
speed on tight curvature and when approaching the goal. It rotates in place
first when the path starts behind the robot.

Nav2's third regulation, slowing wherever the footprint is near an obstacle
in the costmap whichever way the robot goes, is off by default
(``cost_scaling_dist=0``; a positive value brings it back): the scan check
below already caps the speed by what lies on the arc ahead, and the
isotropic rule slowed the robot beside every wall it drove along and round
every door jamb it turned at: 16–37 % of the time to 95 % coverage
(61–175 s a run) on office:1–2, hospital:1, slam_office:1, the maze and the
rings (``homing bench explore``, seed 0; on office:1 at gaps of 0.03–0.26 m
beyond the footprint, median 0.13 m), with no bumper press on any of ten
plans once it was taken away. With nothing to check the arc against (no
lidar, or no return near enough to count) the rule is back at
``blind_scaling_dist`` (0.3 m, Nav2's): the costmap is then all the
controller knows of the walls, and pure pursuit's lookahead, longer at
speed, cuts the corners it turns round (a scripted robot without a lidar
drove its centre within 0.075 m of a maze wall, the footprint being 0.176 m, without it).

Whatever the controller wants, the commanded arc is then checked against
the latest scan with the robot's round footprint (:func:`free_distance`):
the speed is capped so the robot can brake before the first point it would
touch, and when it cannot move at all :class:`CollisionAhead` is raised —
the robot never drives into what the lidar sees, even when the costmap is
stale. When the arc is blocked, rpp hands the tick to its ``fallback``
controller (by name, default ``dwb``: :mod:`homing.navigation.dwb`, which
samples arcs and turn-then-go escapes and steers around) instead of stopping;
with ``fallback=None`` it raises :class:`CollisionAhead`. Speeds stay ≤
``NAV_MAX_V`` (0.5 m/s).

Frames: the pose and the path are in the same frame (``map``); scan points
are in ``base_link`` at the present time (the navigator moves a stale scan
forward by odometry).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Protocol

import numpy as np
from homing.navigation.costmap import Costmap
from homing.robot import Pose2, Twist2
from homing.robot.turtlebot import FOOTPRINT_RADIUS, NAV_MAX_V

DESIRED_V = NAV_MAX_V  # [m/s]
LOOKAHEAD_TIME = 1.5  # [s] lookahead = |v|·time, clamped (Nav2 default)
MIN_LOOKAHEAD = 0.3  # [m]
MAX_LOOKAHEAD = 0.9  # [m]
ROTATE_MIN_ANGLE = 0.785  # [rad] rotate in place when the carrot is this far off the heading
ROTATE_OMEGA = 1.8  # [rad/s] in-place rotation speed (Nav2 default)
MAX_OMEGA = 2.0  # [rad/s]
MIN_RADIUS = 0.9  # [m] curvature regulation starts below this turning radius
COST_SCALING_DIST = 0.0  # [m] obstacle-proximity regulation starts at this clearance beyond the footprint (0: off)
BLIND_SCALING_DIST = 0.3  # [m] the same when there are no obstacle points to check the arc against
MIN_REGULATED_V = 0.15  # [m/s] the curvature/proximity regulations never go below this
APPROACH_DIST = 0.6  # [m] slow down over the last stretch to the goal
MIN_APPROACH_V = 0.05  # [m/s]
MAX_ACCEL = 1.0  # [m/s²] Kobuki's comfortable linear acceleration
MAX_DECEL = 1.0  # [m/s²] braking assumed by the scan check
SAFETY_MARGIN = 0.0  # [m] kept between the footprint (already 14 mm beyond the body) and any scan point
STOP_MARGIN = 0.05  # [m] arc length kept free after braking
COLLISION_HORIZON = 1.0  # [s] how far ahead the arc is checked at the commanded speed
MIN_CHECK_DIST = 0.3  # [m] the arc is always checked at least this far
ARC_STEP = 0.02  # [m] sampling of the checked arc


class ControllerError(Exception):
    """A local controller cannot produce a safe command."""


class CollisionAhead(ControllerError):
    """The scan shows an obstacle on the commanded arc within braking distance: the robot must stop."""


class InvalidPath(ControllerError):
    """The path is empty or the robot is too far from it to track it."""


class Controller(Protocol):
    """Tracks a path: ``compute(pose, speed, path, scan_points, costmap, dt)`` → Twist2.

    ``pose`` and ``path`` ((N, 2) [m]) in the map frame, ``speed`` the current
    twist, ``scan_points`` (M, 2) [m] in base_link now, ``dt`` [s] since the
    last call. Raises :class:`ControllerError` subclasses.
    """

    name: str

    def reset(self) -> None: ...

    def compute(self, pose: Pose2, speed: Twist2, path: np.ndarray, scan_points: np.ndarray,
                costmap: Costmap | None, dt: float) -> Twist2: ...


# -- the scan check ------------------------------------------------------------------------
def path_in_base(pose: Pose2, path: np.ndarray) -> np.ndarray:
    """(N, 2) ``path`` [m, map] seen from the robot at ``pose`` (base_link); an empty path is :class:`InvalidPath`."""
    path = np.asarray(path, dtype=float).reshape(-1, 2)
    if len(path) == 0:
        raise InvalidPath("empty path")
    return pose.inverse().transform_points(path)


def arc_poses(v: float, omega: float, length: float, step: float = ARC_STEP) -> np.ndarray:
    """(K, 3) poses (x, y, θ) in base_link along the arc of (v, ω), every ``step`` [m] up to ``length`` [m]."""
    s = np.arange(0.0, length + 1e-9, step) * (1.0 if v >= 0 else -1.0)
    if abs(v) < 1e-6:
        return np.zeros((1, 3))
    k = omega / v  # [1/m] curvature; the sign of v carries the direction of travel
    if abs(k) < 1e-6:
        return np.column_stack([s, np.zeros_like(s), np.zeros_like(s)])
    th = k * s
    return np.column_stack([np.sin(th) / k, (1.0 - np.cos(th)) / k, th])


def free_distance(v: float, omega: float, points: np.ndarray, radius: float, length: float) -> float:
    """Arc length [m] the footprint (a disc of ``radius`` [m]) travels along (v, ω) before touching a point.

    ``points`` are (M, 2) [m] in base_link; ``inf`` if nothing is touched
    within ``length``. A point already inside the footprint counts only if
    the motion brings the footprint closer to it (so a robot grazing a
    wall may still move away from it).
    """
    pts = np.asarray(points, dtype=float).reshape(-1, 2)
    if len(pts) == 0 or abs(v) < 1e-6:
        return math.inf
    near = np.hypot(pts[:, 0], pts[:, 1]) <= length + radius + ARC_STEP
    pts = pts[near]
    if len(pts) == 0:
        return math.inf
    poses = arc_poses(v, omega, length)
    d = np.hypot(poses[:, None, 0] - pts[None, :, 0], poses[:, None, 1] - pts[None, :, 1])
    inside0 = d[0] < radius
    # Points inside the footprint at the start block only if the robot moves towards them.
    approaching = d[1] < d[0] if len(d) > 1 else np.zeros(len(pts), bool)
    hit = d < radius
    hit[:, inside0 & ~approaching] = False
    rows = np.flatnonzero(hit.any(axis=1))
    if len(rows) == 0:
        return math.inf
    return float(rows[0]) * ARC_STEP


def safe_speed(v: float, omega: float, points: np.ndarray, radius: float = FOOTPRINT_RADIUS + SAFETY_MARGIN,
               decel: float = MAX_DECEL) -> float:
    """The largest |v| [m/s] (≤ |v|) along the arc of curvature ω/v that can brake before the scan's points.

    Same sign as ``v``; 0 when the arc is blocked right away. Rotations in
    place are always safe for a round robot and return ``v`` (= 0).
    """
    if abs(v) < 1e-6:
        return 0.0
    length = max(MIN_CHECK_DIST, abs(v) * COLLISION_HORIZON + v * v / (2 * decel)) + STOP_MARGIN
    s = free_distance(v, omega, points, radius, length)
    if math.isinf(s):
        return v
    room = max(0.0, s - STOP_MARGIN)
    vmax = math.sqrt(2.0 * decel * room)
    return math.copysign(min(abs(v), vmax), v)


# -- regulated pure pursuit -------------------------------------------------------------------
@dataclass
class RegulatedPurePursuit:
    """Nav2's regulated pure pursuit, with every command checked against the scan (see the module doc)."""

    desired_v: float = DESIRED_V  # [m/s]
    lookahead_time: float = LOOKAHEAD_TIME  # [s]
    min_lookahead: float = MIN_LOOKAHEAD  # [m]
    max_lookahead: float = MAX_LOOKAHEAD  # [m]
    rotate_min_angle: float = ROTATE_MIN_ANGLE  # [rad]
    rotate_omega: float = ROTATE_OMEGA  # [rad/s]
    max_omega: float = MAX_OMEGA  # [rad/s]
    min_radius: float = MIN_RADIUS  # [m]
    cost_scaling_dist: float = COST_SCALING_DIST  # [m]
    blind_scaling_dist: float = BLIND_SCALING_DIST  # [m]
    min_regulated_v: float = MIN_REGULATED_V  # [m/s]
    approach_dist: float = APPROACH_DIST  # [m]
    min_approach_v: float = MIN_APPROACH_V  # [m/s]
    max_accel: float = MAX_ACCEL  # [m/s²]
    footprint_radius: float = FOOTPRINT_RADIUS  # [m]
    max_path_offset: float = 1.0  # [m] farther from the path than this: InvalidPath
    fallback: str | None = "dwb"  # controller asked when the arc is blocked (None: raise CollisionAhead)
    name: str = "rpp"

    def __post_init__(self) -> None:
        self.desired_v = min(self.desired_v, NAV_MAX_V)
        self.carrot: np.ndarray | None = None  # last carrot [m], map frame (for pictures)
        self.fallback_used = 0  # commands the fallback gave since the last reset
        self._fallback: Controller | None = None
        if self.fallback is not None:
            if self.fallback == self.name:
                raise ValueError("a controller cannot be its own fallback")
            self._fallback = make_controller(self.fallback, max_v=self.desired_v, max_omega=self.max_omega,
                                             footprint_radius=self.footprint_radius)

    def reset(self) -> None:
        self.carrot = None
        self.fallback_used = 0
        if self._fallback is not None:
            self._fallback.reset()

    def compute(self, pose: Pose2, speed: Twist2, path: np.ndarray, scan_points: np.ndarray,
                costmap: Costmap | None, dt: float) -> Twist2:
        local = path_in_base(pose, path)
        offset, remaining, carrot = _carrot(local, self._lookahead(speed.v))
        if offset > self.max_path_offset:
            raise InvalidPath(f"robot is {offset:.2f} m from its path")
        self.carrot = pose.transform_points(carrot[None, :])[0]
        angle = math.atan2(carrot[1], carrot[0])
        if abs(angle) > self.rotate_min_angle:
            return Twist2(0.0, math.copysign(self.rotate_omega, angle))
        dist2 = float(carrot @ carrot)
        kappa = 2.0 * carrot[1] / dist2 if dist2 > 1e-9 else 0.0
        v = self._regulate(kappa, remaining, pose, costmap, blind=len(scan_points) == 0)
        v = min(v, max(0.0, speed.v) + self.max_accel * max(dt, 1e-3))
        v_safe = safe_speed(v, v * kappa, scan_points, self.footprint_radius + SAFETY_MARGIN)
        if v > 1e-6 and v_safe < 0.01:
            if self._fallback is None:
                raise CollisionAhead("an obstacle in the scan blocks the path ahead")
            # The arc is blocked: let the sampling controller steer around (or raise itself).
            self.fallback_used += 1
            return self._fallback.compute(pose, speed, path, scan_points, costmap, dt)
        v = v_safe
        omega = float(np.clip(v * kappa, -self.max_omega, self.max_omega))
        return Twist2(v, omega)

    def _lookahead(self, v: float) -> float:
        return float(np.clip(abs(v) * self.lookahead_time, self.min_lookahead, self.max_lookahead))

    def _regulate(self, kappa: float, remaining: float, pose: Pose2, costmap: Costmap | None,
                  blind: bool = False) -> float:
        v = self.desired_v
        # Curvature: slow on tight turns (Macenski et al., eq. 5).
        if abs(kappa) > 1e-9 and 1.0 / abs(kappa) < self.min_radius:
            v *= (1.0 / abs(kappa)) / self.min_radius
        # Proximity (off unless cost_scaling_dist > 0, or blind: no points for the scan check): slow where the
        # footprint is close to something in the costmap.
        scaling = max(self.cost_scaling_dist, self.blind_scaling_dist) if blind else self.cost_scaling_dist
        if scaling > 0 and costmap is not None and costmap.cost.size:
            rc = costmap.world_to_cell(np.array([pose.x, pose.y]))
            if costmap.inside(rc)[0]:
                gap = float(costmap.clearance[rc[0, 0], rc[0, 1]]) - self.footprint_radius
                if gap < scaling:
                    v *= max(gap, 0.0) / scaling
        v = max(v, min(self.min_regulated_v, self.desired_v))
        # Approach: slow over the last metres so the goal is not overshot.
        if remaining < self.approach_dist:
            v = max(v * remaining / self.approach_dist, self.min_approach_v)
        return min(v, self.desired_v)


def _carrot(local: np.ndarray, lookahead: float) -> tuple[float, float, np.ndarray]:
    """Distance to the path, remaining path length and the carrot, all from a base_link path [m].

    The path is first pruned at its point closest to the robot; the carrot
    is where the path leaves the lookahead circle (interpolated), or its end.
    """
    if len(local) == 1:
        p = local[0]
        return 0.0, float(np.hypot(*p)), p
    a, b = local[:-1], local[1:]
    ab = b - a
    t = np.clip(np.einsum("ij,ij->i", -a, ab) / np.maximum(np.einsum("ij,ij->i", ab, ab), 1e-12), 0, 1)
    foot = a + t[:, None] * ab
    dist = np.hypot(foot[:, 0], foot[:, 1])
    i = int(np.argmin(dist))
    pts = np.vstack([foot[i], local[i + 1 :]])
    seg = np.hypot(*np.diff(pts, axis=0).T)
    remaining = float(seg.sum())
    r = np.hypot(pts[:, 0], pts[:, 1])
    out = np.flatnonzero(r >= lookahead)
    if len(out) == 0:
        return float(dist[i]), remaining, pts[-1]
    j = int(out[0])
    if j == 0:
        return float(dist[i]), remaining, pts[0]
    # Intersect segment pts[j-1] → pts[j] with the lookahead circle.
    p, q = pts[j - 1], pts[j]
    d = q - p
    A, B, C = d @ d, 2 * p @ d, p @ p - lookahead**2
    disc = max(B * B - 4 * A * C, 0.0)
    s = (-B + math.sqrt(disc)) / (2 * A) if A > 1e-12 else 1.0
    return float(dist[i]), remaining, p + float(np.clip(s, 0.0, 1.0)) * d


CONTROLLERS: dict[str, type] = {"rpp": RegulatedPurePursuit}


def make_controller(name: str, **params: object) -> Controller:
    """The controller registered as ``name`` (``rpp``, ``dwb``) with its parameters."""
    _load_plugins()
    if name not in CONTROLLERS:
        raise KeyError(f"unknown controller '{name}' (known: {', '.join(sorted(CONTROLLERS))})")
    controller: Controller = CONTROLLERS[name](**params)
    return controller


def _load_plugins() -> None:
    """Import the controllers that live in their own modules (they register themselves)."""
    from homing.navigation import dwb  # noqa: F401  (registers "dwb")


_load_plugins()
