"""Nav2's path and pose utility nodes over blackboard paths: truncate, pick a pose, concatenate, compare, time out.

Semantics from Nav2's ``nav2_behavior_tree/plugins`` (``truncate_path_action``,
``truncate_path_local_action``,
``get_pose_from_path_action``, ``concatenate_paths_action``,
``are_poses_near_condition``, ``path_expiring_timer_condition``,
``decorator/path_longer_on_approach``). Paths are homing's blackboard paths
(:mod:`homing.behaviours.paths`): (N, 3) float64 in ``map``, x [m], y [m],
and the heading wanted at the end [rad] in the last row (nan elsewhere, or
nan for "any"); poses are :class:`~homing.robot.Pose2` or ``[x, y, theta]``.
Frames need no transform: every pose and path in homing is in ``map``.
"""

from __future__ import annotations

import math
from collections.abc import Iterator
from typing import Any

import numpy as np
import py_trees
from homing.behaviours.base import HomingBehaviour
from homing.behaviours.goal_checks import near
from homing.behaviours.keys import POSE_KEY
from homing.behaviours.paths import PATH_KEY, as_pose
from homing.behaviours.registry import REQUIRED, Param, register
from homing.behaviours.throttles import changed
from homing.robot import Pose2
from py_trees.behaviour import Behaviour
from py_trees.common import Access, Status


def as_path(value: Any) -> np.ndarray:
    """A blackboard path as an (N, 3) array (N = 0 when unset or empty)."""
    if value is None:
        return np.zeros((0, 3))
    path = np.asarray(value, dtype=float)
    return path.reshape(-1, 3) if path.size else np.zeros((0, 3))


def path_length(path: np.ndarray) -> float:
    """Length [m] of the polyline through the path's points (Nav2's ``calculate_path_length``)."""
    return float(np.hypot(*np.diff(path[:, :2], axis=0).T).sum()) if len(path) > 1 else 0.0


def _heading_at(path: np.ndarray, i: int) -> float:
    """The heading at point ``i``: the end heading for the last point when given, else along the path [rad]."""
    if i == len(path) - 1 and not math.isnan(path[i, 2]):
        return float(path[i, 2])
    a, b = (path[i], path[i + 1]) if i + 1 < len(path) else (path[i - 1], path[i]) if i > 0 else (path[i], path[i])
    return math.atan2(b[1] - a[1], b[0] - a[0])


@register("TruncatePath")
class TruncatePath(HomingBehaviour):
    """Drop the path's last points within ``distance`` of its end (keeping two at least) and SUCCEED: Nav2's ``TruncatePath``.

    The new end heading points from the new last point to the old end, so a
    controller stops short of the goal facing it (Nav2 uses it to stop
    ``distance`` before a person or a dock). An empty path is passed on.
    """

    PARAMS = (
        Param("distance", float, 1.0, "m", "points closer than this to the path's end are dropped", minimum=0.0),
        Param("input_key", str, PATH_KEY, doc="blackboard key of the path to truncate"),
        Param("output_key", str, PATH_KEY, doc="blackboard key the truncated path is written to"),
    )
    READS = ("$input_key",)
    WRITES = ("$output_key",)

    def __init__(self, name: str, distance: float = 1.0, input_key: str = PATH_KEY, output_key: str = PATH_KEY):
        self.input_key, self.output_key = input_key, output_key
        super().__init__(name)
        self.distance = distance

    def update(self) -> Status:
        path = as_path(self.read(self.input_key))
        if len(path) == 0:
            self.write(self.output_key, path)
            return Status.SUCCESS
        end = path[-1, :2]
        n = len(path)
        while n > 2 and math.dist(path[n - 1, :2], end) < self.distance:
            n -= 1
        out = path[:n].copy()
        out[:, 2] = math.nan
        dx, dy = end - out[-1, :2]
        out[-1, 2] = math.atan2(dy, dx)  # atan2(0, 0) = 0: Nav2's fallback for an invalid angle
        self.write(self.output_key, out)
        self.feedback_message = f"{len(path)} -> {n} points"
        return Status.SUCCESS


def _first_after(path: np.ndarray, start: int, step: int, distance: float) -> int:
    """The first index from ``start`` (walking by ``step``) past ``distance`` [m] along the path, or one past the end.

    Nav2's ``first_after_integrated_distance``: the points up to it (exclusive)
    lie within ``distance`` of ``start`` measured along the path.
    """
    stop = len(path) if step > 0 else -1
    travelled = 0.0
    i = start
    while i + step != stop:
        travelled += math.dist(path[i, :2], path[i + step, :2])
        if travelled > distance:
            return i + step
        i += step
    return stop


