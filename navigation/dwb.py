"""A sampling local controller after Nav2's DWB (Fox, Burgard, Thrun, "The Dynamic Window Approach", 1997).

Each call samples velocity pairs (v, ω) inside the *dynamic window* — the
speeds reachable from the current twist within one control period under the
acceleration limits — plus, always, turning in place; forward-simulates each
at constant speed for ``sim_time`` (1.5 s) as exact unicycle arcs; rejects
every trajectory on which the round footprint would touch a scan point or
move deeper into the costmap's inscribed zone; and scores the rest with
Nav2's critics, lower is better:

- **path distance** of the trajectory's end from the global path,
- **goal progress**: how far along the path the end's projection lies (the
  path is cut a little beyond the longest trajectory's reach, so a U-turn
  of the path cannot be shortcut),
- **path alignment**: distance from a point ``forward_point`` ahead of the
  end pose to the path (Nav2's PathAlign), so the robot ends facing along it,
- **obstacle cost**: the costmap's worst cost along the trajectory,
- **clearance**: how close the footprint comes to the scan's points,
- **stall**: a trajectory that ends where it started (unless the goal is near).

The robot therefore steers around what blocks a pure-pursuit arc instead of
stopping, and never picks a motion that touches what the lidar sees within
the horizon. When every sample is rejected it raises
:class:`~homing.navigation.controller.CollisionAhead` and the caller stops.

Registered as the ``dwb`` controller, and used by ``rpp`` as its fallback
when the pure-pursuit arc is blocked (``fallback="dwb"``). Frames as
:class:`~homing.navigation.controller.Controller`: pose and path in ``map``,
scan points in ``base_link`` now. When NOT to use: for a robot that is not
round (the footprint check is a disc), or when no scan is available and the
costmap is stale (it then only sees the costmap).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from homing.navigation.controller import CONTROLLERS, CollisionAhead, InvalidPath, path_in_base
from homing.navigation.costmap import INSCRIBED, MAX_NON_OBSTACLE, NO_INFORMATION, Costmap
from homing.robot import Pose2, Twist2
from homing.robot.turtlebot import FOOTPRINT_RADIUS, NAV_MAX_V

SIM_TIME = 1.5  # [s] forward simulation horizon (Nav2 default 1.7)
SIM_STEP = 0.1  # [s] time between simulated poses
V_SAMPLES = 6  # target linear speeds, 0 … max (Nav2 vx_samples 20)
W_SAMPLES = 19  # target angular speeds, −max … max (Nav2 vtheta_samples 20)
MIN_V = 0.0  # [m/s] no reversing: the lidar sees behind, but backing up is a recovery's job
MAX_OMEGA = 1.8  # [rad/s]
ACC_V = 1.0  # [m/s²] Kobuki's comfortable linear acceleration
DEC_V = 1.0  # [m/s²]
ACC_W = 3.2  # [rad/s²] Nav2 default
MIN_PERIOD = 0.1  # [s] the window spans at least this control period
PATH_WINDOW = 3.0  # [m] of path ahead of the robot considered
FORWARD_POINT = 0.325  # [m] PathAlign's point ahead of the end pose (Nav2 forward_point_distance)
CLEARANCE_REF = 0.15  # [m] clearance beyond the footprint under which the clearance critic rises
PATH_SLACK = 0.3  # [m] the path is considered this far beyond the longest trajectory's reach
ESCAPE_ANGLES = np.radians([-180.0, -135.0, -90.0, -60.0, -30.0, 30.0, 60.0, 90.0, 135.0])  # [rad] turn-then-go primitives
ESCAPE_V = 0.15  # [m/s] their straight part's speed
W_PROGRESS = 1.0  # [1/m] weight of the progress along the path (the end's projection)
W_PATH = 0.6  # [1/m] weight of the end's distance from the path
W_ALIGN = 0.4  # [1/m] weight of the forward point's distance from the path
W_OBSTACLE = 0.3  # weight of the worst normalised costmap cost
W_CLEARANCE = 0.8  # weight of the scan-clearance penalty (0 … 1)
W_STALL = 0.3  # weight of the stall penalty: 1 for a trajectory that goes nowhere, 0 from STALL_DIST on
STALL_DIST = 0.1  # [m] a trajectory ending this far from the start is not a stall
STALL_ZONE = 0.5  # [m] of path left under which stopping is fine (the goal is near)
UNKNOWN_COST = 0.5  # normalised cost of an unknown cell
DEEPEN_EPS = 1e-3  # [m] a footprint already touching may not get closer by more than this


def rollout(v0: float, w0: float, v_target: np.ndarray, w_target: np.ndarray, acc_v: float, dec_v: float,
            acc_w: float, step: float) -> tuple[np.ndarray, np.ndarray]:
    """Simulate K target schedules from the twist (v0 [m/s], w0 [rad/s]) under acceleration limits.

    ``v_target``, ``w_target`` are (K, T) targets per step of ``step`` [s];
    the speeds move towards them at ≤ ``acc_v``/``dec_v`` [m/s²] and
    ``acc_w`` [rad/s²], and each step is integrated as an exact arc. Returns
    (K, T, 3) poses (x, y, θ) in base_link at the end of each step and (K, T, 2)
    the twists (v, ω) held during each step — the first is this period's command.
    """
    k, t = v_target.shape
    pose = np.zeros((k, 3))
    v = np.full(k, float(v0))
    w = np.full(k, float(w0))
    poses = np.empty((k, t, 3))
    twists = np.empty((k, t, 2))
    for i in range(t):
        dv = v_target[:, i] - v
        v = v + np.clip(dv, -dec_v * step, acc_v * step)
        w = w + np.clip(w_target[:, i] - w, -acc_w * step, acc_w * step)
        ds, dth = v * step, w * step
        small = np.abs(dth) < 1e-9
        chord = np.where(small, ds, 2.0 * ds / np.where(small, 1.0, dth) * np.sin(0.5 * dth))
        h = pose[:, 2] + 0.5 * dth
        pose = np.column_stack([pose[:, 0] + chord * np.cos(h), pose[:, 1] + chord * np.sin(h), pose[:, 2] + dth])
        poses[:, i] = pose
        twists[:, i, 0], twists[:, i, 1] = v, w
    return poses, twists


def scan_clearance(traj: np.ndarray, points: np.ndarray, radius: float) -> tuple[np.ndarray, np.ndarray]:
    """Per trajectory: (K,) bool whether the footprint touches a scan point, (K,) smallest gap [m] beyond ``radius``.

    ``traj`` (K, T, 3) in base_link, ``points`` (M, 2) in base_link. A point
    already inside the footprint at the start only counts if the trajectory
    brings the footprint closer to it (the robot may always move away).
    """
    k = traj.shape[0]
    pts = np.asarray(points, dtype=float).reshape(-1, 2)
    reach = float(np.hypot(traj[..., 0], traj[..., 1]).max(initial=0.0)) + radius + CLEARANCE_REF
    pts = pts[np.hypot(pts[:, 0], pts[:, 1]) <= reach]
    if len(pts) == 0:
        return np.zeros(k, bool), np.full(k, math.inf)
    d = np.hypot(traj[:, :, None, 0] - pts[None, None, :, 0], traj[:, :, None, 1] - pts[None, None, :, 1])
    d0 = np.hypot(pts[:, 0], pts[:, 1])  # (M,) from the start pose (the origin)
    touching = (d < radius) & (d < d0[None, None, :] - DEEPEN_EPS)
    hit = touching.any(axis=(1, 2))
    gap = d.min(axis=(1, 2)) - radius
    return hit, gap


def _local_path(path: np.ndarray, window: float) -> tuple[np.ndarray, np.ndarray]:
    """The stretch of a base_link path (N, 2) from the robot's projection on it, ``window`` [m] long, and its arc lengths."""
    if len(path) == 1:
        return path.copy(), np.zeros(1)
    a, b = path[:-1], path[1:]
    ab = b - a
    t = np.clip(np.einsum("ij,ij->i", -a, ab) / np.maximum(np.einsum("ij,ij->i", ab, ab), 1e-12), 0.0, 1.0)
    foot = a + t[:, None] * ab
    i = int(np.argmin(np.hypot(foot[:, 0], foot[:, 1])))
    pts = np.vstack([foot[i], path[i + 1 :]])
    s = np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(pts, axis=0).T))])
    keep = np.searchsorted(s, window) + 1
    return pts[:keep], s[:keep]


