"""Battery percent follows Kobuki's formula, drains with time and motion, and charges only when docked."""

from __future__ import annotations

from dataclasses import replace

import pytest
from homing.robot.types import ChargingState, Pose2
from homing.sim import SimRobot, load_world
from homing.sim.battery import BASE_DEFAULT, COMPUTER_DEFAULT, Battery

HOUR = 3600.0  # [s]


@pytest.fixture(scope="module")
def lab():
    return load_world("lab")


def _with_batteries(world, base: float, computer: float):
    return replace(world, battery_base=replace(BASE_DEFAULT, percent=base),
                   battery_computer=replace(COMPUTER_DEFAULT, percent=computer))


def test_percent_is_kobukis_formula_of_voltage() -> None:
    battery = Battery(BASE_DEFAULT)
    for _ in range(20):
        battery.update(600.0, 0.5, 0.5, on_dock=False)
        v = battery.voltage
        assert 13.2 <= v <= 16.5
        assert battery.percent == pytest.approx(95.0 * (v - 13.2) / (16.5 - 13.2) + 5.0, abs=1e-9)
        assert battery.state(False).percent == battery.percent


def test_idle_and_motion_drain_at_their_currents(lab) -> None:
    off_dock = lab.dock_pose.compose(Pose2(-1.0, 0.0, 0.0))
    world = _with_batteries(lab, 80.0, 80.0)
    idle = SimRobot(world, seed=1, camera=False, start=off_dock)
    spin = SimRobot(world, seed=1, camera=False, start=off_dock)
    spin.command(0.0, 1.0)
    for robot in (idle, spin):
        for _ in range(60):
            robot.step(10.0)
    # percent = 5 + 95·soc for the base; soc falls by I·t / capacity
    drop_idle = 95.0 * BASE_DEFAULT.idle_a * 600.0 / HOUR / BASE_DEFAULT.capacity_ah
    drop_spin = 95.0 * (BASE_DEFAULT.idle_a + BASE_DEFAULT.turn_a_per_radps * 1.0) * 600.0 / HOUR / BASE_DEFAULT.capacity_ah
    assert idle.observe().battery.percent == pytest.approx(80.0 - drop_idle, abs=1e-6)
    assert spin.observe().battery.percent == pytest.approx(80.0 - drop_spin, abs=1e-6)
    computer = idle.observe().computer_battery
    assert computer.percent == pytest.approx(80.0 - 100.0 * COMPUTER_DEFAULT.idle_a * 600.0 / HOUR / 4.4, abs=1e-6)
    assert computer.state is ChargingState.DISCHARGING
    assert computer.percent < idle.observe().battery.percent  # the computer is the short pole


def test_charges_only_inside_docked_tolerance(lab) -> None:
    world = _with_batteries(lab, 50.0, 30.0)
    docked = SimRobot(world, seed=1, camera=False)
    near = SimRobot(world, seed=1, camera=False, start=lab.dock_pose.compose(Pose2(-0.008, 0.0, 0.0)))
    for robot in (docked, near):
        for _ in range(30):
            robot.step(20.0)
    gain = 95.0 * BASE_DEFAULT.charge_a * 600.0 / HOUR / BASE_DEFAULT.capacity_ah
    b = docked.observe().battery
    assert b.percent == pytest.approx(50.0 + gain, abs=1e-6)
    assert b.state is ChargingState.DOCKING_CHARGING and b.on_dock
    assert docked.observe().computer_battery.percent > 30.0
    assert near.observe().battery.percent < 50.0  # 8 mm off: the contacts are open
    assert not near.observe().battery.on_dock


def test_full_battery_reports_charged(lab) -> None:
    robot = SimRobot(_with_batteries(lab, 99.0, 99.0), seed=1, camera=False)
    for _ in range(20):
        robot.step(60.0)
    b = robot.observe().battery
    assert b.percent == pytest.approx(100.0) and b.voltage == pytest.approx(16.5)
    assert b.state is ChargingState.DOCKING_CHARGED
