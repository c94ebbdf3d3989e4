"""Bumpers fire in the sector of the contact; the dock's IR codes and charging contacts follow its geometry."""

from __future__ import annotations

import math

import pytest
from homing.robot.turtlebot import BASE_RADIUS
from homing.robot.types import IR, ChargingState, Pose2
from homing.sim import Fault, SimRobot, load_world
from homing.sim import dock as dk

from tests.sim_helpers import box_room

W, H = 9.0, 4.0  # [m]


@pytest.fixture(scope="module")
def room(tmp_path_factory: pytest.TempPathFactory):
    return load_world(box_room(tmp_path_factory.mktemp("contacts"), W, H))


@pytest.fixture(scope="module")
def lab():
    return load_world("lab")


def _pressed(robot: SimRobot) -> set[str]:
    b = robot.observe().bumpers
    return {name for name in ("left", "centre", "right") if getattr(b, name)}


@pytest.mark.parametrize(("bearing_deg", "v", "expected"), [
    (0.0, 0.2, {"centre"}),
    (20.0, 0.2, {"centre"}),
    (60.0, 0.2, {"left"}),
    (-60.0, 0.2, {"right"}),
    (-40.0, 0.2, {"right"}),
    (180.0, -0.2, set()),  # backing into a wall: Kobuki has no rear bumper
])
def test_bumper_sector_matches_contact_angle(room, bearing_deg: float, v: float, expected: set[str]) -> None:
    # The wall y = 0 lies at world angle −90°; turn the robot so it lies at `bearing` in base_link.
    theta = -math.pi / 2 - math.radians(bearing_deg)
    robot = SimRobot(room, seed=1, camera=False, start=Pose2(6.0, BASE_RADIUS + 0.01, theta))
    assert _pressed(robot) == set()
    robot.command(v, 0.0)
    robot.step(0.3)
    assert _pressed(robot) == expected
    assert robot.truth_pose().y >= BASE_RADIUS - 0.002  # pushed out, never through the wall
    robot.close()


@pytest.mark.parametrize("side", ["left", "centre", "right"])
def test_moving_obstacle_presses_the_bumper_on_its_side(room, side: str) -> None:
    robot = SimRobot(room, seed=1, camera=False, faults=[Fault("bumper_hit", at=0.5, side=side)],
                     start=Pose2(4.5, 2.0, 0.7))
    seen: set[str] = set()
    for _ in range(20):
        robot.step(0.1)
        seen |= _pressed(robot)
    assert seen == {side}
    robot.close()


# --- dock IR --------------------------------------------------------------------------------
def _facing_dock(lab, dx: float, dy: float, turn: float = 0.0) -> Pose2:
    """Robot centre at (dx, dy) in the emitter frame, heading at the emitter, plus ``turn`` [rad]."""
    e = lab.dock.emitter
    p = e.compose(Pose2(dx, dy, 0.0))
    return Pose2(p.x, p.y, math.atan2(e.y - p.y, e.x - p.x) + turn)


@pytest.mark.parametrize(("dx", "dy", "turn_deg", "expected"), [
    (1.5, 0.0, 0.0, (IR.NONE, IR.FAR_CENTER, IR.NONE)),
    (0.5, 0.0, 0.0, (IR.NONE, IR.NEAR_CENTER, IR.NONE)),
    (1.2, 1.0, 0.0, (IR.NONE, IR.FAR_LEFT, IR.NONE)),  # the dock's left
    (1.2, -1.0, 0.0, (IR.NONE, IR.FAR_RIGHT, IR.NONE)),
    (0.45, 0.4, 0.0, (IR.NONE, IR.NEAR_LEFT, IR.NONE)),
    # kobuki_dock_drive: in the left region, turn CCW until the *right* receiver sees the left code
    (1.2, 1.0, 75.0, (IR.FAR_LEFT, IR.NONE, IR.NONE)),
    (1.2, -1.0, -75.0, (IR.NONE, IR.NONE, IR.FAR_RIGHT)),
    (1.5, 0.0, 180.0, (IR.NONE, IR.NONE, IR.NONE)),  # facing away
    (2.6, 0.0, 0.0, (IR.NONE, IR.NONE, IR.NONE)),  # beyond the field's 2 m depth
])
def test_ir_codes_follow_emitter_geometry(lab, dx, dy, turn_deg, expected) -> None:
    pose = _facing_dock(lab, dx, dy, math.radians(turn_deg))
    robot = SimRobot(lab, seed=1, camera=False, start=pose)
    ir = robot.observe().dock_ir
    assert (ir.right, ir.centre, ir.left) == expected
    robot.close()


