"""Motion leaves: navigate to a pose, spin, back up, clear the costmap (Nav2's BT action nodes).

Thin by design: each reads the blackboard, calls :mod:`homing.navigation`
(the navigator of the ``navigation`` service at ``/nav/navigator``, or a
recovery motion), and writes ``/cmd_vel``. Long ones derive from
:class:`~homing.behaviours.base.LongAction`, which owns the deadline and
cancellation; failures carry a typed ``failure_reason`` (``no_path``,
``goal_occupied``, ``start_occupied``, ``no_progress``, ``blocked``, ``bumped``, …) so a
recovery node can choose by cause: the leaves also write it to
``failure_key`` (default ``/nav/failure``; None while running or after a
success), so a recovery branch can test it with ``CheckBlackboard``.
"""

from __future__ import annotations

import math
from typing import Any, ClassVar

from homing.behaviours.base import (
    TIMEOUT_PARAM,
    HomingBehaviour,
    LongAction,
)
from homing.behaviours.keys import (
    CMD_VEL_KEY,
    GRID_KEY,
    MAP_TO_ODOM_KEY,
    NAVIGATOR_KEY,
    OBSERVATION_KEY,
    POSE_KEY,
)
from homing.behaviours.registry import Param, register
from homing.navigation.controller import CollisionAhead, InvalidPath
from homing.navigation.navigator import NavStatus, NoProgress, TooManyBumps
from homing.navigation.planner import GoalOccupied, NoPathFound, StartOccupied
from homing.navigation.recovery import BackUp as BackUpMotion
from homing.navigation.recovery import MotionStatus, Recovery
from homing.navigation.recovery import Spin as SpinMotion
from homing.robot import Pose2
from py_trees.common import Status

FAILURE_KEY = "/nav/failure"
FAILURE_PARAM = Param("failure_key", str, FAILURE_KEY, doc="blackboard key the typed failure reason is written to")

_REASONS: tuple[tuple[type, str], ...] = (
    (StartOccupied, "start_occupied"), (GoalOccupied, "goal_occupied"), (NoPathFound, "no_path"),
    (NoProgress, "no_progress"), (CollisionAhead, "blocked"), (InvalidPath, "invalid_path"),
    (TooManyBumps, "bumped"),
)


def failure_reason(error: Exception | None) -> str:
    """The typed cause of a navigation failure, as ``LongAction.failure_reason`` spells it."""
    for cls, reason in _REASONS:
        if isinstance(error, cls):
            return reason
    return "failed"


class _ReportsFailure(LongAction):
    """A long action that publishes its ``failure_reason`` at ``failure_key`` for recovery branches."""

    failure_key: str = FAILURE_KEY

    def initialise(self) -> None:
        self.write(self.failure_key, None)
        super().initialise()

    def on_failure(self) -> Status:
        self.write(self.failure_key, self.failure_reason)
        return Status.FAILURE


class _Navigating(_ReportsFailure):
    """Drives with the navigation service's navigator (``self.navigator``, taken in ``on_start``) one step a tick."""

    navigator: Any = None

    def step_navigator(self) -> Status:
        """One step of ``self.navigator`` on this tick's observation and map pose: drive, report, map the status."""
        obs, pose = self.observation(), self.read(POSE_KEY)
        if obs is None or pose is None:
            self.feedback_message = "waiting for the map pose"
            return Status.RUNNING
        status, cmd, fb = self.navigator.step(obs, self.read(GRID_KEY), pose, self.read(MAP_TO_ODOM_KEY))
        self.drive(cmd.v, cmd.omega)
        self.feedback_message = fb.message
        if status is NavStatus.SUCCEEDED:
            return Status.SUCCESS
        if status in (NavStatus.FAILED, NavStatus.CANCELLED):
            return self.fail(failure_reason(fb.error), fb.message)
        return Status.RUNNING

    def on_cancel(self) -> None:
        if self.navigator is not None:
            self.navigator.cancel()


