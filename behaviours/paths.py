"""Path leaves, navigation split as Nav2's trees split it: plan (``ComputePathToPose``), then follow (``FollowPath``).

``NavigateToPose`` plans and follows in one leaf (the navigator replans
itself). These leaves hand the decision of *when* to plan to the tree, so
that a Nav2 navigator tree (``pipeline_sequence`` of a
``rate_controller``-ed planner and a controller) runs as written: the
planner writes a path to the blackboard, the follower picks up each new
path while it drives. Both use the ``navigation`` service's navigator
(``/nav/navigator``: its costmap, planner and controller plugins) and write
their typed failure reason to ``failure_key`` (Nav2's ``error_code_id``).

A path on the blackboard is an (N, 3) float64 array in ``map``: x [m],
y [m], and in the last row's third column the heading wanted at the end
[rad] (nan: any), as Nav2's ``nav_msgs/Path`` carries the goal's
orientation. A pose is a :class:`homing.robot.Pose2` or ``[x, y, theta]``
(a mission's ``blackboard:`` entry), a list of goals a list of them.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from homing.behaviours.base import TIMEOUT_PARAM, HomingBehaviour
from homing.behaviours.keys import (
    CMD_VEL_KEY,
    GRID_KEY,
    MAP_TO_ODOM_KEY,
    NAVIGATOR_KEY,
    OBSERVATION_KEY,
    POSE_KEY,
)
from homing.behaviours.motion import (
    FAILURE_KEY,
    FAILURE_PARAM,
    _Navigating,
    _ReportsFailure,
    failure_reason,
)
from homing.behaviours.registry import Param, register
from homing.navigation.costmap import INSCRIBED, LETHAL, NO_INFORMATION
from homing.navigation.planner import PlanningError
from homing.robot import Pose2
from py_trees.common import Status

GOAL_KEY = "/goal"  # Nav2's {goal}: written by the application (a mission's blackboard: entry)
PATH_KEY = "/path"  # Nav2's {path}


def as_pose(value: Any) -> Pose2 | None:
    """A Pose2 from a Pose2 or ``[x, y]`` / ``[x, y, theta]`` (map frame, metres and radians); None otherwise."""
    if isinstance(value, Pose2):
        return value
    if isinstance(value, (list, tuple, np.ndarray)) and len(value) in (2, 3):
        try:
            numbers = [float(v) for v in value]
        except (TypeError, ValueError):
            return None
        return Pose2(numbers[0], numbers[1], numbers[2] if len(numbers) == 3 else 0.0)
    return None


def as_poses(value: Any) -> list[Pose2] | None:
    """A list of poses (see :func:`as_pose`), or None if ``value`` is not one."""
    if not isinstance(value, (list, tuple)):
        return None
    poses = [as_pose(v) for v in value]
    return None if any(p is None for p in poses) else [p for p in poses if p is not None]


def with_heading(xy: np.ndarray, heading: float) -> np.ndarray:
    """An (N, 2) path as the (N, 3) blackboard path: the wanted end heading in the last row (nan elsewhere)."""
    out = np.full((len(xy), 3), math.nan)
    out[:, :2] = xy
    out[-1, 2] = heading
    return out


class _Planning(_ReportsFailure):
    """Plans on the navigation service's costmap from ``/map/pose`` in one tick and writes the path."""

    path_key: str = PATH_KEY

    def plan_through(self, goals: list[Pose2]) -> Status | None:
        navigator, pose = self.read(NAVIGATOR_KEY), self.read(POSE_KEY)
        if navigator is None:
            return self.fail("no_navigator", "no navigation service (add 'navigation' to services)")
        if pose is None:
            return self.fail("no_pose", f"no robot pose at {POSE_KEY} yet")
        pieces: list[np.ndarray] = []
        start = pose
        try:
            for goal in goals:
                piece = navigator.plan_path(start, goal)
                pieces.append(piece if not pieces else piece[1:])
                start = goal
        except PlanningError as err:
            return self.fail(failure_reason(err), f"{type(err).__name__}: {err}")
        path = np.vstack(pieces)
        self.write(self.path_key, with_heading(path, goals[-1].theta))
        self.feedback_message = f"{len(path)} points to ({goals[-1].x:.2f}, {goals[-1].y:.2f})"
        return Status.SUCCESS