def test_codes_overlap_at_region_borders_and_split_near_far(lab) -> None:
    e = lab.dock.emitter
    at = lambda dx, dy: int(lab.dock.codes_at([e.compose(Pose2(dx, dy, 0.0)).as_array()[:2]])[0])  # noqa: E731
    border = math.tan(math.radians(8.5))  # between the side (7°) and centre (10°) edges
    assert at(1.5, 1.5 * border) == IR.FAR_CENTER | IR.FAR_LEFT
    assert at(1.5, -1.5 * border) == IR.FAR_CENTER | IR.FAR_RIGHT
    assert at(dk.NEAR_RANGE - 0.05, 0.0) == IR.NEAR_CENTER
    assert at(dk.NEAR_RANGE + 0.05, 0.0) == IR.FAR_CENTER
    assert at(-0.05, 0.0) == 0  # behind the emitters


def test_ir_around_the_field_is_what_each_receiver_sees(lab) -> None:
    # Dock.ir skips the receivers' geometry when the centre is too far out of the lit box for any
    # receiver to be in it: around the box's edges it must give each receiver's own code (lit where
    # it stands and facing the emitter), so the shortcut darkens no receiver the field lights.
    import numpy as np
    from homing.robot.frames import wrap_angle

    dock, rng = lab.dock, np.random.default_rng(7)
    e = dock.emitter
    lit_seen = 0
    for _ in range(4000):
        dx = rng.uniform(-0.5, dk.FIELD_DEPTH + 0.5)
        dy = rng.uniform(-dk.FIELD_HALF_WIDTH - 0.5, dk.FIELD_HALF_WIDTH + 0.5)
        pose = e.compose(Pose2(dx, dy, rng.uniform(-math.pi, math.pi)))
        ir = dock.ir(pose)
        for name, p, axis in dock.receivers(pose):
            code = int(dock.codes_at(p[None])[0])
            facing = abs(wrap_angle(math.atan2(e.y - p[1], e.x - p[0]) - axis)) <= dk.RECEIVER_HALF_FOV[name]
            assert getattr(ir, name) == (IR(code) if facing and code else IR.NONE), (dx, dy, name)
        lit_seen += ir.any()
    assert lit_seen > 100  # the sample reached the lit box, not only its surroundings


def test_obstacle_in_front_of_dock_blocks_ir(lab) -> None:
    robot = SimRobot(lab, seed=1, camera=False, start=_facing_dock(lab, 1.5, 0.0),
                     faults=[Fault("dock_obstacle", at=0.0, distance=0.5)])
    robot.step(0.1)
    assert not robot.observe().dock_ir.any()
    robot.close()


# --- charging contacts -------------------------------------------------------------------------
def test_starts_docked_and_charges_only_inside_tolerance(lab) -> None:
    robot = SimRobot(lab, seed=1, camera=False)
    assert robot.truth_pose() == lab.dock_pose and robot.charging
    assert robot.observe().battery.on_dock
    docked = lab.dock_pose
    for offset, closed in [
        (Pose2(0.003, 0.0, 0.0), True),
        (Pose2(0.0, 0.004, 0.0), True),
        (Pose2(0.0, 0.0, math.radians(2.5)), True),
        (Pose2(-0.01, 0.0, 0.0), False),
        (Pose2(0.0, 0.008, 0.0), False),
        (Pose2(0.0, 0.0, math.radians(4.0)), False),
    ]:
        robot.set_truth_pose(docked.compose(offset))
        robot.step(0.02)
        assert robot.charging is closed
        assert robot.observe().battery.on_dock is closed
    robot.close()


@pytest.mark.parametrize(("lateral", "yaw_deg", "docks"), [
    (0.0, 0.0, True), (0.02, 4.0, True), (-0.025, -5.0, True), (0.09, 0.0, False), (0.0, 15.0, False),
])
def test_pushing_into_the_dock(lab, lateral: float, yaw_deg: float, docks: bool) -> None:
    # From 0.15 m out, drive straight at the dock: the guide centres a robot within a few cm and degrees.
    start = lab.dock_pose.compose(Pose2(-0.15, lateral, 0.0))
    start = Pose2(start.x, start.y, lab.dock_pose.theta + math.radians(yaw_deg))
    robot = SimRobot(lab, seed=1, camera=False, start=start)
    robot.command(0.1, 0.0)
    for _ in range(60):
        robot.step(0.1)
    obs = robot.observe()
    assert robot.charging is docks
    assert obs.battery.on_dock is docks
    assert obs.bumpers.centre is not docks  # misaligned: the dock's face presses the bumper
    if docks:
        assert obs.battery.state in (ChargingState.DOCKING_CHARGING, ChargingState.DOCKING_CHARGED)
        assert obs.dock_ir.centre & IR.NEAR_CENTER
    robot.close()
