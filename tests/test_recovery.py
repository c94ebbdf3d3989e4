"""Recovery motions against their definitions, integrated on a kinematic robot with the caller's clock."""

from __future__ import annotations

import math

import numpy as np
from homing.navigation.costmap import LETHAL, Costmap
from homing.navigation.recovery import BackUp, MotionStatus, Spin, Wait, make_recovery
from homing.robot import Pose2

from tests.navworld import scan_of, unicycle

DT = 0.05  # [s]


def _run(rec, pose: Pose2, seconds: float, rects: np.ndarray | None = None):  # type: ignore[no-untyped-def]
    rec.start(0.0, pose)
    status, turned = MotionStatus.RUNNING, 0.0
    t = 0.0
    for _ in range(int(seconds / DT)):
        pts = scan_of(pose, rects).points() if rects is not None else None
        status, cmd = rec.step(t, pose, pts)
        if status is not MotionStatus.RUNNING:
            break
        new = unicycle(pose, cmd.v, cmd.omega, DT)
        turned += cmd.omega * DT
        pose, t = new, t + DT
    return status, pose, turned, t


def test_spin_turns_the_requested_angle_either_way() -> None:
    for angle in (2 * math.pi, -math.pi / 2):
        status, pose, turned, t = _run(make_recovery("spin", angle=angle), Pose2(1.0, 2.0, 0.3), 30.0)
        assert status is MotionStatus.SUCCEEDED
        assert abs(turned - angle) < 0.06  # stops on the angle (one tick of overshoot at most)
        assert pose.distance_to(Pose2(1.0, 2.0)) < 1e-9  # in place
        assert t >= abs(angle) / 1.0 - 1e-9  # never faster than its ω limit


def test_spin_times_out_when_the_robot_does_not_turn() -> None:
    spin = Spin(angle=math.pi, time_allowance=2.0)
    spin.start(0.0, Pose2())
    status = MotionStatus.RUNNING
    for k in range(100):  # odometry never changes: a stuck robot
        status, _ = spin.step(k * DT, Pose2())
        if status is not MotionStatus.RUNNING:
            break
    assert status is MotionStatus.FAILED and k * DT > 2.0


def test_backup_drives_straight_back_its_distance() -> None:
    status, pose, _, _ = _run(BackUp(distance=0.3, speed=0.1), Pose2(2.0, 2.0, math.pi / 2), 10.0)
    assert status is MotionStatus.SUCCEEDED
    assert abs(pose.x - 2.0) < 1e-9 and 2.0 - 0.3 - 0.006 <= pose.y <= 2.0 - 0.3 + 1e-9
    assert pose.theta == math.pi / 2


def test_backup_stops_for_an_obstacle_behind() -> None:
    wall = np.array([[0.0, 1.55, 4.0, 1.65]])  # 0.35 m behind the centre of a robot facing +y at y = 2
    status, pose, _, _ = _run(BackUp(distance=0.5, speed=0.1), Pose2(2.0, 2.0, math.pi / 2), 10.0, wall)
    assert status is MotionStatus.FAILED
    assert pose.y - 1.65 >= 0.176  # never touched


def test_wait_holds_still_for_its_duration() -> None:
    status, pose, _, t = _run(Wait(duration=1.0), Pose2(), 5.0)
    assert status is MotionStatus.SUCCEEDED and abs(t - 1.0) < DT + 1e-9 and pose == Pose2()


def test_clear_costmap_clears_the_obstacle_layer_only() -> None:
    cm = Costmap()
    g = np.zeros((40, 40), dtype=np.int8)
    g[0, 0] = 100
    cm.set_static(g, 0.05, (0.0, 0.0))
    cm.obstacles[20, 20] = True
    rec = make_recovery("clear_costmap", costmap=cm)
    rec.start(0.0, Pose2())
    status, cmd = rec.step(0.0, Pose2())
    assert status is MotionStatus.SUCCEEDED and not cm.obstacles.any() and cm.cost[0, 0] == LETHAL
    assert cmd.v == 0.0 and cmd.omega == 0.0