@register("ComputePathToPose")
class ComputePathToPose(_Planning):
    """Plan a path from the robot to the pose at ``goal_key`` and write it to ``path_key``; one tick: Nav2's ``ComputePathToPose``.

    SUCCESS with the path written, or FAILURE with a typed reason at
    ``failure_key`` (``no_path``, ``start_occupied``, ``goal_occupied``,
    ``no_goal``). The planner is the navigation service's.
    """

    PARAMS = (
        Param("goal_key", str, GOAL_KEY, doc="blackboard key of the goal pose (Pose2 or [x, y, theta], map)"),
        Param("path_key", str, PATH_KEY, doc="blackboard key the path is written to"),
        FAILURE_PARAM,
    )
    READS = (NAVIGATOR_KEY, POSE_KEY, "$goal_key")
    WRITES = ("$path_key", "$failure_key")

    def __init__(self, name: str, goal_key: str = GOAL_KEY, path_key: str = PATH_KEY, failure_key: str = FAILURE_KEY):
        self.goal_key, self.path_key, self.failure_key = goal_key, path_key, failure_key
        super().__init__(name)

    def on_start(self) -> Status | None:
        goal = as_pose(self.read(self.goal_key))
        if goal is None:
            return self.fail("no_goal", f"no goal pose at {self.goal_key}")
        return self.plan_through([goal])


@register("ComputePathThroughPoses")
class ComputePathThroughPoses(_Planning):
    """Plan through the poses at ``goals_key`` in order and write one path to ``path_key``: Nav2's ``ComputePathThroughPoses``.

    Each leg is planned from the end of the previous one; one tick. FAILURE
    with a typed reason as ``ComputePathToPose``, ``no_goal`` for an empty list.
    """

    PARAMS = (
        Param("goals_key", str, "/goals", doc="blackboard key of the list of goal poses (map)"),
        Param("path_key", str, PATH_KEY, doc="blackboard key the path is written to"),
        FAILURE_PARAM,
    )
    READS = (NAVIGATOR_KEY, POSE_KEY, "$goals_key")
    WRITES = ("$path_key", "$failure_key")

    def __init__(self, name: str, goals_key: str = "/goals", path_key: str = PATH_KEY, failure_key: str = FAILURE_KEY):
        self.goals_key, self.path_key, self.failure_key = goals_key, path_key, failure_key
        super().__init__(name)

    def on_start(self) -> Status | None:
        goals = as_poses(self.read(self.goals_key))
        if not goals:
            return self.fail("no_goal", f"no goal poses at {self.goals_key}")
        return self.plan_through(goals)


