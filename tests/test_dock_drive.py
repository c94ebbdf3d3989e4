"""IR docking after kobuki's dock_drive: it docks from every start pose of a grid in the IR field, judged by the charger."""

from __future__ import annotations

import math

import pytest
from homing.navigation.dock_drive import (
    APPROACH_V,
    FULL_TURN,
    NEAR_V,
    SERVOED_SLOW_ZONE,
    SETTLE,
    SLOW_ZONE,
    DockDrive,
    DockState,
)
from homing.robot import Bumpers, DockIR, Pose2
from homing.robot.types import IR
from homing.sim import SimRobot, load_world
from homing.sim.dock import FIELD_DEPTH

TICK = 0.1  # [s]


@pytest.fixture(scope="module")
def lab():
    return load_world("lab")


def dock_from(world, start: Pose2, seed: int = 1, limit: float = 150.0,
              trace: bool = False, approach: float = 0.0,
              slow_zone: float = SLOW_ZONE) -> tuple[DockDrive, SimRobot, float]:
    """Run one docking attempt from ``start``; returns the drive, the robot (open) and the time taken [s]."""
    robot = SimRobot(world, seed=seed, camera=False, start=start)
    drive = DockDrive(keep_trace=trace)
    obs = robot.observe()
    drive.start(obs.stamp, obs.odom.pose, approach, slow_zone)
    while obs.stamp < limit:
        cmd = drive.step(obs.stamp, obs.dock_ir, obs.bumpers, obs.battery.on_dock, obs.odom.pose)
        if drive.state.finished:
            break
        robot.command(cmd.v, cmd.omega)
        robot.step(TICK)
        obs = robot.observe()
    return drive, robot, obs.stamp


# Start poses: out from the docked pose, across the field, facing the dock, turned away or backwards.
GRID = [(d, lat, yaw) for d in (0.4, 0.9, 1.5) for lat in (-0.8, -0.3, 0.0, 0.3, 0.8) for yaw in (0, 50, -50, 180)]


@pytest.mark.slow
def test_docks_from_every_start_pose_of_a_grid_in_the_ir_field(lab) -> None:
    failures, times = [], []
    for d, lat, yaw in GRID:
        start = lab.dock_pose.compose(Pose2(-d, lat, 0.0)).compose(Pose2(0.0, 0.0, math.radians(yaw)))
        assert lab.dock.emitter.distance_to(start) < FIELD_DEPTH + 0.5  # inside the field (by construction)
        drive, robot, t = dock_from(lab, start)
        if drive.state is not DockState.DONE or not robot.charging:
            failures.append((d, lat, yaw, drive.state.value, drive.reason))
        # DONE only on the charger's word, and only when the contacts are really closed (truth).
        assert (drive.state is DockState.DONE) <= robot.charging
        times.append(t)
        robot.close()
    assert failures == []
    assert max(times) < 120.0


def test_staging_pose_docks_straight_in_within_twenty_seconds(lab) -> None:
    drive, robot, t = dock_from(lab, lab.staging_pose(1.0), trace=True)
    assert drive.state is DockState.DONE and robot.charging
    assert t < 20.0
    straight_in = {DockState.ALIGNED, DockState.ALIGNED_FAR, DockState.ALIGNED_NEAR, DockState.DOCKED_IN}
    assert {s.state for s in drive.trace[:-1]} <= straight_in | {DockState.SCAN}
    assert sum(s.state is DockState.SCAN for s in drive.trace) <= 1  # the first step only
    robot.close()


def test_docked_means_the_charger_held_for_the_settle_time_not_a_pose() -> None:
    drive = DockDrive()
    drive.start(0.0, Pose2())
    quiet = DockIR()
    # At the docked pose, but the charger reports nothing: no verdict.
    cmd = drive.step(0.0, DockIR(centre=IR.NEAR_CENTER), Bumpers(), False, Pose2())
    assert drive.state is DockState.ALIGNED and cmd.v > 0
    # Charging reported: stop at once, DONE only once it has held for SETTLE.
    t = 0.1
    cmd = drive.step(t, quiet, Bumpers(), True, Pose2())
    assert drive.state is DockState.DOCKED_IN and cmd.v == 0.0 and cmd.omega == 0.0
    while t < 0.1 + SETTLE - 1e-6:
        t += 0.1
        drive.step(t, quiet, Bumpers(), True, Pose2())
    assert drive.state is DockState.DONE