@register("TruncatePathLocal")
class TruncatePathLocal(HomingBehaviour):
    """Write the stretch of the path round the robot's closest pose and SUCCEED: Nav2's ``TruncatePathLocal``.

    The closest pose minimises ``sqrt(dx² + dy² + (w·dθ)²)`` over the path's
    poses, with dx, dy [m] to the robot and dθ [rad] between the robot's
    heading and the path's there (along the path; the end heading at the
    end), w = ``angular_distance_weight`` [m/rad]: with w > 0 a path that
    loops back or reverses at a cusp gives the pose the robot is facing
    along, not the nearest one behind it. Ties go to the later pose. The
    output keeps the poses within ``distance_backward`` [m] before it and
    ``distance_forward`` [m] after it, measured along the path; its last row
    holds the heading along the path there (the original end heading when
    the window reaches the end). With ``max_robot_pose_search_dist`` [m]
    (nan: the whole path) the search starts at the last closest pose and
    spans that much path, so a loop's far side is never taken, until the
    path changes. An empty path is passed on; FAILURE without a robot pose.
    The robot's pose is ``/map/pose`` unless ``pose_key`` names another.
    """

    PARAMS = (
        Param("distance_forward", float, 8.0, "m", "path kept ahead of the closest pose", minimum=0.0),
        Param("distance_backward", float, 4.0, "m", "path kept behind the closest pose", minimum=0.0),
        Param("angular_distance_weight", float, 0.0, "m/rad", "weight of the heading difference", minimum=0.0),
        Param("max_robot_pose_search_dist", float, math.nan, "m",
              "search this much path from the last closest pose (nan: all of it)", above=0.0),
        Param("input_key", str, PATH_KEY, doc="blackboard key of the path"),
        Param("output_key", str, PATH_KEY, doc="blackboard key the stretch is written to"),
        Param("pose_key", str, POSE_KEY, doc="blackboard key of the robot's pose (map)"),
    )
    READS = ("$input_key", "$pose_key")
    WRITES = ("$output_key",)

    def __init__(self, name: str, distance_forward: float = 8.0, distance_backward: float = 4.0,
                 angular_distance_weight: float = 0.0, max_robot_pose_search_dist: float = math.nan,
                 input_key: str = PATH_KEY, output_key: str = PATH_KEY, pose_key: str = POSE_KEY):  # fmt: skip
        self.input_key, self.output_key, self.pose_key = input_key, output_key, pose_key
        super().__init__(name)
        self.forward, self.backward = distance_forward, distance_backward
        self.weight, self.search = angular_distance_weight, max_robot_pose_search_dist
        self.path = np.zeros((0, 3))
        self.begin = 0  # where the closest-pose search starts (pruning only)

    def update(self) -> Status:
        new = as_path(self.read(self.input_key))
        pruning = not math.isnan(self.search)
        if not pruning or not np.array_equal(new, self.path, equal_nan=True):
            self.path, self.begin = new, 0
        pose = as_pose(self.read(self.pose_key))
        if pose is None:
            self.feedback_message = f"no robot pose at {self.pose_key}"
            return Status.FAILURE
        path = self.path
        if len(path) == 0:
            self.write(self.output_key, path)
            return Status.SUCCESS
        end = _first_after(path, self.begin, 1, self.search) if pruning else len(path)
        best, closest = math.inf, self.begin
        for i in range(self.begin, end):
            dtheta = abs(math.remainder(pose.theta - _heading_at(path, i), math.tau))
            d = math.hypot(path[i, 0] - pose.x, path[i, 1] - pose.y, self.weight * dtheta)
            if d <= best:
                best, closest = d, i
        if pruning:
            self.begin = closest
        stop = _first_after(path, closest, 1, self.forward)
        start = _first_after(path, closest, -1, self.backward) + 1
        out = path[start:stop].copy()
        out[:, 2] = math.nan
        out[-1, 2] = path[-1, 2] if stop == len(path) else _heading_at(path, stop - 1)
        self.write(self.output_key, out)
        self.feedback_message = f"points {start}..{stop - 1} of {len(path)} round point {closest}"
        return Status.SUCCESS