@register("FollowPath")
class FollowPath(_Navigating):
    """Drive along the path at ``path_key`` with the navigation service's controller; RUNNING while driving: Nav2's ``FollowPath``.

    Never plans: a newer path written to ``path_key`` while it drives (the
    tree's replanning branch) is taken up at once, as Nav2's controller
    server takes an updated path. SUCCESS at the path's end within the
    tolerances (and its end heading, when it has one); FAILURE with a typed
    reason (``blocked``, ``no_progress``, ``invalid_path``, ``bumped``,
    ``timed_out``, ``no_path`` when there is none).
    """

    PARAMS = (
        Param("path_key", str, PATH_KEY, doc="blackboard key of the path to follow"),
        Param("xy_tolerance", float, 0.15, "m", "reached within this distance of the path's end"),
        Param("yaw_tolerance", float, 0.25, "rad", "and this heading error, when the path has an end heading"),
        FAILURE_PARAM,
        TIMEOUT_PARAM,
    )
    READS = (OBSERVATION_KEY, NAVIGATOR_KEY, GRID_KEY, POSE_KEY, MAP_TO_ODOM_KEY, "$path_key")
    WRITES = (CMD_VEL_KEY, "$failure_key")

    def __init__(self, name: str, path_key: str = PATH_KEY, xy_tolerance: float = 0.15, yaw_tolerance: float = 0.25,
                 failure_key: str = FAILURE_KEY, timeout: float = 0.0) -> None:  # fmt: skip
        self.path_key, self.failure_key = path_key, failure_key
        super().__init__(name, timeout=timeout)
        self.xy_tolerance, self.yaw_tolerance = xy_tolerance, yaw_tolerance
        self.path: Any = None

    @staticmethod
    def _split(path: Any) -> tuple[np.ndarray, float] | None:
        array = np.asarray(path, dtype=float) if path is not None else None
        if array is None or array.ndim != 2 or array.shape[1] not in (2, 3) or len(array) < 1:
            return None
        return array[:, :2], float(array[-1, 2]) if array.shape[1] == 3 else math.nan

    def on_start(self) -> Status | None:
        self.navigator = self.read(NAVIGATOR_KEY)
        if self.navigator is None:
            return self.fail("no_navigator", "no navigation service (add 'navigation' to services)")
        self.path = self.read(self.path_key)
        split = self._split(self.path)
        if split is None:
            return self.fail("no_path", f"no path at {self.path_key}")
        self.navigator.follow(split[0], split[1], self.xy_tolerance, self.yaw_tolerance)
        return None

    def on_running(self) -> Status:
        latest = self.read(self.path_key)
        if latest is not self.path:
            self.path = latest
            split = self._split(latest)
            if split is not None:
                self.navigator.update_path(*split)
        return self.step_navigator()


@register("RemovePassedGoals")
class RemovePassedGoals(HomingBehaviour):
    """Drop the goals at the head of the list the robot is within ``radius`` of (never the last): Nav2's ``RemovePassedGoals``.

    Reads the list at ``input_key``, writes what is left to ``output_key``
    (they may be the same key); SUCCESS, or FAILURE without a robot pose.
    """

    PARAMS = (
        Param("input_key", str, "/goals", doc="blackboard key of the list of goal poses"),
        Param("output_key", str, "/goals", doc="blackboard key the remaining goals are written to"),
        Param("radius", float, 0.5, "m", "a goal this close to the robot counts as passed"),
    )
    READS = (POSE_KEY, "$input_key")
    WRITES = ("$output_key",)

    def __init__(self, name: str, input_key: str = "/goals", output_key: str = "/goals", radius: float = 0.5):
        self.input_key, self.output_key = input_key, output_key
        super().__init__(name)
        self.radius = radius

    def update(self) -> Status:
        goals, pose = as_poses(self.read(self.input_key)), self.read(POSE_KEY)
        if goals is None or pose is None:
            self.feedback_message = f"no goal list at {self.input_key}" if goals is None else "no robot pose"
            return Status.FAILURE
        while len(goals) > 1 and math.hypot(goals[0].x - pose.x, goals[0].y - pose.y) <= self.radius:
            goals.pop(0)
        self.write(self.output_key, goals)
        self.feedback_message = f"{len(goals)} goals left"
        return Status.SUCCESS


