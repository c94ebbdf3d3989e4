"""The navigator end to end on a kinematic robot in an exact maze: reaches goals without touching, typed failures, cancel."""

from __future__ import annotations

import math

import numpy as np
import pytest
from homing.navigation.navigator import Navigator, NavStatus
from homing.navigation.planner import GoalOccupied
from homing.robot import BatteryState, Bumpers, DockIR, Observation, Odometry, Pose2, Twist2
from homing.robot.turtlebot import BASE_RADIUS, NAV_MAX_V

from homing.map_server import MapData
from tests.navworld import (
    MAZE,
    MAZE_GOAL,
    MAZE_START,
    point_rect_distance,
    rasterise,
    scan_of,
    unicycle,
)

DT = 0.1  # [s] tick
SCAN_EVERY = 2  # ticks: ~5 Hz like the RPLIDAR
RES = 0.05  # [m]


def _obs(t: float, pose: Pose2, twist: Twist2, scan_pose: Pose2, scan_t: float, rects: np.ndarray) -> Observation:
    return Observation(
        stamp=t, odom=Odometry(t, pose, twist), scan=scan_of(scan_pose, rects, stamp=scan_t), image=None,
        bumpers=Bumpers(), dock_ir=DockIR(), battery=BatteryState(16.0, 90.0),
    )


def _navigate(nav: Navigator, goal: Pose2, start: Pose2, seconds: float, rects: np.ndarray = MAZE,
              map_rects: np.ndarray = MAZE, cancel_at: float = math.inf):  # type: ignore[no-untyped-def]
    grid = MapData(rasterise(map_rects, (10.0, 10.0), RES), RES, (0.0, 0.0, 0.0))
    nav.set_goal(goal)
    pose, twist = start, Twist2()
    scan_pose, scan_t = pose, 0.0
    trail = [pose]
    status = NavStatus.RUNNING
    for k in range(int(seconds / DT)):
        t = k * DT
        if k % SCAN_EVERY == 0:
            scan_pose, scan_t = pose, t
        if t >= cancel_at:
            nav.cancel()
        # Odometry is exact and map = odom here: the scan is stale by up to one tick.
        status, cmd, fb = nav.step(_obs(t, pose, twist, scan_pose, scan_t, rects), grid, pose, Pose2())
        if status is not NavStatus.RUNNING:
            break
        assert cmd.v <= NAV_MAX_V + 1e-9
        twist = cmd
        pose = unicycle(pose, cmd.v, cmd.omega, DT)
        trail.append(pose)
    return status, trail, fb


@pytest.mark.parametrize(("planner", "controller", "params"), [
    ("fmm", "rpp", {}), ("astar", "rpp", {}),
    # the slow in-place turn that once ended in CollisionAhead here
    pytest.param("fmm", "rpp", {"rotate_omega": 1.0}, marks=pytest.mark.slow),
    pytest.param("fmm", "dwb", {}, marks=pytest.mark.slow),
])
def test_navigates_the_maze_without_touching(planner: str, controller: str, params: dict[str, float]) -> None:
    goal = Pose2(MAZE_GOAL[0], MAZE_GOAL[1], math.pi / 2)
    nav = Navigator(planner=planner, controller=controller, controller_params=params)
    status, trail, fb = _navigate(nav, goal, Pose2(*MAZE_START, 0.0), 120.0)
    assert status is NavStatus.SUCCEEDED, fb.message
    end = trail[-1]
    assert math.hypot(end.x - goal.x, end.y - goal.y) <= 0.15 + 0.05
    assert abs(math.remainder(end.theta - goal.theta, 2 * math.pi)) <= 0.25 + 0.15
    xy = np.array([[p.x, p.y] for p in trail])
    assert point_rect_distance(xy, MAZE).min() >= BASE_RADIUS
    assert fb.replans >= 2  # it replanned on the way


@pytest.mark.parametrize("controller", ["rpp", "dwb"])
def test_goes_around_an_obstacle_the_map_does_not_have(controller: str) -> None:
    box = np.array([[4.6, 5.0, 5.4, 5.6]])  # in the corridor between walls 1 and 2, only in the scan
    world = np.vstack([MAZE, box])
    status, trail, fb = _navigate(Navigator(controller=controller), Pose2(5.0, 8.0, 0.0),
                                  Pose2(5.0, 3.5, math.pi / 2), 90.0,
                                  rects=world, map_rects=MAZE)
    assert status is NavStatus.SUCCEEDED, fb.message
    xy = np.array([[p.x, p.y] for p in trail])
    assert point_rect_distance(xy, world).min() >= BASE_RADIUS


