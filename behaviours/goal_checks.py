"""Conditions over goals, failures and time, as Nav2's condition nodes answer them.

``GoalUpdated`` and ``GlobalUpdatedGoal`` notice a new goal (Nav2's
recovery branches give way to one), ``GoalReached`` asks whether the robot
is at it, ``FailureIs`` whether the typed failure a leaf reported is one a
recovery can help with (Nav2's ``WouldAPlannerRecoveryHelp`` and
``WouldAControllerRecoveryHelp`` over error codes), ``TimeExpired`` and
``DistanceTraveled`` fire periodically. All answer in one tick, never
RUNNING, so they can sit under a ``guard`` or at the head of a reactive node.
"""

from __future__ import annotations

import math
from typing import Any

from homing.behaviours.base import HomingBehaviour
from homing.behaviours.keys import POSE_KEY
from homing.behaviours.motion import FAILURE_KEY
from homing.behaviours.paths import GOAL_KEY, as_pose
from homing.behaviours.registry import REQUIRED, Param, register
from homing.behaviours.throttles import changed
from py_trees.common import Status

# The typed reasons a clearing recovery can help with, as Nav2 lists error codes:
PLANNER_REASONS = ("no_path", "timed_out", "failed")  # NO_VALID_PATH, TIMEOUT, UNKNOWN
CONTROLLER_REASONS = ("blocked", "no_progress", "invalid_path", "timed_out", "failed")  # NO_VALID_CONTROL, FAILED_TO_MAKE_PROGRESS, PATIENCE_EXCEEDED, UNKNOWN


class _GoalWatch(HomingBehaviour):
    """Remembers the goal (and goal list) it saw and answers whether they changed since."""

    PARAMS = (
        Param("goal_key", str, GOAL_KEY, doc="blackboard key of the goal ('' = none)"),
        Param("goals_key", str, "", doc="blackboard key of a goal list ('' = none)"),
    )
    READS = ("$goal_key", "$goals_key")
    REMEMBER_ACROSS_RESTARTS = False

    def __init__(self, name: str, goal_key: str = GOAL_KEY, goals_key: str = ""):
        self.goal_key, self.goals_key = goal_key, goals_key
        super().__init__(name)
        self.seen: tuple[Any, Any] | None = None

    def _keys(self, keys: Any) -> list[str]:  # '' means "no such key": nothing to register
        return [k for k in super()._keys(keys) if k]

    def current(self) -> tuple[Any, Any]:
        return (self.read(self.goal_key) if self.goal_key else None, self.read(self.goals_key) if self.goals_key else None)

    def initialise(self) -> None:
        if self.status == Status.INVALID and not self.REMEMBER_ACROSS_RESTARTS:
            self.seen = None  # reset by its parent (or halted): look afresh, as Nav2's node from IDLE

    def update(self) -> Status:
        now = self.current()
        if self.seen is None:
            self.seen = now
            self.feedback_message = "remembering the goal"
            return Status.FAILURE
        if changed(self.seen[0], now[0]) or changed(self.seen[1], now[1]):
            self.seen = now
            self.feedback_message = "new goal"
            return Status.SUCCESS
        self.feedback_message = "same goal"
        return Status.FAILURE


@register("GoalUpdated", kind="condition")
class GoalUpdated(_GoalWatch):
    """SUCCESS when the goal at ``goal_key`` (or list at ``goals_key``) changed since this node's last tick: Nav2's ``GoalUpdated``.

    Its first tick after a (re)start only remembers the goal and fails, as
    Nav2's does from IDLE; a parent that starts over resets it.
    """


@register("GlobalUpdatedGoal", kind="condition")
class GlobalUpdatedGoal(_GoalWatch):
    """Like ``GoalUpdated``, but its memory outlives restarts by its parents: Nav2's ``GlobalUpdatedGoal``.

    Only its very first tick remembers the goal and fails; after that it
    answers whether the goal changed since it last looked, whenever that was.
    """

    REMEMBER_ACROSS_RESTARTS = True