@register("RemoveInCollisionGoals")
class RemoveInCollisionGoals(HomingBehaviour):
    """Drop the goals that lie on costly cells of the costmap, keep the others in order: Nav2's ``RemoveInCollisionGoals``.

    A goal is kept when its cost is below ``cost_threshold`` (Nav2's 0..255
    scale: 253 inscribed, 254 lethal), or when it is unknown (255) and
    ``consider_unknown_as_obstacle`` is false; a goal outside the costmap is
    unknown. Its cost is the navigation costmap's at its (x, y) [m, ``map``]
    (``use_footprint`` false: Nav2's point cost), or with ``use_footprint``
    (Nav2's default) the cost of the robot's round footprint there: lethal
    where the centre's is inscribed (the rim touches a lethal cell), the
    centre's otherwise. With the default threshold 254, goals where the
    robot would touch an obstacle are dropped, as in Nav2.
    Writes the goals kept to ``output_key`` (an empty list if none is) and
    SUCCEEDS; FAILS without a navigation service or a goal list, as Nav2
    fails when its costmap service does not answer. Use it before
    ``ComputePathThroughPoses`` so that an occupied waypoint is skipped,
    not waited for.
    """

    PARAMS = (
        Param("input_key", str, "/goals", doc="blackboard key of the list of goal poses"),
        Param("output_key", str, "/goals", doc="blackboard key the goals kept are written to"),
        Param("cost_threshold", float, 254.0, doc="goals on a cost at or above this are dropped (0..255)",
              minimum=0.0, maximum=255.0),
        Param("use_footprint", bool, True, doc="the robot's footprint cost, not the point cost"),
        Param("consider_unknown_as_obstacle", bool, False, doc="drop goals on unknown cells too"),
    )
    READS = (NAVIGATOR_KEY, "$input_key")
    WRITES = ("$output_key",)

    def __init__(self, name: str, input_key: str = "/goals", output_key: str = "/goals", cost_threshold: float = 254.0,
                 use_footprint: bool = True, consider_unknown_as_obstacle: bool = False):  # fmt: skip
        self.input_key, self.output_key = input_key, output_key
        super().__init__(name)
        self.cost_threshold, self.unknown_is_obstacle = cost_threshold, consider_unknown_as_obstacle
        self.use_footprint = use_footprint

    def update(self) -> Status:
        navigator, goals = self.read(NAVIGATOR_KEY), as_poses(self.read(self.input_key))
        if navigator is None or goals is None:
            self.feedback_message = "no navigation service" if navigator is None else f"no goal list at {self.input_key}"
            return Status.FAILURE
        if not goals:
            self.write(self.output_key, [])
            return Status.SUCCESS
        costs = navigator.costmap.cost_at(np.array([[g.x, g.y] for g in goals]))
        if self.use_footprint:
            costs = np.where(costs == INSCRIBED, LETHAL, costs)
        kept = [g for g, c in zip(goals, costs, strict=True)
                if (c == NO_INFORMATION and not self.unknown_is_obstacle) or c < self.cost_threshold]
        self.write(self.output_key, kept)
        self.feedback_message = f"{len(kept)} of {len(goals)} goals clear" if kept else "every goal is in collision"
        return Status.SUCCESS


@register("IsPathValid", kind="condition")
class IsPathValid(HomingBehaviour):
    """SUCCESS while the path at ``path_key`` is clear of obstacles on the costmap as it is now: Nav2's ``IsPathValid``.

    The stretch under the robot itself is not checked (a robot grazing a
    wall sits in inscribed cells). FAILURE without a path or a navigator.
    """

    PARAMS = (Param("path_key", str, PATH_KEY, doc="blackboard key of the path to check"),)
    READS = (NAVIGATOR_KEY, POSE_KEY, "$path_key")

    def __init__(self, name: str, path_key: str = PATH_KEY):
        self.path_key = path_key
        super().__init__(name)

    def update(self) -> Status:
        navigator, pose, path = self.read(NAVIGATOR_KEY), self.read(POSE_KEY), self.read(self.path_key)
        if navigator is None or pose is None or path is None or len(path) < 2:
            self.feedback_message = "nothing to check"
            return Status.FAILURE
        blocked = navigator.path_blocked(np.asarray(path, dtype=float), pose)
        self.feedback_message = "blocked" if blocked else "clear"
        return Status.FAILURE if blocked else Status.SUCCESS
