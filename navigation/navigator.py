"""The navigator: costmap, global planner and local controller plugins behind one ``step`` (Nav2's bt_navigator + servers).

One :class:`Navigator` holds a goal and, every tick, refreshes the costmap
from the grid and the latest scan, replans at a fixed period (or at once
when the path is blocked or lost), runs the controller, checks progress on
odometry, and returns ``(status, Twist2, feedback)``. It never blocks: a
behaviour calls :meth:`Navigator.step` from its ``update`` and writes the
command to ``/cmd_vel``. Failures are typed (the planner's
:class:`~homing.navigation.planner.PlanningError`, the controller's
:class:`~homing.navigation.controller.ControllerError`, :class:`NoProgress`)
and land in ``feedback.error`` so a recovery can choose by cause.

A goal beyond the grid is planned to all the same: the costmap grows to
hold it (the cells beyond the grid unknown, crossed at a cost with the
planner's ``allow_unknown`` as in Nav2) and the path is replanned as the
grid fills in. The costmap keeps the robot's trail (:mod:`homing.navigation.trail`), so it
can always plan back the way it came. A bumper press marks the costmap (see
:mod:`homing.navigation.layers`), backs the robot off ``BUMP_BACKUP`` and
replans around the mark; keep-out zones and bumper marks reach the
controller as points beside the scan's, since the lidar cannot see them.

Progress (Nav2's progress checker) counts turning on the spot a few times
only; a ``map_to_odom`` correction larger than a few centimetres replans at
once, so the path follows the map the robot is now placed in. The controller
checks the last few scans moved to the present by odometry.

Split as Nav2's tree splits it (``ComputePathToPose`` then ``FollowPath``):
:meth:`Navigator.plan_path` plans once on the current costmap, and
:meth:`Navigator.follow` drives along a path it is given, without planning
(:meth:`Navigator.update_path` swaps in a newer one while driving), so the
tree's own replanning branch decides when to plan.

Frames: goal, path and ``pose_in_map`` in ``map``; progress and the motion of
a stale scan measured in ``odom``. Time is the observation's stamp (the
adapter's clock).
"""

from __future__ import annotations

import enum
import math
from collections import deque
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from homing.navigation.controller import (
    CollisionAhead,
    ControllerError,
    InvalidPath,
    make_controller,
)
from homing.navigation.costmap import INSCRIBED, NO_INFORMATION, Costmap, CostmapParams
from homing.navigation.planner import ESCAPE_RADIUS, PlanningError, make_planner, path_length
from homing.navigation.recovery import BackUp, MotionStatus
from homing.robot import Observation, Pose2, Twist2
from homing.robot.frames import wrap_angle
from homing.robot.history import PoseHistory

XY_TOLERANCE = 0.15  # [m] goal reached (Nav2 default 0.25; the dock staging pose wants better)
YAW_TOLERANCE = 0.25  # [rad]
REPLAN_PERIOD = 1.0  # [s] Nav2's default 1 Hz replanning
PLAN_PATIENCE = 2.0  # [s] how long planning may keep failing before the goal fails
BLOCKED_TIMEOUT = 8.0  # [s] stopped by an obstacle in the scan this long: fail
PROGRESS_RADIUS = 0.25  # [m] Nav2 SimpleProgressChecker required_movement_radius (0.5 there)
PROGRESS_TIME = 10.0  # [s] Nav2 movement_time_allowance
PROGRESS_ANGLE = math.pi / 2  # [rad] turning this much on the spot counts as progress…
PROGRESS_TURNS = 2  # …this many times in a row at most (a robot spinning forever makes none)
STATIC_PERIOD = 1.0  # [s] re-read an unchanged grid object at most this often
HEADING_GAIN = 1.5  # [1/s] final in-place rotation: ω = gain·error
HEADING_MIN_OMEGA = 0.3  # [rad/s]
HEADING_MAX_OMEGA = 1.2  # [rad/s]
ODOM_HISTORY = 3.0  # [s] odometry kept to move a stale scan to the present
MAP_JUMP_XY = 0.05  # [m] a map → odom correction this large replans at once (the path was planned in the old map)
MAP_JUMP_YAW = 0.05  # [rad]
GOAL_MARGIN = 0.5  # [m] the costmap spans this much around a goal beyond the grid (room to plan around it)
BUMP_BACKUP = 0.25  # [m] backed off after a bumper press (Nav2's recovery tree backs up 0.30 m)
BUMP_BACKUP_SPEED = 0.1  # [m/s]
BUMP_LIMIT = 5  # bumper presses within one goal before it fails (something unseen keeps getting in the way)
VIRTUAL_RADIUS = 2.0  # [m] keep-out edges and bumper marks this close are handed to the controller
SCAN_MEMORY = 3  # scans (≈ 0.5 s at 5.5 Hz) whose points the controller checks: fills single-scan dropouts