@register("GoalReached", kind="condition")
class GoalReached(HomingBehaviour):
    """SUCCESS while the robot (``/map/pose``) is within ``xy_tolerance`` of the goal at ``goal_key``: Nav2's ``GoalReached``."""

    PARAMS = (
        Param("goal_key", str, GOAL_KEY, doc="blackboard key of the goal pose"),
        Param("xy_tolerance", float, 0.25, "m", "reached within this distance (Nav2's goal checker default)"),
    )
    READS = (POSE_KEY, "$goal_key")

    def __init__(self, name: str, goal_key: str = GOAL_KEY, xy_tolerance: float = 0.25):
        self.goal_key = goal_key
        super().__init__(name)
        self.xy_tolerance = xy_tolerance

    def update(self) -> Status:
        goal, pose = as_pose(self.read(self.goal_key)), self.read(POSE_KEY)
        status, self.feedback_message = near(goal, pose, self.xy_tolerance, ("no goal", "no robot pose"), "from the goal")
        return status


def near(a: Any, b: Any, tolerance: float, missing: tuple[str, str], what: str) -> tuple[Status, str]:
    """(SUCCESS when poses ``a`` and ``b`` are within ``tolerance`` [m] in x, y, else FAILURE; a feedback message).

    A missing pose (None) fails, with ``missing[0]`` or ``missing[1]`` as the message.
    """
    if a is None or b is None:
        return Status.FAILURE, missing[0] if a is None else missing[1]
    gap = math.hypot(a.x - b.x, a.y - b.y)
    return (Status.SUCCESS if gap <= tolerance else Status.FAILURE), f"{gap:.2f} m {what}"


@register("FailureIs", kind="condition")
class FailureIs(HomingBehaviour):
    """SUCCESS when the typed failure reason at ``key`` is one of ``reasons``: Nav2's ``WouldA…RecoveryHelp`` / ``AreErrorCodesPresent``.

    Leaves that fail write a reason (``no_path``, ``blocked``,
    ``no_progress``…) to their ``failure_key``; a recovery branch that
    starts with ``FailureIs`` runs only for causes it can fix. Unset or
    None (the leaf succeeded, or is running) is FAILURE.
    """

    PARAMS = (
        Param("key", str, FAILURE_KEY, doc="blackboard key of the failure reason"),
        Param("reasons", list, REQUIRED, doc="the reasons that answer SUCCESS"),
    )
    READS = ("$key",)

    def __init__(self, name: str, reasons: list[str], key: str = FAILURE_KEY):
        self.key = key
        super().__init__(name)
        self.reasons = [str(r) for r in reasons]

    def update(self) -> Status:
        reason = self.read(self.key)
        ok = reason is not None and str(reason) in self.reasons
        self.feedback_message = f"{self.key} = {reason!r}"
        return Status.SUCCESS if ok else Status.FAILURE


@register("TimeExpired", kind="condition")
class TimeExpired(HomingBehaviour):
    """SUCCESS once every ``seconds`` of adapter time, FAILURE in between: Nav2's ``TimeExpired``.

    The clock starts at the node's first tick and restarts at each SUCCESS.
    """

    PARAMS = (Param("seconds", float, REQUIRED, "s", "period"),)

    def __init__(self, name: str, seconds: float):
        if not seconds > 0:
            raise ValueError(f"seconds must be > 0, not {seconds}")
        super().__init__(name)
        self.seconds = float(seconds)
        self.start: float | None = None

    def update(self) -> Status:
        now = self.now()
        if self.start is None:
            self.start = now
        if now - self.start >= self.seconds:
            self.start = now
            return Status.SUCCESS
        self.feedback_message = f"{self.seconds - (now - self.start):.1f} s left"
        return Status.FAILURE


@register("DistanceTraveled", kind="condition")
class DistanceTraveled(HomingBehaviour):
    """SUCCESS once the robot (``/map/pose``) has moved ``distance`` since the last SUCCESS: Nav2's ``DistanceTraveled``."""

    PARAMS = (Param("distance", float, REQUIRED, "m", "straight-line distance in map"),)
    READS = (POSE_KEY,)

    def __init__(self, name: str, distance: float):
        super().__init__(name)
        self.distance = float(distance)
        self.anchor: Any = None

    def update(self) -> Status:
        pose = self.read(POSE_KEY)
        if pose is None:
            self.feedback_message = "no robot pose"
            return Status.FAILURE
        if self.anchor is None:
            self.anchor = pose
        moved = math.hypot(pose.x - self.anchor.x, pose.y - self.anchor.y)
        if moved >= self.distance:
            self.anchor = pose
            return Status.SUCCESS
        self.feedback_message = f"moved {moved:.2f} of {self.distance:g} m"
        return Status.FAILURE