@register("GetPoseFromPath")
class GetPoseFromPath(HomingBehaviour):
    """Write the path's pose at ``index`` (negative: from the end) and SUCCEED; FAIL if empty or out of range: Nav2's ``GetPoseFromPath``.

    A Pose2 in ``map``; its heading is the path's end heading for the last
    point (when the path has one), else the direction along the path there.
    """

    PARAMS = (
        Param("index", int, -1, doc="which pose: 0 the first, -1 the last"),
        Param("path_key", str, PATH_KEY, doc="blackboard key of the path"),
        Param("pose_key", str, REQUIRED, doc="blackboard key the pose is written to"),
    )
    READS = ("$path_key",)
    WRITES = ("$pose_key",)

    def __init__(self, name: str, pose_key: str, index: int = -1, path_key: str = PATH_KEY):
        self.path_key, self.pose_key = path_key, pose_key
        super().__init__(name)
        self.index = index

    def update(self) -> Status:
        path = as_path(self.read(self.path_key))
        i = self.index + len(path) if self.index < 0 else self.index
        if not 0 <= i < len(path):
            self.feedback_message = f"no pose {self.index} in a path of {len(path)}"
            return Status.FAILURE
        self.write(self.pose_key, Pose2(float(path[i, 0]), float(path[i, 1]), _heading_at(path, i)))
        return Status.SUCCESS


@register("ConcatenatePaths")
class ConcatenatePaths(HomingBehaviour):
    """Write the first path followed by the second and SUCCEED; FAIL when both are empty: Nav2's ``ConcatenatePaths``.

    The result keeps the second path's end heading (the first one's becomes
    an inner point); an unset path counts as empty.
    """

    PARAMS = (
        Param("input_key1", str, REQUIRED, doc="blackboard key of the first path"),
        Param("input_key2", str, REQUIRED, doc="blackboard key of the second path"),
        Param("output_key", str, PATH_KEY, doc="blackboard key the joined path is written to"),
    )
    READS = ("$input_key1", "$input_key2")
    WRITES = ("$output_key",)

    def __init__(self, name: str, input_key1: str, input_key2: str, output_key: str = PATH_KEY):
        self.input_key1, self.input_key2, self.output_key = input_key1, input_key2, output_key
        super().__init__(name)

    def update(self) -> Status:
        first, second = as_path(self.read(self.input_key1)), as_path(self.read(self.input_key2))
        if len(first) == 0 and len(second) == 0:
            self.feedback_message = "both paths are empty"
            return Status.FAILURE
        out = np.vstack([first, second])
        if len(second):
            out[: len(first), 2] = math.nan
        self.write(self.output_key, out)
        return Status.SUCCESS


@register("GetCurrentPose")
class GetCurrentPose(HomingBehaviour):
    """Write the robot's pose in ``map`` (``/map/pose``) to ``pose_key`` and SUCCEED; FAIL without one: Nav2's ``GetCurrentPose``."""

    PARAMS = (Param("pose_key", str, REQUIRED, doc="blackboard key the pose is written to"),)
    READS = (POSE_KEY,)
    WRITES = ("$pose_key",)

    def __init__(self, name: str, pose_key: str):
        self.pose_key = pose_key
        super().__init__(name)

    def update(self) -> Status:
        pose = self.read(POSE_KEY)
        if pose is None:
            self.feedback_message = f"no robot pose at {POSE_KEY}"
            return Status.FAILURE
        self.write(self.pose_key, pose)
        return Status.SUCCESS


@register("ArePosesNear", kind="condition")
class ArePosesNear(HomingBehaviour):
    """SUCCESS when two poses are within ``tolerance`` of each other (x, y only), else FAILURE: Nav2's ``ArePosesNear``."""

    PARAMS = (
        Param("ref_key", str, REQUIRED, doc="blackboard key of the first pose"),
        Param("target_key", str, REQUIRED, doc="blackboard key of the second pose"),
        Param("tolerance", float, REQUIRED, "m", "the greatest distance that is near", minimum=0.0),
    )
    READS = ("$ref_key", "$target_key")

    def __init__(self, name: str, ref_key: str, target_key: str, tolerance: float):
        self.ref_key, self.target_key = ref_key, target_key
        super().__init__(name)
        self.tolerance = tolerance

    def update(self) -> Status:
        a, b = as_pose(self.read(self.ref_key)), as_pose(self.read(self.target_key))
        status, self.feedback_message = near(a, b, self.tolerance, ("no reference pose", "no target pose"), "apart")
        return status