def project(q: np.ndarray, pts: np.ndarray, s: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(K,) arc length [m] of each point's projection onto the polyline ``pts`` (N, 2) with arc lengths ``s`` (N,), and (K,) distance [m] to it."""
    if len(pts) == 1:
        return np.zeros(len(q)), np.hypot(q[:, 0] - pts[0, 0], q[:, 1] - pts[0, 1])
    a, ab = pts[:-1], np.diff(pts, axis=0)
    L2 = np.maximum(np.einsum("ij,ij->i", ab, ab), 1e-12)
    t = np.clip(((q[:, None, :] - a[None]) * ab[None]).sum(-1) / L2[None], 0.0, 1.0)
    foot = a[None] + t[..., None] * ab[None]
    d = np.hypot(q[:, None, 0] - foot[..., 0], q[:, None, 1] - foot[..., 1])
    j = np.argmin(d, axis=1)
    rows = np.arange(len(q))
    along = s[j] + t[rows, j] * np.sqrt(L2[j])
    return along, d[rows, j]


def polyline_distance(q: np.ndarray, pts: np.ndarray) -> np.ndarray:
    """(K,) distances [m] from points q (K, 2) to the polyline ``pts`` (N, 2)."""
    if len(pts) == 1:
        return np.hypot(q[:, 0] - pts[0, 0], q[:, 1] - pts[0, 1])
    a, ab = pts[:-1], np.diff(pts, axis=0)
    L2 = np.maximum(np.einsum("ij,ij->i", ab, ab), 1e-12)
    t = np.clip(((q[:, None, :] - a[None]) * ab[None]).sum(-1) / L2[None], 0.0, 1.0)
    foot = a[None] + t[..., None] * ab[None]
    return np.hypot(q[:, None, 0] - foot[..., 0], q[:, None, 1] - foot[..., 1]).min(axis=1)


def turn_then_go(angles: np.ndarray, omega: float, v: float, acc_w: float, steps: int,
                 step: float) -> tuple[np.ndarray, np.ndarray]:
    """Escape primitives as (A, T) target schedules: turn in place by each angle [rad] at ``omega`` [rad/s], then drive straight at ``v`` [m/s]."""
    angles = np.asarray(angles, dtype=float)
    t = (np.arange(steps) + 0.5) * step
    turn_time = np.abs(angles) / omega + 0.5 * omega / acc_w  # [s] including the ramp down
    turning = t[None, :] < turn_time[:, None]
    w_t = np.where(turning, np.sign(angles)[:, None] * omega, 0.0)
    v_t = np.where(turning, 0.0, v)
    return v_t, w_t


@dataclass
class DWB:
    """Dynamic-window sampling controller with Nav2's critics (see the module doc); ``dwb`` in the registry."""

    max_v: float = NAV_MAX_V  # [m/s]
    min_v: float = MIN_V  # [m/s]
    max_omega: float = MAX_OMEGA  # [rad/s]
    acc_v: float = ACC_V  # [m/s²]
    dec_v: float = DEC_V  # [m/s²]
    acc_omega: float = ACC_W  # [rad/s²]
    sim_time: float = SIM_TIME  # [s]
    v_samples: int = V_SAMPLES
    omega_samples: int = W_SAMPLES
    footprint_radius: float = FOOTPRINT_RADIUS  # [m]
    max_path_offset: float = 1.0  # [m] farther from the path than this: InvalidPath
    name: str = "dwb"

    def __post_init__(self) -> None:
        self.max_v = min(self.max_v, NAV_MAX_V)
        self.best: np.ndarray | None = None  # (T, 3) chosen trajectory in map (for pictures)
        self.rejected = 0  # samples rejected on the last call
        self.escaping = False  # whether the last command was an escape primitive's turn

    def reset(self) -> None:
        self.best = None
        self.escaping = False

    # -- sampling ---------------------------------------------------------------------
    def targets(self, steps: int) -> tuple[np.ndarray, np.ndarray]:
        """(K, T) target v [m/s] and ω [rad/s]: a grid of constant targets, then the escape primitives.

        Targets span the robot's whole speed range; :func:`rollout` reaches them
        at the acceleration limits, so every simulated trajectory — and the
        command, its first step — respects the dynamic window.
        """
        vs = np.linspace(self.min_v, self.max_v, self.v_samples)
        ws = np.linspace(-self.max_omega, self.max_omega, self.omega_samples)
        vv, ww = np.meshgrid(vs, ws, indexing="ij")
        v_t = np.repeat(vv.reshape(-1, 1), steps, axis=1)
        w_t = np.repeat(ww.reshape(-1, 1), steps, axis=1)
        # Turning in place never touches anything for a round robot; a turn followed by a short
        # straight lets the robot leave a corner that every arc runs into, instead of stalling.
        ev, ew = turn_then_go(ESCAPE_ANGLES, self.max_omega, ESCAPE_V, self.acc_omega, steps, SIM_STEP)
        return np.vstack([v_t, ev]), np.vstack([w_t, ew])

    # -- one control step -------------------------------------------------------------
    def compute(self, pose: Pose2, speed: Twist2, path: np.ndarray, scan_points: np.ndarray,
                costmap: Costmap | None, dt: float) -> Twist2:
        local = path_in_base(pose, path)
        reach = self.max_v * self.sim_time + FORWARD_POINT + PATH_SLACK
        pts, s = _local_path(local, reach)
        offset = float(np.hypot(*pts[0]))
        if offset > self.max_path_offset:
            raise InvalidPath(f"robot is {offset:.2f} m from its path")
        steps = int(round(self.sim_time / SIM_STEP))
        v_t, w_t = self.targets(steps)
        v0 = min(max(speed.v, self.min_v), self.max_v)
        w0 = min(max(speed.omega, -self.max_omega), self.max_omega)
        traj, twists = rollout(v0, w0, v_t, w_t, self.acc_v, self.dec_v, self.acc_omega, SIM_STEP)
        hit, gap = scan_clearance(traj, scan_points, self.footprint_radius)
        bad = hit | self._costmap_blocked(traj, pose, costmap)
        self.rejected = int(bad.sum())
        if bad.all():
            raise CollisionAhead("every sampled trajectory touches an obstacle")
        score = self._score(traj, pts, s, gap, pose, costmap)
        score[bad] = np.inf
        k = int(np.argmin(score))
        self.escaping = k >= len(v_t) - len(ESCAPE_ANGLES)
        self.best = np.column_stack([pose.transform_points(traj[k, :, :2]), traj[k, :, 2] + pose.theta])
        # The command is the first step towards the chosen target, within this period's window.
        period = max(dt, MIN_PERIOD)
        v = v0 + float(np.clip(v_t[k, 0] - v0, -self.dec_v * period, self.acc_v * period))
        w = w0 + float(np.clip(w_t[k, 0] - w0, -self.acc_omega * period, self.acc_omega * period))
        return Twist2(v, w)

    def _score(self, traj: np.ndarray, pts: np.ndarray, s: np.ndarray, gap: np.ndarray,
               pose: Pose2, costmap: Costmap | None) -> np.ndarray:
        end = traj[:, -1, :]
        progress, path_d = project(end[:, :2], pts, s)
        ahead = end[:, :2] + FORWARD_POINT * np.column_stack([np.cos(end[:, 2]), np.sin(end[:, 2])])
        _, align_d = project(ahead, pts, s)
        clear = np.clip((CLEARANCE_REF - gap) / CLEARANCE_REF, 0.0, 1.0)
        score = -W_PROGRESS * progress + W_PATH * path_d + W_ALIGN * align_d + W_CLEARANCE * clear
        if s[-1] > STALL_ZONE:
            # Standing still or turning on the spot is never progress: without this, a robot whose
            # arcs all run into a corner would rather stop than step sideways out of it.
            moved = np.hypot(end[:, 0], end[:, 1])
            score += W_STALL * np.clip(1.0 - moved / STALL_DIST, 0.0, 1.0)
        if costmap is not None and costmap.cost.size:
            score += W_OBSTACLE * self._worst_cost(traj, pose, costmap)
        return score

    @staticmethod
    def _map_xy(traj: np.ndarray, pose: Pose2) -> np.ndarray:
        return pose.transform_points(traj[..., :2].reshape(-1, 2))

    def _costmap_blocked(self, traj: np.ndarray, pose: Pose2, costmap: Costmap | None) -> np.ndarray:
        """(K,) whether a trajectory takes the footprint into (or deeper into) the costmap's inscribed zone."""
        if costmap is None or costmap.cost.size == 0:
            return np.zeros(len(traj), bool)
        k, t = traj.shape[:2]
        rc = costmap.world_to_cell(self._map_xy(traj, pose))
        ok = costmap.inside(rc)
        flat = np.full(len(rc), np.inf, dtype=np.float64)
        flat[ok] = costmap.clearance[rc[ok, 0], rc[ok, 1]]
        # The robot's trail (homing.navigation.trail) takes the padding off cells the costmap then prices below
        # INSCRIBED: the footprint fits there, as the planner's path through them says.
        lifted = np.zeros(len(rc), dtype=bool)
        lifted[ok] = costmap.cost[rc[ok, 0], rc[ok, 1]] < INSCRIBED
        flat[lifted] = np.inf
        clear = flat.reshape(k, t)
        rc0 = costmap.world_to_cell(np.array([pose.x, pose.y]))
        c0 = float(costmap.clearance[rc0[0, 0], rc0[0, 1]]) if costmap.inside(rc0)[0] else math.inf
        r = costmap.inscribed_radius
        # Grazing already (a stale costmap, a localisation jump): only forbid getting closer.
        return np.asarray(((clear < r) & (clear < c0 - DEEPEN_EPS)).any(axis=1))

    def _worst_cost(self, traj: np.ndarray, pose: Pose2, costmap: Costmap) -> np.ndarray:
        k, t = traj.shape[:2]
        c = costmap.cost_at(self._map_xy(traj, pose)).astype(np.float64).reshape(k, t)
        norm = np.where(c == NO_INFORMATION, UNKNOWN_COST, np.minimum(c, MAX_NON_OBSTACLE) / MAX_NON_OBSTACLE)
        return norm.max(axis=1)


CONTROLLERS["dwb"] = DWB
