"""Nav2's path and pose utilities as homing leaves and decorators, against Nav2's documented semantics and geometry.

Each node is built on its own, its blackboard inputs written by hand, and
its outputs checked in metres and radians (Nav2 ``plugins/action/
truncate_path_action.cpp``, ``get_pose_from_path_action.cpp``,
``concatenate_paths_action.cpp``, ``get_current_pose_action.cpp``,
``plugins/condition/are_poses_near_condition.cpp``,
``path_expiring_timer_condition.cpp``, ``plugins/decorator/
path_longer_on_approach.cpp``).
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from homing.behaviours import path_tools as pt
from homing.behaviours.keys import POSE_KEY
from homing.robot import Pose2
from py_trees.common import Status

from tests.mission_fakes import F, FakeRobot, R, S, Scripted, board, tick

N = Status.INVALID


def straight(n: int, step: float = 0.5, heading: float = math.nan) -> np.ndarray:
    """n points along x, ``step`` apart, from the origin (map), with the end heading given."""
    path = np.full((n, 3), math.nan)
    path[:, 0], path[:, 1] = np.arange(n) * step, 0.0
    path[-1, 2] = heading
    return path


def test_truncate_path_drops_the_end_within_distance_and_faces_the_old_end() -> None:
    client = board("/path", "/short")
    path = straight(9)  # 0.0 .. 4.0 m
    path[-1, 1] = 0.5  # the end is off to the side: the new end heading points at it
    client.set("/path", path)
    node = pt.TruncatePath("t", distance=1.2, input_key="/path", output_key="/short")
    assert tick(node) == S
    out = client.get("/short")
    assert len(out) == 6, "the end and the points 0.71 and 1.12 m from it are dropped, the one at 1.58 m kept"
    assert out[-1, 0] == 2.5 and math.isclose(out[-1, 2], math.atan2(0.5, 1.5))
    assert np.isnan(out[:-1, 2]).all()
    client.set("/path", straight(3, 0.1))
    assert tick(node) == S and len(client.get("/short")) == 2, "two points are always kept"
    client.set("/path", np.zeros((0, 3)))
    assert tick(node) == S and len(client.get("/short")) == 0, "an empty path passes"


@pytest.mark.parametrize(("index", "expected"), [(0, (0.0, 0.0)), (2, (1.0, 0.0)), (-1, (2.0, 0.0)), (-5, (0.0, 0.0)), (-6, None), (5, None)])
def test_get_pose_from_path_counts_from_either_end(index: int, expected: tuple[float, float] | None) -> None:
    client = board("/path", "/pose")
    client.set("/path", straight(5, heading=1.0))
    node = pt.GetPoseFromPath("g", pose_key="/pose", index=index, path_key="/path")
    if expected is None:
        assert tick(node) == F and not client.exists("/pose")
        return
    assert tick(node) == S
    pose = client.get("/pose")
    assert (pose.x, pose.y) == expected
    assert pose.theta == (1.0 if index == -1 else 0.0), "the end heading at the end, along the path elsewhere"


def test_concatenate_paths_joins_and_keeps_the_second_end_heading() -> None:
    client = board("/a", "/b", "/out")
    client.set("/a", straight(2, heading=0.5))
    second = straight(2, heading=2.0)
    second[:, 0] += 3.0
    client.set("/b", second)
    node = pt.ConcatenatePaths("c", input_key1="/a", input_key2="/b", output_key="/out")
    assert tick(node) == S
    out = client.get("/out")
    assert out[:, 0].tolist() == [0.0, 0.5, 3.0, 3.5] and np.isnan(out[:3, 2]).all() and out[3, 2] == 2.0
    client.set("/a", np.zeros((0, 3)))
    client.set("/b", np.zeros((0, 3)))
    assert tick(node) == F


def test_get_current_pose_and_are_poses_near() -> None:
    client = board(POSE_KEY, "/here", "/goal")
    getter = pt.GetCurrentPose("p", pose_key="/here")
    assert tick(getter) == F, "no pose yet"
    client.set(POSE_KEY, Pose2(1.0, 2.0, 0.3))
    assert tick(getter) == S and client.get("/here") == Pose2(1.0, 2.0, 0.3)
    near = pt.ArePosesNear("n", ref_key="/here", target_key="/goal", tolerance=0.5)
    client.set("/goal", [1.3, 2.4, 3.0])
    assert tick(near) == S, "0.5 m apart: near (headings do not count)"
    client.set("/goal", [1.4, 2.4, 0.3])
    assert tick(near) == F


def test_path_expiring_timer_fires_each_period_and_a_new_path_restarts_it() -> None:
    client = board("/path")
    robot = FakeRobot()
    node = pt.PathExpiringTimer("e", seconds=1.0, path_key="/path")
    node.setup(robot=robot)
    client.set("/path", straight(3))
    results = [tick(node, robot, dt=0.25) for _ in range(5)]  # t = 0 .. 1.0
    assert results == [F, F, F, F, S], "the first tick starts the timer; it fires 1 s later"
    assert [tick(node, robot, dt=0.25) for _ in range(2)] == [F, F]  # t = 1.25, 1.5: restarted at 1.0
    client.set("/path", straight(4))  # t = 1.75: a new path restarts the timer
    assert [tick(node, robot, dt=0.25) for _ in range(4)] == [F, F, F, F]  # 1.75 .. 2.5
    assert tick(node, robot) == S  # t = 2.75


def test_path_longer_on_approach_runs_the_child_for_a_detour_near_the_goal() -> None:
    client = board("/path")
    child = Scripted("wait", [R, S])
    node = pt.PathLongerOnApproach("plo", child, prox_len=2.0, length_factor=2.0, path_key="/path")
    client.set("/path", straight(4))  # 1.5 m to the goal at x = 1.5
    assert tick(node) == S and child.ticks == 0, "the first path to a goal never triggers"
    detour = np.array([[0.0, 0.0, math.nan], [0.0, 2.0, math.nan], [1.5, 2.0, math.nan], [1.5, 1.0, math.nan],
                       [1.5, 0.0, math.nan]])  # fmt: skip  # 5 points: a new path (Nav2 compares point counts)
    client.set("/path", detour)  # 5.5 m > 2 x 1.5 m, same end, robot within 2 m: the child runs
    assert tick(node) == R and child.ticks == 1
    assert tick(node) == S and child.ticks == 2, "the child's status, while the detour stays"
    assert tick(node) == S and child.ticks == 2, "the detour is now the old path: nothing new"
    client.set("/path", straight(3))
    client.get("/path")[-1, 0] = 9.0  # another goal: the watch starts over
    assert tick(node) == S and child.ticks == 2