@register("PathExpiringTimer", kind="condition")
class PathExpiringTimer(HomingBehaviour):
    """SUCCESS once every ``seconds`` while the path stays the same; a new path restarts the timer: Nav2's ``PathExpiringTimer``.

    The first tick starts the timer and FAILS; later ticks FAIL until
    ``seconds`` have passed since the timer started or the path last
    changed, then SUCCEED once and restart it. Nav2 uses it to replan when
    a path grows old. The adapter's clock; the first-tick state is kept for
    the node's life, as Nav2 keeps it.
    """

    PARAMS = (
        Param("seconds", float, 1.0, "s", "period", above=0.0),
        Param("path_key", str, PATH_KEY, doc="blackboard key of the path watched"),
    )
    READS = ("$path_key",)

    def __init__(self, name: str, seconds: float = 1.0, path_key: str = PATH_KEY):
        self.path_key = path_key
        super().__init__(name)
        self.seconds = seconds
        self.start: float | None = None  # [s] adapter clock
        self.path: Any = None

    def update(self) -> Status:
        path = self.read(self.path_key)
        if self.start is None:
            self.start, self.path = self.now(), path
            return Status.FAILURE
        if path is not None and (self.path is None or changed(self.path, path)):
            self.start, self.path = self.now(), path
        if self.now() - self.start < self.seconds:
            self.feedback_message = f"path {self.now() - self.start:.1f} of {self.seconds:g} s old"
            return Status.FAILURE
        self.start = self.now()
        return Status.SUCCESS


@register("path_longer_on_approach", kind="decorator", params=(
    Param("prox_len", float, REQUIRED, "m", "near the goal: the old path is shorter than this", minimum=0.0),
    Param("length_factor", float, REQUIRED, doc="the new path is longer than this times the old one", above=0.0),
    Param("path_key", str, PATH_KEY, doc="blackboard key of the path watched"),
), reads=("$path_key",))  # fmt: skip
class PathLongerOnApproach(py_trees.decorators.Decorator):
    """Tick the child only when, near the goal, a new path to the same goal is much longer; else SUCCEED: Nav2's ``PathLongerOnApproach``.

    Each tick compares the path with the one seen on the previous tick: if
    it is a new path (another point count) to the same end, the old one was
    shorter than ``prox_len`` and the new one is longer than
    ``length_factor`` times it, the child runs (typically a wait for a
    person to step out of the way) and its status is returned; otherwise
    the node SUCCEEDS without ticking it. A change of goal starts the watch
    over (the first path to a goal never triggers). The comparison is made
    every tick, the running child too: once it no longer holds, a running
    child is halted (Nav2 leaves it running, unticked).
    """

    def __init__(self, name: str, child: Behaviour, prox_len: float, length_factor: float, path_key: str = PATH_KEY):
        super().__init__(name=name, child=child)
        self.prox_len, self.length_factor, self.path_key = prox_len, length_factor, path_key
        self.bb = self.attach_blackboard_client(name=name)
        self.bb.register_key(key=path_key, access=Access.READ)
        self.old = np.zeros((0, 3))
        self.first = True

    def _triggered(self, new: np.ndarray) -> bool:
        old = self.old
        updated = len(old) and len(new) and len(new) != len(old) and np.array_equal(old[-1, :2], new[-1, :2])
        return bool(updated) and path_length(old) < self.prox_len and \
            path_length(new) > self.length_factor * path_length(old) and not self.first  # fmt: skip

    def tick(self) -> Iterator[Behaviour]:
        new = as_path(self.bb.get(self.path_key) if self.bb.exists(self.path_key) else None)
        if not self.first and (len(self.old) == 0 or len(new) == 0
                               or not np.array_equal(self.old[-1], new[-1], equal_nan=True)):  # fmt: skip
            self.first = True
        if self._triggered(new):
            yield from super().tick()
            if self.status != Status.RUNNING:
                self.old = new
            return
        if self.decorated.status == Status.RUNNING:
            self.decorated.stop(Status.INVALID)  # Nav2 leaves it running unticked; homing halts it
        self.old, self.first = new, False
        self.feedback_message = "no longer path on approach"
        self.status = Status.SUCCESS
        yield self

    def update(self) -> Status:
        return self.decorated.status
