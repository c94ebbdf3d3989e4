"""Regulated pure pursuit on a kinematic robot: follows paths, keeps ≤ 0.5 m/s, stops before what the scan sees."""

from __future__ import annotations

import math

import numpy as np
import pytest
from homing.navigation.controller import (
    CollisionAhead,
    InvalidPath,
    free_distance,
    make_controller,
    safe_speed,
)
from homing.navigation.costmap import Costmap
from homing.robot import Pose2, Twist2
from homing.robot.turtlebot import BASE_RADIUS, FOOTPRINT_RADIUS, NAV_MAX_V

from tests.navworld import point_rect_distance, rasterise, scan_of, unicycle

DT = 0.05  # [s] control period
DECEL = 1.0  # [m/s²] the fake base cannot brake harder than this


def _drive(path: np.ndarray, rects: np.ndarray, pose: Pose2, seconds: float, appear_at: float = 0.0,
           name: str = "rpp", costmap: Costmap | None = None,
           **params: object) -> tuple[list[Pose2], list[Twist2], int]:
    """Run the controller on a unicycle whose speed changes at ≤ DECEL; obstacles show up at ``appear_at`` [s]
    (in the scan; ``costmap``, when given, is handed to the controller as it is)."""
    ctrl = make_controller(name, **params)
    speed = Twist2()
    poses, cmds, blocked = [pose], [], 0
    empty = np.zeros((0, 4))
    for k in range(int(seconds / DT)):
        t = k * DT
        world = rects if t >= appear_at else empty
        pts = scan_of(pose, world, stamp=t).points() if len(world) else np.zeros((0, 2))
        try:
            cmd = ctrl.compute(pose, speed, path, pts, costmap, DT)
        except CollisionAhead:
            cmd, blocked = Twist2(), blocked + 1
        cmds.append(cmd)
        v = speed.v + float(np.clip(cmd.v - speed.v, -DECEL * DT, DECEL * DT))
        speed = Twist2(v, cmd.omega)
        pose = unicycle(pose, speed.v, speed.omega, DT)
        poses.append(pose)
    return poses, cmds, blocked


def test_follows_an_l_shaped_path_within_limits() -> None:
    path = np.array([[0.0, 0.0], [3.0, 0.0], [3.0, 3.0]])
    poses, cmds, _ = _drive(path, np.zeros((0, 4)), Pose2(0.0, 0.0, 0.0), 25.0)
    end = poses[-1]
    assert math.hypot(end.x - 3.0, end.y - 3.0) < 0.15
    assert max(c.v for c in cmds) <= NAV_MAX_V + 1e-9
    assert max(c.v for c in cmds) > 0.45  # and it does go at speed on the straight
    xy = np.array([[p.x, p.y] for p in poses])
    # Cross-track error: distance to the L stays small (corner cutting bounded by the lookahead).
    d = np.minimum(np.where(xy[:, 0] <= 3, np.abs(xy[:, 1]), np.hypot(xy[:, 0] - 3, xy[:, 1])),
                   np.where(xy[:, 1] >= 0, np.abs(xy[:, 0] - 3), np.hypot(xy[:, 0] - 3, xy[:, 1])))
    assert d.max() < 0.35


def test_stops_before_an_obstacle_that_appears_in_the_scan() -> None:
    path = np.array([[0.0, 0.0], [6.0, 0.0]])
    box = np.array([[2.5, -0.4, 2.8, 0.4]])  # a box across the path, seen only from t = 2 s
    poses, cmds, blocked = _drive(path, box, Pose2(0.0, 0.0, 0.0), 15.0, appear_at=2.0, fallback=None)
    xy = np.array([[p.x, p.y] for p in poses])
    gap = point_rect_distance(xy, box)[:, 0]
    assert gap.min() >= BASE_RADIUS  # the body never touches the box
    assert gap.min() <= FOOTPRINT_RADIUS + 0.25  # but it drove up to it rather than stopping early
    assert blocked > 0 and cmds[-1] == Twist2()  # and it says why it stopped
    assert poses[-1].distance_to(poses[-20]) < 1e-6  # standing still at the end