def test_a_flicker_of_the_charger_does_not_count() -> None:
    drive = DockDrive()
    drive.start(0.0, Pose2())
    drive.step(0.0, DockIR(centre=IR.NEAR_CENTER), Bumpers(), True, Pose2())
    drive.step(0.1, DockIR(centre=IR.NEAR_CENTER), Bumpers(), False, Pose2())
    drive.step(0.2, DockIR(centre=IR.NEAR_CENTER), Bumpers(), True, Pose2())
    drive.step(0.2 + SETTLE / 2, DockIR(centre=IR.NEAR_CENTER), Bumpers(), True, Pose2())
    assert drive.state is DockState.DOCKED_IN


def test_codes_are_or_ed_over_the_window() -> None:
    drive = DockDrive(window=0.4)
    drive.start(0.0, Pose2())
    assert drive.filtered(0.0, DockIR(centre=IR.FAR_LEFT)) == (IR.NONE, IR.FAR_LEFT, IR.NONE)
    assert drive.filtered(0.2, DockIR(right=IR.NEAR_RIGHT)) == (IR.NEAR_RIGHT, IR.FAR_LEFT, IR.NONE)
    assert drive.filtered(0.5, DockIR()) == (IR.NEAR_RIGHT, IR.NONE, IR.NONE)  # the first sample has aged out
    assert drive.filtered(0.7, DockIR()) == (IR.NONE, IR.NONE, IR.NONE)


def test_a_full_turn_without_any_code_is_lost_not_a_stall() -> None:
    drive = DockDrive()
    drive.start(0.0, Pose2())
    t, yaw = 0.0, 0.0
    while not drive.state.finished and t < 60.0:
        cmd = drive.step(t, DockIR(), Bumpers(), False, Pose2(0.0, 0.0, yaw))
        yaw = math.remainder(yaw + cmd.omega * TICK, 2 * math.pi)
        t += TICK
    assert drive.state is DockState.LOST and drive.reason == "no_signal"
    assert t == pytest.approx(FULL_TURN / 0.66, abs=1.0)


def test_bumps_back_off_and_fail_after_the_limit() -> None:
    drive = DockDrive(max_bumps=2)
    drive.start(0.0, Pose2())
    cmd = drive.step(0.0, DockIR(centre=IR.NEAR_CENTER), Bumpers(centre=True), False, Pose2())
    assert drive.state is DockState.BUMPED and cmd.v < 0
    drive.step(0.1, DockIR(centre=IR.NEAR_CENTER), Bumpers(), False, Pose2())
    assert drive.state is DockState.BUMPED  # still backing off
    drive.step(0.2, DockIR(centre=IR.NEAR_CENTER), Bumpers(left=True), False, Pose2())
    assert drive.state is DockState.FAILED and drive.reason == "bumped"


@pytest.mark.parametrize(("code", "sign"), [(IR.NEAR_LEFT, 1), (IR.NEAR_RIGHT, -1), (IR.FAR_LEFT, 1), (IR.FAR_RIGHT, -1)])
def test_aligned_steers_towards_the_centre_line(code: IR, sign: int) -> None:
    # Standing in the dock's left region, facing it, the centre line lies to the robot's left: turn left.
    drive = DockDrive()
    drive.start(0.0, Pose2())
    drive.step(0.0, DockIR(centre=IR.FAR_CENTER), Bumpers(), False, Pose2())
    cmd = drive.step(1.0, DockIR(centre=code), Bumpers(), False, Pose2())
    assert cmd.v > 0 and math.copysign(1, cmd.omega) == sign