class NavStatus(enum.Enum):
    """Where a navigation goal is."""

    IDLE = "idle"
    RUNNING = "running"
    SUCCEEDED = "succeeded"
    FAILED = "failed"
    CANCELLED = "cancelled"


class NavigationError(Exception):
    """A navigation goal failed for a reason that is neither the planner's nor the controller's."""


class NoProgress(NavigationError):
    """The robot has not moved ``PROGRESS_RADIUS`` in ``PROGRESS_TIME`` (Nav2's progress checker)."""


class TooManyBumps(NavigationError):
    """A bumper fired ``BUMP_LIMIT`` times on the way to one goal: what the lidar cannot see blocks it."""


@dataclass
class NavFeedback:
    """What the navigator reports each step (for leaves, the view and pictures)."""

    goal: Pose2 | None = None
    path: np.ndarray | None = None  # (N, 2) [m], map frame
    distance_remaining: float = math.inf  # [m] along the path
    error: Exception | None = None
    message: str = ""
    replans: int = 0
    recoveries: list[str] = field(default_factory=list)
    bumps: int = 0  # bumper presses during this goal


class Navigator:
    """Costmap + planner + controller chosen by name; see the module doc.

    ``planner``: ``dijkstra``, ``fmm`` or ``astar``; ``controller``: ``rpp`` (with its ``dwb`` fallback) or ``dwb``;
    ``*_params`` go to their constructors. Not thread-safe; one goal at a time.
    """

    path: np.ndarray | None  # (N, 2) [m] in map: the path being followed

    def __init__(self, planner: str = "fmm", controller: str = "rpp",
                 costmap: CostmapParams | None = None,
                 planner_params: dict[str, Any] | None = None,
                 controller_params: dict[str, Any] | None = None,
                 xy_tolerance: float = XY_TOLERANCE, yaw_tolerance: float = YAW_TOLERANCE,
                 replan_period: float = REPLAN_PERIOD, plan_patience: float = PLAN_PATIENCE,
                 blocked_timeout: float = BLOCKED_TIMEOUT, progress_radius: float = PROGRESS_RADIUS,
                 progress_time: float = PROGRESS_TIME) -> None:
        self.costmap = Costmap(costmap)
        self.planner = make_planner(planner, **(planner_params or {}))
        self.controller = make_controller(controller, **(controller_params or {}))
        self.xy_tolerance = xy_tolerance  # [m]
        self.yaw_tolerance = yaw_tolerance  # [rad]
        self.replan_period = replan_period  # [s]
        self.plan_patience = plan_patience  # [s]
        self.blocked_timeout = blocked_timeout  # [s]
        self.progress_radius = progress_radius  # [m]
        self.progress_time = progress_time  # [s]
        self.status = NavStatus.IDLE
        self.feedback = NavFeedback()
        self.goal: Pose2 | None = None
        self.goal_xy_tolerance = xy_tolerance  # [m]
        self.goal_yaw_tolerance = yaw_tolerance  # [rad]
        self._static_key: tuple[Any, ...] | None = None
        self._static_time = -math.inf
        self._scan_stamp: float | None = None
        self._odom = PoseHistory(ODOM_HISTORY)
        self._scans: deque[tuple[float, Pose2, np.ndarray]] = deque(maxlen=SCAN_MEMORY)  # stamp, odom then, points
        self._bump_stamp: float | None = None  # observation whose bumpers were last marked
        self._reset_goal_state()

    # -- goals ---------------------------------------------------------------------------
    def set_goal(self, goal: Pose2, xy_tolerance: float | None = None,
                 yaw_tolerance: float | None = None) -> None:
        """Start navigating to ``goal`` (map frame); ``yaw_tolerance=math.inf`` ignores the heading."""
        self.goal = goal
        self.goal_xy_tolerance = self.xy_tolerance if xy_tolerance is None else xy_tolerance
        self.goal_yaw_tolerance = self.yaw_tolerance if yaw_tolerance is None else yaw_tolerance
        self._reset_goal_state()
        self.status = NavStatus.RUNNING
        self.feedback = NavFeedback(goal=goal, message="navigating")
        # A goal beyond the grid (a user's, or one the map has not reached yet): grow the costmap to it.
        m = GOAL_MARGIN
        self.costmap.require(goal.x - m, goal.y - m, goal.x + m, goal.y + m)

    def follow(self, path: np.ndarray, heading: float = math.nan, xy_tolerance: float | None = None,
               yaw_tolerance: float | None = None) -> None:
        """Drive along ``path`` ((N, 2) [m] in map) to its last point, then turn to ``heading`` (nan: any); never plans."""
        end = np.asarray(path, dtype=float)[-1]
        self.set_goal(Pose2(float(end[0]), float(end[1]), 0.0), xy_tolerance, yaw_tolerance)
        self._follow_yaw_tolerance = self.goal_yaw_tolerance
        self.update_path(path, heading)

    def update_path(self, path: np.ndarray, heading: float = math.nan) -> None:
        """Follow ``path`` ((N, 2) [m] in map) from now on, to its last point and ``heading``, in place of the last one."""
        self.path = np.asarray(path, dtype=float)[:, :2]
        end = self.path[-1]
        self.goal = Pose2(float(end[0]), float(end[1]), 0.0 if math.isnan(heading) else float(heading))
        self.goal_yaw_tolerance = math.inf if math.isnan(heading) else self._follow_yaw_tolerance
        self.feedback.goal = self.goal
        self._external = True
        self._force_replan = False

    def plan_path(self, pose_in_map: Pose2, goal: Pose2) -> np.ndarray:
        """A path ((N, 2) [m] in map) from ``pose_in_map`` to ``goal`` on the costmap as it is; raises PlanningError."""
        m = GOAL_MARGIN
        self.costmap.require(goal.x - m, goal.y - m, goal.x + m, goal.y + m)
        return self.planner.plan(self.costmap, pose_in_map, goal)

    def path_blocked(self, path: np.ndarray, pose_in_map: Pose2) -> bool:
        """Whether the costmap now puts an obstacle on ``path`` ((N, 2) [m] in map), past the robot's own spot."""
        kept = self.path
        self.path = np.asarray(path, dtype=float)[:, :2]
        try:
            return self._path_blocked(pose_in_map)
        finally:
            self.path = kept

    def set_keepout(self, zones: object) -> None:
        """Keep-out zones in ``map`` (:func:`homing.navigation.layers.parse_keepout` spellings) no path may cross."""
        self.costmap.set_keepout(zones)

    def cancel(self) -> None:
        """Drop the goal; the next step returns CANCELLED and a zero command."""
        if self.status is NavStatus.RUNNING:
            self.status = NavStatus.CANCELLED
            self.feedback.message = "cancelled"
        self.controller.reset()
        self.costmap.release()

    def _reset_goal_state(self) -> None:
        self.path = None
        self._plan_time = -math.inf
        self._plan_fail_since: float | None = None
        self._blocked_since: float | None = None
        self._checkpoint: tuple[float, Pose2] | None = None
        self._turned = 0.0  # [rad] turned on the spot since the checkpoint (odometry)
        self._turn_credits = 0  # times turning counted as progress since the robot last moved
        self._last_odom: Pose2 | None = None
        self._last_stamp: float | None = None
        self._force_replan = True
        self._plan_map_to_odom: Pose2 | None = None
        self._backup: BackUp | None = None  # backing off a bump
        self._external = False  # following a path given by follow(): the caller plans
        self._path_samples: tuple[Any, np.ndarray, np.ndarray] | None = None  # _path_blocked's, for the path it had
        # _path_blocked's samples' flat cells and which lie in the costmap, for the lattice (origin, res, shape) then
        self._path_cells: tuple[Any, np.ndarray, np.ndarray] | None = None
        self._follow_yaw_tolerance = self.yaw_tolerance

    # -- world model -----------------------------------------------------------------------
    def update_costmap(self, obs: Observation, grid: Any, pose_in_map: Pose2,
                       map_to_odom: Pose2 | None = None) -> None:
        """Refresh the static layer from ``grid`` and the obstacle layer from a new scan (idempotent per tick)."""
        self._remember_odom(obs)
        version = getattr(grid, "version", None)
        key = (id(grid), version)
        # A grid with a ``version`` (homing.mapping.grid) says when it changed; anything else is re-read now and then.
        stale = version is None and obs.stamp - self._static_time >= STATIC_PERIOD
        if grid is not None and (key != self._static_key or stale):
            self.costmap.update_static(grid)
            self._static_key, self._static_time = key, obs.stamp
        if self.costmap.cost.size:
            # Where the robot's centre is, it fits: the way back through a door the map redraws narrower later.
            self.costmap.mark_trail(pose_in_map)
        if self.costmap.cost.size and obs.stamp != self._bump_stamp:
            # Bumper presses mark where the robot is now; the marks fade after their memory.
            self._bump_stamp = obs.stamp
            self.costmap.mark_bumpers(obs.bumpers, pose_in_map, obs.stamp)
            self.costmap.forget_bumps(obs.stamp)
        scan = obs.scan
        if scan is not None and scan.stamp != self._scan_stamp and self.costmap.cost.size:
            self._scan_stamp = scan.stamp
            odom_then = self._odom_at(scan.stamp)
            if map_to_odom is not None:
                pose_then = map_to_odom.compose(odom_then)
            else:
                pose_then = pose_in_map.compose(obs.odom.pose.between(odom_then))
            self.costmap.update_scan(scan, pose_then)

    def scan_points_now(self, obs: Observation) -> np.ndarray:
        """(M, 2) [m] the last ``SCAN_MEMORY`` scans' end points in base_link *now*, moved by odometry since each scan.

        Several scans, not one: a ray the lidar drops (grazing incidence,
        noise) leaves a gap in one scan that a disc could slip through; the
        previous scans fill it. They are at most ~0.5 s old, so odometry's
        drift over that span is millimetres.
        """
        if obs.scan is None:
            return np.zeros((0, 2))
        self._remember_odom(obs)
        if not self._scans or self._scans[-1][0] != obs.scan.stamp:
            self._scans.append((obs.scan.stamp, self._odom_at(obs.scan.stamp), obs.scan.points()))
        now = obs.odom.pose
        return np.vstack([now.between(then).transform_points(pts) for _, then, pts in self._scans])

    def obstacle_points_now(self, obs: Observation, pose_in_map: Pose2) -> np.ndarray:
        """(M, 2) [m] in base_link: :meth:`scan_points_now` plus the nearby keep-out edges and bumper marks."""
        pts = self.scan_points_now(obs)
        unseen = self.costmap.virtual_points(pose_in_map, VIRTUAL_RADIUS)
        if len(unseen) == 0:
            return pts
        return np.vstack([pts, pose_in_map.inverse().transform_points(unseen)])

    def _remember_odom(self, obs: Observation) -> None:
        if not len(self._odom) or self._odom.samples[-1][0] < obs.stamp:
            self._odom.add(obs.stamp, obs.odom.pose)

    def _odom_at(self, stamp: float) -> Pose2:
        # Interpolated between the ticks either side of the stamp, not the tick before it: turning on the spot at
        # 1.8 rad/s, half a tick is 5°, and a scan drawn 5° off marked walls 10 cm into the room (office:1, 290 s:
        # the path through a door blocked and free every other scan, the robot turning back and forth for 77 s).
        return self._odom.at(stamp) if len(self._odom) else Pose2()

    # -- the step ----------------------------------------------------------------------------
    def step(self, obs: Observation, grid: Any, pose_in_map: Pose2,
             map_to_odom: Pose2 | None = None) -> tuple[NavStatus, Twist2, NavFeedback]:
        """One control cycle at ``obs.stamp``: returns the status, the command (base_link) and feedback."""
        self.update_costmap(obs, grid, pose_in_map, map_to_odom)
        if self.status is not NavStatus.RUNNING or self.goal is None:
            return self.status, Twist2(), self.feedback
        now = obs.stamp
        dt = 0.1 if self._last_stamp is None else max(now - self._last_stamp, 1e-3)
        self._last_stamp = now
        fb = self.feedback
        fb.error = None
        # A bumper fired: something the lidar cannot see. It is marked; back off, then plan around it.
        if obs.bumpers.any() and self._backup is None:
            fb.bumps += 1
            if fb.bumps >= BUMP_LIMIT:
                return self._fail(TooManyBumps(f"a bumper fired {fb.bumps} times on the way"))
            self._backup = BackUp(BUMP_BACKUP, BUMP_BACKUP_SPEED)
            self._backup.start(now, obs.odom.pose)
            self.controller.reset()
        if self._backup is not None:
            state, cmd = self._backup.step(now, obs.odom.pose, self.obstacle_points_now(obs, pose_in_map))
            if state is MotionStatus.RUNNING:
                fb.message = "bumped: backing off"
                return NavStatus.RUNNING, cmd, fb
            self._backup, self._force_replan = None, True
            self._checkpoint = None  # backing off is not a lack of progress
        # Arrived?
        dist = pose_in_map.distance_to(self.goal)
        if dist <= self.goal_xy_tolerance:
            return self._final_heading(pose_in_map)
        # Progress, on odometry so a map correction is not mistaken for motion.
        if self._no_progress(now, obs.odom.pose):
            return self._fail(NoProgress(f"moved less than {self.progress_radius} m in {self.progress_time:.0f} s"))
        # A map correction moved the robot against the map: the old path may now cut a wall.
        if map_to_odom is not None and self._plan_map_to_odom is not None:
            jump = self._plan_map_to_odom.between(map_to_odom)
            if math.hypot(jump.x, jump.y) > MAP_JUMP_XY or abs(jump.theta) > MAP_JUMP_YAW:
                self._force_replan = True
        # Plan (unless the caller hands the path over, as Nav2's FollowPath is handed one).
        if self._external:
            pass
        elif self._force_replan or now - self._plan_time >= self.replan_period or self._path_blocked(pose_in_map):
            try:
                self.path = self.planner.plan(self.costmap, pose_in_map, self.goal)
                self._plan_time, self._plan_fail_since, self._force_replan = now, None, False
                self._plan_map_to_odom = map_to_odom
                fb.replans += 1
            except PlanningError as err:
                if self._plan_fail_since is None:
                    self._plan_fail_since = now
                if now - self._plan_fail_since >= self.plan_patience:
                    return self._fail(err)
                fb.error, fb.message = err, f"planning failed: {err}"
                if self.path is None:
                    return NavStatus.RUNNING, Twist2(), fb
                # Otherwise keep following the previous path while planning recovers.
        assert self.path is not None
        fb.path = self.path
        fb.distance_remaining = path_length(np.vstack([[pose_in_map.x, pose_in_map.y], self.path[1:]]))
        # Control.
        try:
            cmd = self.controller.compute(pose_in_map, obs.odom.twist, self.path, self.obstacle_points_now(obs, pose_in_map),
                                          self.costmap, dt)
            self._blocked_since = None
            fb.message = f"{dist:.2f} m to go"
        except CollisionAhead as err:
            self._blocked_since = self._blocked_since if self._blocked_since is not None else now
            self._force_replan = True  # the obstacle is in the costmap now: go around it
            if now - self._blocked_since >= self.blocked_timeout:
                return self._fail(err)
            fb.error, fb.message = err, "obstacle ahead: stopped"
            return NavStatus.RUNNING, Twist2(), fb
        except InvalidPath as err:
            self._force_replan = True
            fb.error, fb.message = err, str(err)
            return NavStatus.RUNNING, Twist2(), fb
        except ControllerError as err:
            return self._fail(err)
        return NavStatus.RUNNING, cmd, fb

    def _no_progress(self, now: float, odom: Pose2) -> bool:
        """Nav2's SimpleProgressChecker, plus turning on the spot counted as progress ``PROGRESS_TURNS`` times at most."""
        if self._last_odom is not None:
            self._turned += abs(wrap_angle(odom.theta - self._last_odom.theta))
        self._last_odom = odom
        if self._checkpoint is None or self._checkpoint[1].distance_to(odom) >= self.progress_radius:
            self._checkpoint, self._turned, self._turn_credits = (now, odom), 0.0, 0
        elif self._turned >= PROGRESS_ANGLE and self._turn_credits < PROGRESS_TURNS:
            # Turning to face a new path or to escape a corner is work towards the goal, but only so often.
            self._checkpoint, self._turned = (now, self._checkpoint[1]), 0.0
            self._turn_credits += 1
        return now - self._checkpoint[0] > self.progress_time

    def _final_heading(self, pose: Pose2) -> tuple[NavStatus, Twist2, NavFeedback]:
        assert self.goal is not None
        err = wrap_angle(self.goal.theta - pose.theta)
        if not math.isfinite(self.goal_yaw_tolerance) or abs(err) <= self.goal_yaw_tolerance:
            self.status = NavStatus.SUCCEEDED
            self.feedback.message = "goal reached"
            self.feedback.distance_remaining = 0.0
            self.controller.reset()
            self.costmap.release()
            return self.status, Twist2(), self.feedback
        w = float(np.clip(HEADING_GAIN * err, -HEADING_MAX_OMEGA, HEADING_MAX_OMEGA))
        w = math.copysign(max(abs(w), HEADING_MIN_OMEGA), err)
        self.feedback.message = "turning to the goal's heading"
        return NavStatus.RUNNING, Twist2(0.0, w), self.feedback

    def _path_blocked(self, pose: Pose2) -> bool:
        """Whether the costmap now puts an obstacle on the path ahead (sampled every half cell).

        The stretch within ``ESCAPE_RADIUS`` of the robot is not checked: a robot
        grazing a wall sits in inscribed cells, and the planner lets it out.
        """
        if self.path is None or len(self.path) < 2:
            return self.path is None
        costmap = self.costmap
        key = (id(self.path), costmap.resolution)
        if self._path_samples is None or self._path_samples[0] != key or self._path_samples[1] is not self.path:
            # Sampled once per path (a path is replanned about once a second; this runs every tick).
            seg = np.diff(self.path, axis=0)
            n = np.maximum(1, np.ceil(np.hypot(*seg.T) / (0.5 * costmap.resolution))).astype(int)
            samples = np.concatenate([a + np.linspace(0, 1, k, endpoint=False)[:, None] * d
                                      for a, d, k in zip(self.path[:-1], seg, n, strict=True)])
            self._path_samples = (key, self.path, samples)
            self._path_cells = None
        pts = self._path_samples[2]
        # The samples' cells, found once per path and costmap lattice (the costs under them are read each tick).
        lattice = (costmap.origin, costmap.resolution, costmap.shape)
        if self._path_cells is None or self._path_cells[0] != lattice:
            rc = costmap.world_to_cell(pts)
            inside = costmap.inside(rc)
            self._path_cells = (lattice, np.where(inside, rc[:, 0] * costmap.shape[1] + rc[:, 1], 0), inside)
        _, cells, inside = self._path_cells
        cost = np.where(inside, costmap.cost.reshape(-1).take(cells), NO_INFORMATION)  # as Costmap.cost_at
        blocked = (cost >= INSCRIBED) & (np.hypot(pts[:, 0] - pose.x, pts[:, 1] - pose.y) > ESCAPE_RADIUS)
        if getattr(self.planner, "allow_unknown", False):
            blocked &= cost != NO_INFORMATION  # paths into the unknown are the plan, not a blockage
        return bool(np.any(blocked))

    def _fail(self, err: Exception) -> tuple[NavStatus, Twist2, NavFeedback]:
        self.status = NavStatus.FAILED
        self.feedback.error = err
        self.feedback.message = f"{type(err).__name__}: {err}"
        self.controller.reset()
        self.costmap.release()
        return self.status, Twist2(), self.feedback