@register("NavigateToPose")
class NavigateToPose(_Navigating):
    """Drive to a goal pose in ``map`` with the navigation service's planner and controller; RUNNING while driving.

    The goal is ``x``, ``y``, ``theta`` when given, otherwise the pose at
    ``goal_key`` (a Pose2 or ``[x, y, theta]``). ``theta`` nan: any final heading.
    """

    PARAMS: ClassVar[tuple[Param, ...]] = (
        Param("x", float, math.nan, "m", "goal x in map (nan: read goal_key)"),
        Param("y", float, math.nan, "m", "goal y in map"),
        Param("theta", float, math.nan, "rad", "goal heading in map (nan: any)"),
        Param("goal_key", str, "/nav/goal", doc="blackboard key holding a Pose2 goal when x/y are not given"),
        Param("xy_tolerance", float, 0.15, "m", "reached within this distance", above=0.0),
        Param("yaw_tolerance", float, 0.25, "rad", "and this heading error", above=0.0),
        FAILURE_PARAM,
        TIMEOUT_PARAM,
    )
    READS: ClassVar[tuple[str, ...]] = (OBSERVATION_KEY, NAVIGATOR_KEY, GRID_KEY, POSE_KEY, MAP_TO_ODOM_KEY, "$goal_key")
    WRITES = (CMD_VEL_KEY, "$failure_key")

    def __init__(self, name: str, x: float = math.nan, y: float = math.nan, theta: float = math.nan,
                 goal_key: str = "/nav/goal", xy_tolerance: float = 0.15, yaw_tolerance: float = 0.25,
                 timeout: float = 0.0, failure_key: str = FAILURE_KEY, **kwargs: Any) -> None:
        self.goal_key = goal_key
        self.failure_key = failure_key
        super().__init__(name, timeout=timeout, **kwargs)
        self.x, self.y, self.theta = x, y, theta
        self.xy_tolerance, self.yaw_tolerance = xy_tolerance, yaw_tolerance
        self.navigator: Any = None

    def on_start(self) -> Status | None:
        self.navigator = self.read(NAVIGATOR_KEY)
        if self.navigator is None:
            return self.fail("no_navigator", "no navigation service (add 'navigation' to services)")
        if math.isnan(self.x) or math.isnan(self.y):
            from homing.behaviours.paths import as_pose  # paths builds on this module

            goal = as_pose(self.read(self.goal_key))
            if goal is None:
                return self.fail("no_goal", f"nothing at {self.goal_key}")
        else:
            goal = Pose2(self.x, self.y, 0.0 if math.isnan(self.theta) else self.theta)
        free_heading = math.isnan(self.theta) and not (math.isnan(self.x) or math.isnan(self.y))
        self.navigator.set_goal(goal, self.xy_tolerance, math.inf if free_heading else self.yaw_tolerance)
        return None

    def on_running(self) -> Status:
        return self.step_navigator()


@register("NavigateThroughPoses")
class NavigateThroughPoses(NavigateToPose):
    """Drive through the goal poses at ``goals_key`` in order, ending at the last: Nav2's ``NavigateThroughPoses``.

    The navigation service's navigator drives to each pose in turn; every
    pose but the last counts as passed once the robot is within
    ``pass_radius`` [m] of it, whatever its heading, and the robot goes on to
    the next one without turning to it (Nav2's through-poses tree drops
    goals passed within such a radius, ``RemovePassedGoals``). The last pose
    must be reached within ``xy_tolerance`` [m] and ``yaw_tolerance`` [rad].
    Poses are Pose2 or ``[x, y, theta]`` in ``map``. FAILS with the typed
    reason of the leg that failed (``no_path``, ``blocked``, …), or
    ``no_goal`` for an empty list; the list is read once, when it starts.
    """

    PARAMS: ClassVar[tuple[Param, ...]] = (
        Param("goals_key", str, "/goals", doc="blackboard key of the list of goal poses"),
        Param("pass_radius", float, 0.5, "m", "a pose before the last is passed this close", above=0.0),
        Param("xy_tolerance", float, 0.15, "m", "the last pose is reached within this distance", above=0.0),
        Param("yaw_tolerance", float, 0.25, "rad", "and this heading error", above=0.0),
        FAILURE_PARAM,
        TIMEOUT_PARAM,
    )
    READS = (OBSERVATION_KEY, NAVIGATOR_KEY, GRID_KEY, POSE_KEY, MAP_TO_ODOM_KEY, "$goals_key")

    def __init__(self, name: str, goals_key: str = "/goals", pass_radius: float = 0.5, xy_tolerance: float = 0.15,
                 yaw_tolerance: float = 0.25, timeout: float = 0.0, failure_key: str = FAILURE_KEY) -> None:  # fmt: skip
        self.goals_key = goals_key
        super().__init__(name, goal_key=goals_key, xy_tolerance=xy_tolerance, yaw_tolerance=yaw_tolerance,
                         timeout=timeout, failure_key=failure_key)  # fmt: skip
        self.pass_radius = pass_radius
        self.goals: list[Pose2] = []
        self.leg = 0

    def on_start(self) -> Status | None:
        from homing.behaviours.paths import as_poses  # paths builds on this module

        self.navigator = self.read(NAVIGATOR_KEY)
        if self.navigator is None:
            return self.fail("no_navigator", "no navigation service (add 'navigation' to services)")
        self.goals = as_poses(self.read(self.goals_key)) or []
        if not self.goals:
            return self.fail("no_goal", f"no goal poses at {self.goals_key}")
        self.leg = 0
        self._start_leg()
        return None

    def _start_leg(self) -> None:
        last = self.leg == len(self.goals) - 1
        self.navigator.set_goal(self.goals[self.leg], self.xy_tolerance if last else self.pass_radius,
                                self.yaw_tolerance if last else math.inf)  # fmt: skip

    def on_running(self) -> Status:
        status = self.step_navigator()
        if status == Status.SUCCESS and self.leg < len(self.goals) - 1:
            self.leg += 1
            self._start_leg()
            self.feedback_message = f"passed pose {self.leg} of {len(self.goals)}"
            return Status.RUNNING
        return status