def test_goal_in_a_wall_fails_with_goal_occupied() -> None:
    status, _, fb = _navigate(Navigator(), Pose2(9.0, 2.05), Pose2(*MAZE_START), 10.0)
    assert status is NavStatus.FAILED and isinstance(fb.error, GoalOccupied)


def test_cancel_stops_at_once() -> None:
    nav = Navigator()
    status, trail, _ = _navigate(nav, Pose2(*MAZE_GOAL), Pose2(*MAZE_START), 10.0, cancel_at=2.0)
    assert status is NavStatus.CANCELLED and len(trail) == int(2.0 / DT) + 1


def test_turning_on_the_spot_counts_as_progress_only_a_few_times() -> None:
    nav = Navigator()
    # Standing still: no progress after PROGRESS_TIME.
    assert not nav._no_progress(0.0, Pose2()) and not nav._no_progress(10.0, Pose2())
    assert nav._no_progress(10.1, Pose2())
    # Turning at 0.5 rad/s on the spot: each quarter turn (π s) buys time, PROGRESS_TURNS times only.
    nav = Navigator()
    t, failed_at = 0.0, None
    while t < 60.0 and failed_at is None:
        if nav._no_progress(t, Pose2(0.0, 0.0, 0.5 * t)):
            failed_at = t
        t += 0.1
    assert failed_at is not None
    assert 10.0 + 2 * (math.pi / 2) / 0.5 - 0.2 <= failed_at <= 10.0 + 2 * (math.pi / 2) / 0.5 + 0.3


def test_a_map_correction_replans_at_once() -> None:
    grid = MapData(rasterise(MAZE, (10.0, 10.0), RES), RES, (0.0, 0.0, 0.0))
    nav = Navigator()
    nav.set_goal(Pose2(*MAZE_GOAL))
    pose = Pose2(*MAZE_START, math.pi / 2)
    replans = []
    for k, m2o in enumerate([Pose2(), Pose2(), Pose2(0.01, 0.0, 0.0), Pose2(0.2, 0.0, 0.0), Pose2(0.2, 0.0, 0.0)]):
        t = 0.1 * k  # well inside the 1 s replanning period
        nav.step(_obs(t, pose, Twist2(), pose, t, MAZE), grid, m2o.compose(pose), m2o)
        replans.append(nav.feedback.replans)
    assert replans == [1, 1, 1, 2, 2]  # a 1 cm correction is noise; 20 cm moves the robot against the map


def test_a_goal_beyond_the_known_grid_is_reached_through_the_unknown() -> None:
    # Only a 3 m × 3 m corner of the maze is mapped; the goal lies 5 m beyond it, behind a wall's end.
    known = MapData(rasterise(MAZE, (10.0, 10.0), RES)[:60, :60], RES, (0.0, 0.0, 0.0))
    goal = Pose2(3.0, 8.0, 0.0)
    nav = Navigator()
    nav.set_goal(goal, yaw_tolerance=math.inf)
    pose, twist, status = Pose2(*MAZE_START, 0.0), Twist2(), NavStatus.RUNNING
    trail = [pose]
    for k in range(int(90.0 / DT)):
        t = k * DT
        status, cmd, fb = nav.step(_obs(t, pose, twist, pose, t, MAZE), known, pose, Pose2())
        if status is not NavStatus.RUNNING:
            break
        twist, pose = cmd, unicycle(pose, cmd.v, cmd.omega, DT)
        trail.append(pose)
    assert status is NavStatus.SUCCEEDED, fb.message
    xy = np.array([[p.x, p.y] for p in trail])
    assert point_rect_distance(xy, MAZE).min() >= BASE_RADIUS  # walls seen only by the scan, never touched
    assert nav.costmap.shape == (60, 60)  # back to the grid once the goal is reached


