"""Navigation in the pybullet simulator: from the dock to a goal in a known world without touching anything.

The robot starts docked, its bumper touching the dock, which stands below the
lidar's plane (the scan never sees it): it backs off first, as the lifecycle's
undocking does. Driving off the dock without that pressed a bumper whatever
the in-place turn speed — the cause the previous report could not find.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from homing.navigation.navigator import Navigator, NavStatus
from homing.navigation.recovery import BackUp, MotionStatus
from homing.robot import Pose2

RATE = 10.0  # [Hz] ticks


@pytest.mark.slow
def test_reaches_a_goal_in_loop_without_bumping(floor_plans) -> None:  # type: ignore[no-untyped-def]
    from homing.sim import SimRobot, load_world

    world = load_world(floor_plans / "loop.yaml")
    robot = SimRobot(world, seed=3)
    try:
        # The true map is the grid and map = odom at the start (truth used only to set up the test).
        start = robot.truth_pose()
        map_to_odom = start.compose(robot.observe().odom.pose.inverse())
        # The dock faces the inner block from the outer corridor (x ≈ 7.3 … 9.9 m); go 5 m along it.
        goal = Pose2(8.6, start.y + 5.0, math.pi / 2)
        assert world.is_free(goal.x, goal.y)
        bumped = _back_off(robot, 0.3)
        nav = Navigator()
        nav.set_goal(goal)
        status = NavStatus.RUNNING
        for _ in range(int(90 * RATE)):
            obs = robot.observe()
            bumped |= obs.bumpers.any()
            status, cmd, fb = nav.step(obs, world.map, map_to_odom.compose(obs.odom.pose), map_to_odom)
            if status is not NavStatus.RUNNING:
                break
            robot.command(cmd.v, cmd.omega)
            robot.step(1.0 / RATE)
        end = robot.truth_pose()
        assert status is NavStatus.SUCCEEDED, fb.message
        assert not bumped
        est = map_to_odom.compose(obs.odom.pose)
        assert math.hypot(est.x - goal.x, est.y - goal.y) <= 0.15 + 0.05  # where it believes it is
        # Truth differs by the odometry's drift only (no SLAM here): within 10 % of the 5 m travelled.
        assert math.hypot(end.x - goal.x, end.y - goal.y) < 0.15 + 0.5
    finally:
        robot.close()


def _back_off(robot, distance: float) -> bool:  # type: ignore[no-untyped-def]
    """Back straight off the dock by ``distance`` [m]; whether a bumper fired."""
    backup, bumped = BackUp(distance, 0.1), False
    obs = robot.observe()
    backup.start(obs.stamp, obs.odom.pose)
    for _ in range(int(10 * RATE)):
        obs = robot.observe()
        bumped |= obs.bumpers.any()
        status, cmd = backup.step(obs.stamp, obs.odom.pose, obs.scan.points() if obs.scan else None)
        if status is not MotionStatus.RUNNING:
            break
        robot.command(cmd.v, cmd.omega)
        robot.step(1.0 / RATE)
    assert status is MotionStatus.SUCCEEDED
    return bumped


def _leave_dock(robot, nav: Navigator, goal: Pose2, world, seconds: float = 40.0) -> tuple[NavStatus, int]:  # type: ignore[no-untyped-def]
    """Navigate straight from the docked pose (no back-off) on the true map; (status, bumper presses)."""
    start = robot.truth_pose()
    map_to_odom = start.compose(robot.observe().odom.pose.inverse())
    nav.set_goal(goal, yaw_tolerance=math.inf)
    presses, before, status = 0, False, NavStatus.RUNNING
    for _ in range(int(seconds * RATE)):
        obs = robot.observe()
        presses += int(obs.bumpers.any() and not before)
        before = obs.bumpers.any()
        status, cmd, _ = nav.step(obs, world.map, map_to_odom.compose(obs.odom.pose), map_to_odom)
        if status is not NavStatus.RUNNING:
            break
        robot.command(cmd.v, cmd.omega)
        robot.step(1.0 / RATE)
    return status, presses


@pytest.mark.slow
def test_leaving_the_dock_for_a_goal_behind_never_bumps_with_the_dock_keepout(floor_plans) -> None:  # type: ignore[no-untyped-def]
    from homing.navigation.layers import dock_keepout
    from homing.sim import SimRobot, load_world

    world = load_world(floor_plans / "loop.yaml")
    docked = world.dock_pose
    # 1 m behind the docked robot and 2 m to its left: it must turn round beside the (invisible) dock.
    goal = docked.compose(Pose2(-1.0, 2.0, 0.0))
    assert world.is_free(goal.x, goal.y)
    robot = SimRobot(world, seed=3, camera=False)
    try:
        # Without the keep-out zone the turn presses a bumper on the dock the lidar cannot see…
        status, presses = _leave_dock(robot, Navigator(), goal, world)
        assert presses >= 1
    finally:
        robot.close()
    robot = SimRobot(world, seed=3, camera=False)
    try:
        # …with the dock marked where the robot started (the mission knows it), never.
        nav = Navigator()
        nav.set_keepout([dock_keepout(robot.truth_pose())])
        status, presses = _leave_dock(robot, nav, goal, world)
        assert status is NavStatus.SUCCEEDED, nav.feedback.message
        assert presses == 0
        assert math.hypot(robot.truth_pose().x - goal.x, robot.truth_pose().y - goal.y) <= 0.15 + 0.05
    finally:
        robot.close()


@pytest.mark.slow
def test_a_bump_on_the_dock_marks_the_costmap_on_the_docks_face(floor_plans) -> None:  # type: ignore[no-untyped-def]
    from homing.navigation.costmap import LETHAL
    from homing.navigation.layers import BUMP_RIM
    from homing.sim import SimRobot, load_world
    from homing.sim.dock import DOCK_DEPTH, DOCK_WIDTH

    world = load_world(floor_plans / "room.yaml")
    # 0.3 m out from the docked pose and 0.07 m aside, facing the dock: off its guide (±4 cm), square to its face.
    robot = SimRobot(world, seed=5, camera=False, start=world.dock_pose.compose(Pose2(-0.3, 0.07, 0.0)))
    try:
        nav = Navigator()
        bumpers = None
        for _ in range(int(20 * RATE)):  # creep into the dock until a bumper fires
            obs = robot.observe()
            truth = robot.truth_pose()
            nav.update_costmap(obs, world.map, truth)  # a perfect localiser: only the marking is under test
            if obs.bumpers.any():
                bumpers = obs.bumpers
                break
            robot.command(0.1, 0.0)
            robot.step(1.0 / RATE)
        assert bumpers is not None and bumpers.centre
        marks = nav.costmap.bumps.points
        # Truth: the dock's box in its station frame, x ∈ [0, depth], |y| ≤ width/2.
        local = world.dock.station.inverse().transform_points(marks)
        dx = np.maximum(np.maximum(-local[:, 0], 0.0), local[:, 0] - DOCK_DEPTH)
        dy = np.maximum(np.abs(local[:, 1]) - DOCK_WIDTH / 2, 0.0)
        gap = np.hypot(dx, dy)
        # A centre arc against a flat face: within the arc's sag (r·(1 − cos 30°)) plus a cell of the mark.
        assert gap.max() <= BUMP_RIM * (1 - math.cos(math.radians(30))) + 0.02
        assert np.all(np.abs(local[:, 1]) <= DOCK_WIDTH / 2 + 0.02)  # across the face, not beside the dock
        face = world.dock.station.compose(Pose2(DOCK_DEPTH, 0.0, 0.0))
        assert nav.costmap.cost_at(np.array([[face.x, face.y]]))[0] == LETHAL
        # Clear costmap drops it.
        nav.costmap.clear()
        assert nav.costmap.cost_at(np.array([[face.x, face.y]]))[0] != LETHAL
    finally:
        robot.close()
