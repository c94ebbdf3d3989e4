"""Navigation split as Nav2 splits it (plan, then follow) and Nav2's goal conditions, through missions.

A test service publishes the exact maze of :mod:`tests.navworld` as
``/map/grid`` and the scripted robot's pose (it integrates its commands
exactly) as ``/map/pose``, so the leaves run against the real navigation
service (costmap, planner, controller) with no simulator: a Nav2-style
replanning tree must reach the goal without touching a wall, replanning
about once a second.
"""

from __future__ import annotations

import math
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np
import py_trees
import pytest
from homing.behaviours import goal_checks as gc
from homing.behaviours.paths import as_pose, as_poses, with_heading
from homing.behaviours.registry import SERVICES, register_service
from homing.missions.compiler import compile_mission
from homing.missions.runner import Runner, StatusChange
from homing.robot import Observation, Pose2
from homing.robot.turtlebot import BASE_RADIUS
from py_trees.common import Access, Status

from homing.map_server import MapData
from tests.mission_fakes import F, FakeRobot, S, tick
from tests.navworld import MAZE, MAZE_GOAL, MAZE_START, point_rect_distance, rasterise

RES = 0.05  # [m]


class _MazeTruth:
    """Test-only localiser: the maze as /map/grid, the scripted robot's exact pose as /map/pose."""

    name = "_test_maze_truth"
    writes = ("/map/grid", "/map/pose", "/map/map_to_odom")

    def setup(self, robot: Any, blackboard: Any) -> None:
        self.robot, self.bb = robot, blackboard
        self.grid = MapData(rasterise(MAZE, (10.0, 10.0), RES), RES, (0.0, 0.0, 0.0))

    def update(self, obs: Observation) -> None:
        self.bb.set("/map/grid", self.grid, overwrite=True)
        self.bb.set("/map/pose", obs.odom.pose, overwrite=True)
        self.bb.set("/map/map_to_odom", Pose2(), overwrite=True)

    def shutdown(self) -> None:
        pass


@pytest.fixture
def maze() -> Iterator[None]:
    register_service(_MazeTruth.name, writes=_MazeTruth.writes)(_MazeTruth)
    try:
        yield
    finally:
        SERVICES.pop(_MazeTruth.name, None)


def run_maze(tmp_path: Path, tree: str, until: float = 120.0) -> tuple[Runner, list[StatusChange], list[Pose2]]:
    path = tmp_path / "m.yaml"
    path.write_text(f"services: [_test_maze_truth, navigation]\nblackboard: {{goal: [{MAZE_GOAL[0]}, {MAZE_GOAL[1]}, 0.0]}}\ntree:\n{tree}")
    robot = FakeRobot()
    robot.pose = Pose2(*MAZE_START, 0.0)
    trail: list[Pose2] = []
    log: list[StatusChange] = []
    runner = Runner(compile_mission(path), robot, until=until, on_change=log.append,
                    on_tick=lambda r: trail.append(robot.pose))  # fmt: skip
    runner.result = runner.run()  # type: ignore[attr-defined]
    return runner, log, trail


REPLANNING = """
  pipeline_sequence:
    - rate_controller:
        hz: 1
        child: {ComputePathToPose: {goal_key: goal, path_key: path}}
    - FollowPath: {path_key: path}
"""


def test_replanning_pipeline_reaches_the_goal_without_touching(tmp_path: Path, maze: None) -> None:
    runner, log, trail = run_maze(tmp_path, REPLANNING)
    assert runner.result.reason == "success", "\n".join(c.line() for c in log[-20:])  # type: ignore[attr-defined]
    end = trail[-1]
    assert math.hypot(end.x - MAZE_GOAL[0], end.y - MAZE_GOAL[1]) <= 0.15 + 1e-6
    clearance = point_rect_distance(np.array([(p.x, p.y) for p in trail]), MAZE).min()
    assert clearance > BASE_RADIUS, f"the robot touched a wall ({clearance:.3f} m from one)"
    # Replanned once a second while driving: the rate controller goes RUNNING → SUCCESS at each plan.
    duration = runner.result.time  # type: ignore[attr-defined]
    plans = sum(1 for c in log if c.node == "rate_controller" and c.new == Status.SUCCESS)
    assert abs(plans - duration) <= 2, (plans, duration)


def test_follow_path_fails_without_a_path_and_reports_why(tmp_path: Path, maze: None) -> None:
    tree = "  sequence: [SetBlackboard: {key: path, value: []}, FollowPath: {path_key: path}]\n"
    runner, _, _ = run_maze(tmp_path, tree, until=2.0)
    assert runner.result.reason == "failure"  # type: ignore[attr-defined]
    assert py_trees.blackboard.Blackboard.storage.get("/nav/failure") == "no_path"