def test_steers_past_an_obstacle_beside_the_path_without_stopping() -> None:
    path = np.array([[0.0, 0.0], [6.0, 0.0]])
    wall = np.array([[1.0, 0.5, 5.0, 0.6]])  # parallel to the path, 0.5 m to the left
    _, cmds, blocked = _drive(path, wall, Pose2(0.0, 0.0, 0.0), 14.0)
    assert blocked == 0 and max(c.v for c in cmds) > 0.45


def test_keeps_full_speed_beside_a_wall_it_clears() -> None:
    # A wall along the path 0.12 m beyond the footprint, in the scan and in the costmap: the arc ahead is clear, so
    # the robot runs at the speed limit beside it (the scan check, not the wall's nearness, sets the speed)…
    gap = 0.12  # [m] between the footprint and the wall's face
    wall = np.array([[0.0, 1.0 + FOOTPRINT_RADIUS + gap, 8.0, 1.3 + FOOTPRINT_RADIUS + gap]])
    costmap = Costmap()
    costmap.set_static(rasterise(wall, (8.0, 3.0), costmap.resolution), costmap.resolution, (0.0, 0.0))
    path = np.array([[0.5, 1.0], [7.5, 1.0]])
    poses, cmds, blocked = _drive(path, wall, Pose2(0.5, 1.0, 0.0), 8.0, costmap=costmap)
    xy = np.array([[p.x, p.y] for p in poses])
    assert blocked == 0 and point_rect_distance(xy, wall).min() >= BASE_RADIUS
    beside = xy[1:, 0] > 2.0  # past the first metre and a half of acceleration
    assert min(c.v for c, b in zip(cmds, beside, strict=True) if b) >= 0.95 * NAV_MAX_V
    assert max(c.v for c in cmds) == pytest.approx(NAV_MAX_V)
    # … while Nav2's proximity rule, asked for, still crawls there: v scaled by gap / cost_scaling_dist.
    _, slow, _ = _drive(path, wall, Pose2(0.5, 1.0, 0.0), 8.0, costmap=costmap, cost_scaling_dist=0.3)
    assert max(c.v for c in slow) <= NAV_MAX_V * (gap + costmap.resolution) / 0.3
    # … and so does the default with no scan to check the arc against (the wall only in the costmap): blind, the
    # costmap's nearness is all it knows of the wall.
    _, blind, _ = _drive(path, wall, Pose2(0.5, 1.0, 0.0), 8.0, appear_at=1e9, costmap=costmap)
    assert max(c.v for c in blind) <= NAV_MAX_V * (gap + costmap.resolution) / 0.3


def test_free_distance_matches_geometry() -> None:
    pts = np.array([[1.0, 0.0]])
    assert free_distance(0.3, 0.0, pts, 0.2, 2.0) == pytest.approx(0.8, abs=0.021)
    assert math.isinf(free_distance(0.3, 0.0, pts, 0.2, 0.5))  # beyond the checked length
    assert math.isinf(free_distance(-0.3, 0.0, pts, 0.2, 2.0))  # backing away from it
    # On a left turn of radius 1 m a point on that circle a quarter turn ahead is reached after
    # the arc from the start to where the disc first touches it: angle 2·asin(0.2/2) less than π/2.
    k = 1.0
    p = np.array([[1.0, 1.0]])
    want = (math.pi / 2 - 2 * math.asin(0.2 / 2)) / k
    assert free_distance(0.5, 0.5, p, 0.2, 3.0) == pytest.approx(want, abs=0.021)


def test_safe_speed_brakes_in_time() -> None:
    pts = np.array([[0.6, 0.0]])
    v = safe_speed(0.5, 0.0, pts, radius=0.2)
    room = 0.6 - 0.2 - 0.05  # free arc less the stop margin
    assert v <= math.sqrt(2 * 1.0 * room) + 1e-9 and v > 0
    assert safe_speed(0.5, 0.0, np.array([[0.22, 0.0]]), radius=0.2) == 0.0
    assert safe_speed(0.0, 1.0, np.array([[0.1, 0.0]]), radius=0.2) == 0.0  # rotation is v = 0


def test_rotates_in_place_towards_a_path_behind() -> None:
    ctrl = make_controller("rpp")
    cmd = ctrl.compute(Pose2(0, 0, 0), Twist2(), np.array([[0.0, 0.0], [-2.0, 0.1]]), np.zeros((0, 2)), None, DT)
    assert cmd.v == 0.0 and abs(cmd.omega) >= 0.9