@pytest.mark.parametrize("slow_zone", [SLOW_ZONE, SERVOED_SLOW_ZONE])
def test_from_a_known_staging_distance_it_drives_in_faster_and_meets_the_contacts_at_kobukis_speed(
        lab, slow_zone: float) -> None:
    kobuki, robot, t_kobuki = dock_from(lab, lab.staging_pose(1.0))
    robot.close()
    drive, robot, t = dock_from(lab, lab.staging_pose(1.0), trace=True, approach=1.0, slow_zone=slow_zone)
    assert drive.state is DockState.DONE and robot.charging
    assert kobuki.state is DockState.DONE
    # The 0.8 m − slow_zone it may drive at APPROACH_V instead of 5 cm/s save about that much/0.05 − /0.15 s.
    fast = 0.8 - slow_zone
    assert t_kobuki - t > 0.8 * (fast / NEAR_V - fast / APPROACH_V)
    moving = [s for s in drive.trace if s.cmd.v > 0]
    assert max(s.cmd.v for s in moving) == pytest.approx(APPROACH_V)
    # Within slow_zone of the dock (the last slow_zone / NEAR_V seconds before the contacts) kobuki's speed.
    closed = next(s.time for s in drive.trace if s.state is DockState.DOCKED_IN)
    last = [s for s in moving if s.time > closed - 0.8 * slow_zone / NEAR_V]
    assert last and all(s.cmd.v <= NEAR_V + 1e-9 for s in last)
    robot.close()


def test_autodock_shortens_the_slow_zone_only_where_the_tag_servo_left_the_robot() -> None:
    import py_trees
    from homing.behaviours.docking import STAGED_XY, AutoDock
    from homing.behaviours.keys import STAGED_KEY
    from py_trees.common import Access

    leaf = AutoDock("dock", approach=1.0)
    bb = py_trees.blackboard.Client(name="test-staged")
    bb.register_key(key=STAGED_KEY, access=Access.WRITE)
    here = Pose2(2.0, 1.0, 0.5)
    bb.set(STAGED_KEY, None)
    assert leaf._slow_zone(here) == SLOW_ZONE  # no servo since: the map's staging pose, drifted by the trip
    bb.set(STAGED_KEY, here.compose(Pose2(0.5 * STAGED_XY, 0.0, 0.01)))
    assert leaf._slow_zone(here) == SERVOED_SLOW_ZONE
    bb.set(STAGED_KEY, here.compose(Pose2(-0.3, 0.0, 0.0)))  # backed off since (a retry without a new servo)
    assert leaf._slow_zone(here) == SLOW_ZONE
    bb.set(STAGED_KEY, here.compose(Pose2(0.0, 0.0, 0.2)))  # turned since
    assert leaf._slow_zone(here) == SLOW_ZONE


@pytest.mark.parametrize("code", [IR.NEAR_LEFT, IR.NEAR_RIGHT])
def test_the_beam_lost_while_steering_is_looked_for_back_the_way_it_came(code: IR) -> None:
    drive = DockDrive(window=0.1)
    drive.start(0.0, Pose2(), approach=1.0)
    drive.step(0.0, DockIR(centre=IR.NEAR_CENTER), Bumpers(), False, Pose2())
    steer = drive.step(0.5, DockIR(centre=code), Bumpers(), False, Pose2()).omega
    cmd = drive.step(1.0, DockIR(), Bumpers(), False, Pose2())
    assert drive.state is DockState.SCAN
    assert cmd.v == 0 and math.copysign(1, cmd.omega) == -math.copysign(1, steer)
    # Still turning that way on the next ticks, and kobuki's slow approach once the beam is found again.
    assert math.copysign(1, drive.step(1.5, DockIR(), Bumpers(), False, Pose2()).omega) == -math.copysign(1, steer)
    drive.step(2.0, DockIR(centre=IR.NEAR_CENTER), Bumpers(), False, Pose2())
    assert drive.step(2.5, DockIR(centre=IR.NEAR_CENTER), Bumpers(), False, Pose2()).v == NEAR_V
