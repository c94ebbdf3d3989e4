"""The navigator meets what the lidar cannot see: a low box it bumps into, and a keep-out zone it must avoid.

Kinematic robot in the exact maze of :mod:`tests.navworld`; a low box is
left out of both the map and the scan (as the 0.12 m dock is below the
lidar), and the robot's bumpers fire, kobuki-style, when a motion would push
its rim into it: the robot stays put and the sector of the contact's bearing
is pressed.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from homing.navigation.layers import Keepout
from homing.navigation.navigator import Navigator, NavStatus
from homing.robot import BatteryState, Bumpers, DockIR, Observation, Odometry, Pose2, Twist2
from homing.robot.turtlebot import BASE_RADIUS, bumper_sector

from homing.map_server import MapData
from tests.navworld import MAZE, point_rect_distance, rasterise, scan_of, unicycle

DT = 0.1  # [s]
RES = 0.05  # [m]
LOW_BOX = np.array([[4.9, 5.5, 5.2, 5.62]])  # [m] dock-sized, in the corridor x ∈ [4.1, 6.0], below the lidar


def _contact(pose: Pose2, rects: np.ndarray, rim: float = BASE_RADIUS) -> Bumpers:
    """Bumpers pressed by rectangles within ``rim`` [m] of a robot at ``pose`` (bearing of the nearest point)."""
    pressed = {"left": False, "centre": False, "right": False}
    for x0, y0, x1, y1 in rects:
        qx, qy = min(max(pose.x, x0), x1), min(max(pose.y, y0), y1)
        if math.hypot(qx - pose.x, qy - pose.y) < rim:
            side = bumper_sector(math.atan2(qy - pose.y, qx - pose.x) - pose.theta)
            if side is not None:
                pressed[side] = True
    return Bumpers(**pressed)


def _gap(pose: Pose2, rects: np.ndarray) -> float:
    return float(point_rect_distance(np.array([[pose.x, pose.y]]), rects).min()) if len(rects) else math.inf


def _drive(nav: Navigator, start: Pose2, goal: Pose2, seconds: float, low: np.ndarray):  # type: ignore[no-untyped-def]
    grid = MapData(rasterise(MAZE, (10.0, 10.0), RES), RES, (0.0, 0.0, 0.0))
    nav.set_goal(goal, yaw_tolerance=math.inf)
    pose, twist, bumpers = start, Twist2(), Bumpers()
    trail, presses, backing = [pose], 0, 0
    status = NavStatus.RUNNING
    for k in range(int(seconds / DT)):
        t = k * DT
        obs = Observation(stamp=t, odom=Odometry(t, pose, twist), scan=scan_of(pose, MAZE, stamp=t), image=None,
                          bumpers=bumpers, dock_ir=DockIR(), battery=BatteryState(16.0, 90.0))
        status, cmd, fb = nav.step(obs, grid, pose, Pose2())
        if status is not NavStatus.RUNNING:
            break
        backing += int(cmd.v < 0)
        nxt = unicycle(pose, cmd.v, cmd.omega, DT)
        hit = _contact(nxt, low)
        if hit.any() and _gap(nxt, low) < _gap(pose, low):
            presses += int(not bumpers.any())
            # The bumper stops the robot at contact: the largest part of the motion that keeps the rim out.
            lo, hi = 0.0, 1.0
            for _ in range(20):
                mid = 0.5 * (lo + hi)
                lo, hi = (mid, hi) if _gap(unicycle(pose, cmd.v, cmd.omega, mid * DT), low) >= BASE_RADIUS else (lo, mid)
            pose = unicycle(pose, cmd.v, cmd.omega, lo * DT)
            bumpers, twist = _contact(pose, low, BASE_RADIUS + 1e-3), Twist2()
        else:
            bumpers, twist, pose = Bumpers(), cmd, nxt
        trail.append(pose)
    return status, np.array([[p.x, p.y] for p in trail]), presses, backing, fb


def test_a_bump_backs_off_marks_the_box_and_goes_around_it() -> None:
    nav = Navigator()
    status, xy, presses, backing, fb = _drive(nav, Pose2(5.0, 3.5, math.pi / 2), Pose2(5.0, 8.0), 120.0, LOW_BOX)
    assert status is NavStatus.SUCCEEDED, fb.message
    assert 1 <= presses <= 3 and fb.bumps == presses  # it could not know the box before touching it
    assert backing >= 1  # it backed off after the bump
    assert point_rect_distance(xy, LOW_BOX).min() >= BASE_RADIUS - 0.02  # touched, never pushed in
    # Each bump's arc passes over the contact: within a centimetre or two of the box, never inside the robot.
    bumps = nav.costmap.bumps
    stamps = np.unique(bumps.stamps)
    assert len(stamps) >= presses
    for t in stamps:
        arc = bumps.points[bumps.stamps == t]
        assert point_rect_distance(arc, LOW_BOX).min() <= 0.015
    # The first bump is head-on (centre bumper): its whole arc hugs the box's near face.
    first = bumps.points[bumps.stamps == stamps[0]]
    assert point_rect_distance(first, LOW_BOX).max() <= 0.03


def test_without_the_box_there_is_no_bump() -> None:
    status, _, presses, backing, _ = _drive(Navigator(), Pose2(5.0, 3.5, math.pi / 2), Pose2(5.0, 8.0), 60.0,
                                            np.zeros((0, 4)))
    assert status is NavStatus.SUCCEEDED and presses == 0 and backing == 0


def test_a_keepout_over_the_box_means_no_bump_at_all() -> None:
    nav = Navigator()
    x0, y0, x1, y1 = LOW_BOX[0]
    nav.set_keepout([Keepout(np.array([[x0, y0], [x1, y0], [x1, y1], [x0, y1]]))])
    status, xy, presses, _, fb = _drive(nav, Pose2(5.0, 3.5, math.pi / 2), Pose2(5.0, 8.0), 90.0, LOW_BOX)
    assert status is NavStatus.SUCCEEDED, fb.message
    assert presses == 0
    assert point_rect_distance(xy, LOW_BOX).min() >= BASE_RADIUS


@pytest.mark.slow
def test_an_unseen_barrier_fails_the_goal_after_a_few_bumps_never_pushing_in() -> None:
    from homing.navigation.navigator import BUMP_LIMIT, TooManyBumps
    from homing.navigation.planner import PlanningError

    barrier = np.array([[4.1, 5.5, 6.0, 5.62]])  # across the only corridor to the goal
    nav = Navigator()
    status, xy, presses, _, fb = _drive(nav, Pose2(5.0, 3.5, math.pi / 2), Pose2(5.0, 8.0), 300.0, barrier)
    assert status is NavStatus.FAILED
    assert isinstance(fb.error, TooManyBumps | PlanningError), fb.message
    assert 1 <= presses <= BUMP_LIMIT
    assert point_rect_distance(xy, barrier).min() >= BASE_RADIUS - 1e-6