def test_far_from_the_path_is_a_typed_failure() -> None:
    with pytest.raises(InvalidPath):
        make_controller("rpp").compute(Pose2(0, 3, 0), Twist2(), np.array([[0.0, 0.0], [5.0, 0.0]]),
                                       np.zeros((0, 2)), None, DT)


# -- the DWB controller and rpp's fallback ---------------------------------------------------
# A path around a box that passes its corners 0.22–0.25 m off: pure pursuit's lookahead cuts
# the first corner and its scan check then blocks every arc (it used to stall here).
AROUND = np.array([[0.0, 0.0], [2.25, 0.0], [2.25, 0.62], [3.05, 0.62], [3.05, 0.0], [6.0, 0.0]])
BOX = np.array([[2.5, -0.4, 2.8, 0.4]])


def _arrival(poses: list[Pose2], goal: tuple[float, float]) -> float | None:
    k = next((i for i, p in enumerate(poses) if math.hypot(p.x - goal[0], p.y - goal[1]) < 0.15), None)
    return None if k is None else k * DT


def test_rpp_alone_stalls_at_a_tight_corner() -> None:
    poses, _, blocked = _drive(AROUND, BOX, Pose2(), 25.0, fallback=None)
    assert _arrival(poses, (6.0, 0.0)) is None and blocked > 100


@pytest.mark.parametrize(("name", "params"), [("rpp", {}), ("dwb", {})])
def test_dwb_and_rpp_with_fallback_round_the_corner_without_touching(name: str, params: dict[str, object]) -> None:
    poses, cmds, blocked = _drive(AROUND, BOX, Pose2(), 25.0, name=name, **params)
    t = _arrival(poses, (6.0, 0.0))
    assert t is not None and t < 20.0 and blocked == 0
    xy = np.array([[p.x, p.y] for p in poses])
    assert point_rect_distance(xy, BOX).min() >= BASE_RADIUS
    assert max(c.v for c in cmds) <= NAV_MAX_V + 1e-9


def test_dwb_never_drives_into_a_wall_across_its_path() -> None:
    wall = np.array([[2.0, -3.0, 2.1, 3.0]])  # the path runs through it and nothing else knows
    poses, cmds, blocked = _drive(np.array([[0.0, 0.0], [6.0, 0.0]]), wall, Pose2(), 15.0, name="dwb")
    xy = np.array([[p.x, p.y] for p in poses])
    assert point_rect_distance(xy, wall).min() >= BASE_RADIUS
    assert max(c.v for c in cmds) > 0.45  # it did drive at speed towards it first


def test_dwb_commands_respect_the_acceleration_limits() -> None:
    path = np.array([[0.0, 0.0], [3.0, 0.0], [3.0, 3.0]])
    poses, cmds, _ = _drive(path, np.zeros((0, 4)), Pose2(), 25.0, name="dwb")
    assert math.hypot(poses[-1].x - 3.0, poses[-1].y - 3.0) < 0.2
    v = np.array([c.v for c in cmds])
    # The window spans max(dt, 0.1 s) at 1 m/s², so no step in v exceeds 0.1 m/s.
    assert np.abs(np.diff(v)).max() <= 1.0 * 0.1 + 1e-9 and v.max() <= NAV_MAX_V + 1e-9


def test_rollout_and_scan_clearance_match_geometry() -> None:
    from homing.navigation.dwb import rollout, scan_clearance

    targets = np.full((1, 10), 0.5)
    poses, twists = rollout(0.0, 0.0, targets, np.zeros((1, 10)), 1.0, 1.0, 3.2, 0.1)
    assert twists[0, :, 0] == pytest.approx(np.minimum(0.1 * np.arange(1, 11), 0.5))
    assert poses[0, -1, 0] == pytest.approx(0.1 * twists[0, :, 0].sum())
    traj = np.zeros((2, 5, 3))
    traj[0, :, 0] = np.linspace(0.1, 0.5, 5)  # forward towards a point at 0.6 m: touches at 0.41 m
    traj[1, :, 0] = -np.linspace(0.1, 0.5, 5)  # backwards: away from it and from one inside the disc
    hit, gap = scan_clearance(traj, np.array([[0.6, 0.0], [0.1, 0.0]]), 0.19)
    assert hit.tolist() == [True, False]
