"""Nav2's ``IsStopped`` and ``IsStuck`` on homing's odometry, tick by tick (Nav2 ``plugins/condition/is_stopped_condition.cpp``, ``is_stuck_condition.cpp``)."""

from __future__ import annotations

import py_trees
from homing.behaviours.keys import OBSERVATION_KEY
from homing.behaviours.odometry_checks import IsStopped, IsStuck
from homing.robot import Twist2

from tests.mission_fakes import F, FakeRobot, R, S, board, tick


def drive(client: py_trees.blackboard.Client, robot: FakeRobot, v: float, omega: float = 0.0) -> None:
    """The robot's odometry twist this tick, written where the runner writes it."""
    robot.cmd = Twist2(v, omega)
    client.set(OBSERVATION_KEY, robot.observe())


def test_is_stopped_runs_while_slow_and_succeeds_after_the_duration() -> None:
    client = board(OBSERVATION_KEY)
    robot = FakeRobot()
    node = IsStopped("stopped", velocity_threshold=0.1, duration=0.25)
    node.setup(robot=robot)
    results = []
    for v, omega in [(0.3, 0.0), (0.05, 0.0), (0.05, 0.05), (0.0, 0.0), (0.0, 0.0), (0.0, 0.2), (0.0, 0.0)]:
        drive(client, robot, v, omega)
        results.append(tick(node, robot, dt=0.1))
    assert results == [F, R, R, R, S, F, R], "slow from t=0.1; > 0.25 s at t=0.4; turning resets it"


def test_is_stuck_sees_a_hard_deceleration_only() -> None:
    client = board(OBSERVATION_KEY)
    robot = FakeRobot()
    node = IsStuck("stuck")
    node.setup(robot=robot)
    results = []
    for v in [0.5, 0.5, 0.3, 0.5, 0.0, 0.0]:  # 0.2 m/s lost in 0.1 s is -2 m/s², 0.5 m/s is -5
        drive(client, robot, v)
        results.append(tick(node, robot, dt=0.1))
    assert results == [F] * 6
    robot2 = FakeRobot()
    node2 = IsStuck("stuck2")
    node2.setup(robot=robot2)
    results = []
    for v in [0.5, 0.5, 0.5, 0.0]:  # stopped dead from 0.5 m/s within 0.04 s: -12.5 m/s², a bump
        drive(client, robot2, v)
        results.append(tick(node2, robot2, dt=0.04))
    assert results == [F, F, F, S]