def test_the_path_check_with_its_kept_cells_finds_what_the_costmap_holds_under_the_path_each_time() -> None:
    from homing.navigation.costmap import INSCRIBED, NO_INFORMATION
    from homing.navigation.planner import ESCAPE_RADIUS

    def fresh(nav: Navigator, path: np.ndarray, pose: Pose2) -> bool:
        """The check as first written: the samples' costs looked up afresh, the robot's own stretch left out."""
        seg = np.diff(path, axis=0)
        n = np.maximum(1, np.ceil(np.hypot(*seg.T) / (0.5 * nav.costmap.resolution))).astype(int)
        pts = np.concatenate([a + np.linspace(0, 1, k, endpoint=False)[:, None] * d
                              for a, d, k in zip(path[:-1], seg, n, strict=True)])
        pts = pts[np.hypot(pts[:, 0] - pose.x, pts[:, 1] - pose.y) > ESCAPE_RADIUS]
        cost = nav.costmap.cost_at(pts)
        return bool(np.any((cost >= INSCRIBED) & (cost != NO_INFORMATION)))

    nav = Navigator(planner="astar", planner_params={"allow_unknown": True})
    grid = np.zeros((120, 120), np.int8)
    grid[:, 100:] = -1  # unknown beyond x = 5 m
    nav.costmap.set_static(grid, RES, (0.0, 0.0))
    path = np.array([[0.5, 0.5], [3.0, 1.0], [4.0, 3.5], [6.5, 4.0]])  # its last leg into the unknown
    nav.path = path
    seen = set()
    for step in range(6):
        if step == 2:
            grid[40:44, 50:90] = 100  # a wall across the path
            nav.costmap.set_static(grid, RES, (0.0, 0.0))
        if step == 3:
            nav.costmap.require(-2.0, -2.0, 8.0, 8.0)  # the costmap grows: other cells under the same path
        if step == 4:
            nav.costmap.set_static(grid, RES, (0.0, 0.0))
            nav.costmap.release()
        if step == 5:
            grid[40:44, 50:90] = 0
            nav.costmap.set_static(grid, RES, (0.0, 0.0))
        for pose in (Pose2(0.5, 0.5, 0.0), Pose2(3.6, 2.1, 0.0), Pose2(4.2, 3.6, 0.0)):
            got = nav._path_blocked(pose)
            assert got == fresh(nav, path, pose)
            seen.add(got)
    assert seen == {True, False}  # both answers came up


def test_a_scan_taken_between_ticks_while_turning_fast_marks_the_walls_where_they_are() -> None:
    """The lidar's stamp falls between two ticks' odometry. Turning on the spot at 1.8 rad/s, half a tick is 5°:
    a scan placed with the tick before it marked walls up to 19 cm into the room, and a door's way ahead came
    and went scan by scan (office:1: 77 s turning back and forth). Interpolated, every mark lies on a wall."""
    room = np.array([(0.0, 0.0, 6.0, 0.1), (0.0, 5.9, 6.0, 6.0), (0.0, 0.0, 0.1, 6.0), (5.9, 0.0, 6.0, 6.0),
                     (2.5, 4.0, 3.5, 4.1)])  # a room with a shelf in it
    grid = MapData(rasterise(room, (6.0, 6.0), RES), RES, (0.0, 0.0, 0.0))
    nav = Navigator()
    omega = 1.8  # [rad/s] the controller's fastest turn on the spot
    pose_at = lambda t: Pose2(3.0, 2.0, omega * t)  # noqa: E731
    for k in range(40):  # four seconds, a scan half-way between every two ticks
        t = k * DT
        scan_t = t - DT / 2
        obs = Observation(stamp=t, odom=Odometry(t, pose_at(t), Twist2(0.0, omega)),
                          scan=scan_of(pose_at(scan_t), room, stamp=scan_t) if k else None, image=None,
                          bumpers=Bumpers(), dock_ir=DockIR(), battery=BatteryState(16.0, 90.0))
        nav.update_costmap(obs, grid, pose_at(t), Pose2())
    marks = nav.costmap.cell_to_world(np.argwhere(nav.costmap.obstacles))
    assert len(marks) > 50
    off = point_rect_distance(marks, room).min(axis=1)
    assert off.max() <= RES  # [m] within a cell of a wall (the tick before: 0.19 m)