class _MotionLeaf(_ReportsFailure):
    """Runs one :mod:`homing.navigation.recovery` motion on odometry and the scan until it ends."""

    READS = (OBSERVATION_KEY, NAVIGATOR_KEY)
    WRITES = (CMD_VEL_KEY, "$failure_key")

    def make(self) -> Recovery:
        raise NotImplementedError

    def on_start(self) -> Status | None:
        obs = self.observation()
        if obs is None:
            return self.fail("no_observation")
        self.motion = self.make()
        self.motion.start(obs.stamp, obs.odom.pose)
        return None

    def on_running(self) -> Status:
        obs = self.observation()
        if obs is None:  # the runner writes one every tick; only a misconfigured tree gets here
            return self.fail("no_observation")
        nav = self.read(NAVIGATOR_KEY)
        pts = nav.scan_points_now(obs) if nav is not None else (obs.scan.points() if obs.scan else None)
        status, cmd = self.motion.step(obs.stamp, obs.odom.pose, pts)
        self.drive(cmd.v, cmd.omega)
        self.feedback_message = self.motion.message
        if status is MotionStatus.SUCCEEDED:
            return Status.SUCCESS
        if status is MotionStatus.FAILED:
            return self.fail("blocked" if "obstacle" in self.motion.message else "timed_out", self.motion.message)
        return Status.RUNNING


@register("Spin")
class Spin(_MotionLeaf):
    """Turn in place by ``angle`` (a full turn refreshes the costmap all round), measured on odometry."""

    PARAMS = (
        Param("angle", float, 2 * math.pi, "rad", "relative turn, counter-clockwise positive"),
        Param("omega", float, 1.0, "rad/s", "turning speed", above=0.0),
        FAILURE_PARAM,
        TIMEOUT_PARAM,
    )

    def __init__(self, name: str, angle: float = 2 * math.pi, omega: float = 1.0, timeout: float = 0.0,
                 failure_key: str = FAILURE_KEY, **kwargs: Any) -> None:
        self.failure_key = failure_key
        super().__init__(name, timeout=timeout, **kwargs)
        self.angle, self.omega = angle, omega

    def make(self) -> Recovery:
        return SpinMotion(self.angle, self.omega)


@register("BackUp")
class BackUp(_MotionLeaf):
    """Drive straight backwards ``distance`` at ``speed``; fails rather than touch what the scan sees behind."""

    PARAMS = (
        Param("distance", float, 0.15, "m", "how far to back up", above=0.0),
        Param("speed", float, 0.05, "m/s", "backing speed", above=0.0),
        FAILURE_PARAM,
        TIMEOUT_PARAM,
    )

    def __init__(self, name: str, distance: float = 0.15, speed: float = 0.05, timeout: float = 0.0,
                 failure_key: str = FAILURE_KEY, **kwargs: Any) -> None:
        self.failure_key = failure_key
        super().__init__(name, timeout=timeout, **kwargs)
        self.distance, self.speed = distance, speed

    def make(self) -> Recovery:
        return BackUpMotion(self.distance, self.speed)


@register("ClearCostmap")
class ClearCostmap(HomingBehaviour):
    """Empty the navigation costmap's obstacle layer (the map stays); SUCCESS at once, FAILURE without a navigator."""

    READS = (NAVIGATOR_KEY,)

    def update(self) -> Status:
        nav = self.read(NAVIGATOR_KEY)
        if nav is None:
            self.feedback_message = "no navigation service"
            return Status.FAILURE
        nav.costmap.clear()
        self.feedback_message = "costmap cleared"
        return Status.SUCCESS