def test_compute_path_to_a_goal_in_a_wall_fails_with_goal_occupied(tmp_path: Path, maze: None) -> None:
    tree = """
  sequence:
    - SetBlackboard: {key: goal, value: [2.05, 3.0, 0.0]}
    - ComputePathToPose: {goal_key: goal, path_key: path, failure_key: plan_error}
"""
    runner, _, _ = run_maze(tmp_path, tree, until=2.0)
    assert runner.result.reason == "failure"  # type: ignore[attr-defined]
    assert py_trees.blackboard.Blackboard.storage.get("/plan_error") == "goal_occupied"


def test_path_through_poses_visits_them_in_order(tmp_path: Path, maze: None) -> None:
    tree = """
  sequence:
    - SetBlackboard: {key: goals, value: [[3.0, 8.5, 0.0], [5.0, 1.0, 0.0], [9.0, 1.0, 0.0]]}
    - RemovePassedGoals: {input_key: goals, output_key: goals, radius: 0.5}
    - ComputePathThroughPoses: {goals_key: goals, path_key: path}
    - FollowPath: {path_key: path}
    - IsPathValid: {path_key: path}
"""
    runner, log, trail = run_maze(tmp_path, tree, until=200.0)
    assert runner.result.reason == "success", "\n".join(c.line() for c in log[-20:])  # type: ignore[attr-defined]
    path = py_trees.blackboard.Blackboard.storage["/path"]
    assert path.shape[1] == 3 and math.isnan(path[0, 2]) and path[-1, 2] == 0.0
    xy = np.array([(p.x, p.y) for p in trail])
    near = [int(np.argmin(np.hypot(*(xy - g).T))) for g in ((3.0, 8.5), (5.0, 1.0), (9.0, 1.0))]
    assert near == sorted(near), "the via points are passed in order"
    assert min(np.hypot(*(xy - (3.0, 8.5)).T)) < 0.6


def test_pose_conversions() -> None:
    assert as_pose([1, 2]) == Pose2(1.0, 2.0, 0.0)
    assert as_pose(Pose2(1, 2, 3)) == Pose2(1, 2, 3)
    assert as_pose("x") is None and as_pose([1, "a"]) is None
    assert as_poses([[0, 0, 0], [1, 1]]) == [Pose2(0, 0, 0), Pose2(1, 1, 0)]
    assert as_poses([[0, 0], 5]) is None
    out = with_heading(np.array([[0.0, 0.0], [1.0, 0.0]]), 0.5)
    assert out.shape == (2, 3) and math.isnan(out[0, 2]) and out[1, 2] == 0.5


# --------------------------------------------------------------------------- goal conditions


def board(*keys: str) -> py_trees.blackboard.Client:
    client = py_trees.blackboard.Client(name="test-board")
    for key in keys:
        client.register_key(key=key, access=Access.WRITE)
    return client


def test_goal_updated_remembers_then_notices_a_new_goal() -> None:
    bb = board("/goal")
    bb.set("/goal", [1.0, 2.0, 0.0])
    node = gc.GoalUpdated("gu", goal_key="/goal")
    assert [tick(node) for _ in range(2)] == [F, F], "first tick remembers, then the same goal"
    bb.set("/goal", [1.0, 2.5, 0.0])
    assert [tick(node) for _ in range(2)] == [S, F]
    bb.set("/goal", Pose2(3, 3, 0))
    node.stop(Status.INVALID)  # reset by its parent: looks afresh
    assert tick(node) == F
    glob = gc.GlobalUpdatedGoal("gg", goal_key="/goal")
    tick(glob)
    bb.set("/goal", Pose2(4, 4, 0))
    glob.stop(Status.INVALID)
    assert tick(glob) == S, "GlobalUpdatedGoal keeps its memory across resets"


def test_failure_is_matches_typed_reasons() -> None:
    bb = board("/err")
    node = gc.FailureIs("f", reasons=list(gc.PLANNER_REASONS), key="/err")
    bb.set("/err", None)
    assert tick(node) == F
    bb.set("/err", "no_path")
    assert tick(node) == S
    bb.set("/err", "goal_occupied")
    assert tick(node) == F, "clearing the costmap cannot make an occupied goal free"


def test_goal_reached_and_distance_traveled() -> None:
    bb = board("/goal", "/map/pose")
    bb.set("/goal", [1.0, 1.0, 0.0])
    reached, moved = gc.GoalReached("r", goal_key="/goal"), gc.DistanceTraveled("d", distance=1.0)
    got = []
    for x in (0.0, 0.5, 0.8, 1.1):
        bb.set("/map/pose", Pose2(x, 1.0, 0.0))
        got.append((tick(reached), tick(moved)))
    assert got == [(F, F), (F, F), (S, F), (S, S)]


def test_time_expired_fires_every_period() -> None:
    robot = FakeRobot()
    node = gc.TimeExpired("t", seconds=0.3)
    node.setup(robot=robot)
    assert [tick(node, robot) for _ in range(7)] == [F, F, F, S, F, F, S]
