"""The hardware adapter against the emulated robot: the real adapters, the real bytes over pseudo-terminals."""

from __future__ import annotations

import math
import time
from collections.abc import Iterator
from pathlib import Path

import pytest
import serial  # type: ignore[import-untyped]
from homing.emulators.emulation import Emulation
from homing.robot import ChargingState, RobotAdapter
from homing.robot.hardware.robot import HardwareRobot, open_robot
from homing.robot.hardware.robot_file import load_robot
from homing.sim import load_world

from homing.errors import UserError
from tests.wall_clock import until


@pytest.fixture
def emulation(tmp_path: Path) -> Iterator[Emulation]:
    emu = Emulation(load_world("lab"), tmp_path / "emu", seed=2)
    emu.start()
    yield emu
    emu.stop()


def test_adapter_reads_what_the_simulator_senses(emulation: Emulation) -> None:
    robot = open_robot(emulation.robot_file)
    try:
        assert isinstance(robot, RobotAdapter)
        obs = robot.observe()
        # Docked at the start: charged, on the dock, the dock's centre IR in view
        sim = emulation.robot.observe()
        assert obs.battery.state is ChargingState.DOCKING_CHARGED and obs.battery.on_dock
        assert obs.battery.voltage == pytest.approx(sim.battery.voltage, abs=0.05)
        assert obs.dock_ir == sim.dock_ir and obs.dock_ir.any()
        assert obs.computer_battery is not None and obs.computer_battery.percent == pytest.approx(
            sim.computer_battery.percent, abs=0.5)
        for _ in range(30):  # back out of the dock at 0.1 m/s for 3 s, then turn at 1 rad/s for 1.5 s
            robot.command(-0.1, 0.0)
            robot.step(0.1)
        for _ in range(15):
            robot.command(0.0, 1.0)
            robot.step(0.1)
        robot.command(0.0, 0.0)
        # The base takes a command 0.2 s late (the emulator's DEAD_TIME): compare once it reports standing still,
        # not while the last turn still runs (at 1 rad/s a 20 ms old reading is 1° behind).
        for _ in range(20):
            robot.step(0.1)
            twist = robot.observe().odom.twist
            if twist.v == 0.0 and twist.omega == 0.0:
                break
        robot.step(0.1)
        with emulation.lock:
            sim_odom = emulation.robot.odometry.pose
            travelled = emulation.distance
        obs = robot.observe()
        assert travelled == pytest.approx(0.3, abs=0.03)
        assert obs.odom.pose.distance_to(sim_odom) < 2e-3  # encoder ticks are 85 µm, the gyro 0.01°
        assert abs(obs.odom.pose.theta - sim_odom.theta) < math.radians(0.05)
        assert obs.battery.state is ChargingState.DISCHARGING and not obs.battery.on_dock
        assert robot.base.stats.checksum_errors == 0 and robot.lidar.scans >= 20
        assert obs.devices_lost == ()
    finally:
        robot.close()


def test_lost_device_stops_the_base_and_is_picked_up_again(emulation: Emulation) -> None:
    robot = open_robot(emulation.robot_file)
    try:
        robot.command(-0.1, 0.0)
        assert until(lambda: emulation.base.speed == -100, 1.0)
        emulation.unplug("lidar")
        assert until(lambda: robot.observe().devices_lost == ("lidar",), 3.0)
        assert robot.command(-0.1, 0.0).v == 0.0  # no lidar, no driving
        assert until(lambda: emulation.base.speed == 0, 1.0)
        emulation.replug("lidar")
        assert until(lambda: robot.observe().devices_lost == (), 6.0)
        assert robot.lidar.reconnects >= 1
        assert robot.command(-0.1, 0.0).v == pytest.approx(-0.1)
        assert until(lambda: emulation.base.speed == -100, 1.0)
    finally:
        robot.close()


def test_watchdog_stops_a_base_left_without_commands(emulation: Emulation) -> None:
    robot = open_robot(emulation.robot_file)
    try:
        robot.command(0.0, 0.5)
        assert until(lambda: emulation.base.speed != 0, 1.0)
        t0 = time.monotonic()
        assert until(lambda: emulation.base.speed == 0, 2.0)
        assert time.monotonic() - t0 >= 0.4  # cmd_timeout 0.6 s, less the command's own travel
    finally:
        robot.close()


def test_missing_and_busy_ports_are_one_line_errors(emulation: Emulation, tmp_path: Path) -> None:
    bad = tmp_path / "robot.yaml"
    bad.write_text("base:\n  port: /dev/no-such-kobuki\nlidar:\n  port: rplidar\n")
    with pytest.raises(UserError) as err:
        HardwareRobot(load_robot(bad))
    assert str(err.value) == f"{bad}:2:9: base port /dev/no-such-kobuki: no such device (is it plugged in?)"
    holder = serial.Serial(str(emulation.lidar_link.link), 115200, exclusive=True)
    try:
        with pytest.raises(UserError) as err:
            open_robot(emulation.robot_file)
        assert str(err.value).startswith(f"{emulation.robot_file}:6:9: lidar port ")
        assert str(err.value).endswith("busy: another program has it open")
    finally:
        holder.close()


@pytest.mark.parametrize(("text", "message"), [
    ("base: {port: a}\n", "robot file: missing required section 'lidar'"),
    ("base: {port: a, baud: 1234}\nlidar: {port: b}\n", "'baud' must be one of"),
    ("base: {port: a}\nlidar: {port: b, range_max: 0.1}\n", "'range_max' (0.1 m) must exceed 'range_min'"),
    ("base: {port: a, wheel_seperation: 0.23}\nlidar: {port: b}\n", "did you mean 'wheel_separation'"),
    ("base: {port: a}\nlidar: {port: b}\ncamera: {source: 0, info: nope.yaml}\n", None),
    ("kind: ros3\nbase: {port: a}\nlidar: {port: b}\n", "1:7: 'kind' must be turtlebot2 or ros2, not 'ros3'"),
])  # fmt: skip
def test_robot_file_mistakes_are_located(tmp_path: Path, text: str, message: str | None) -> None:
    path = tmp_path / "robot.yaml"
    path.write_text(text)
    if message is None:
        config = load_robot(path)
        assert config.camera is not None and config.camera.info == tmp_path / "nope.yaml"
        return
    with pytest.raises(UserError) as err:
        load_robot(path)
    assert str(err.value).startswith(f"{path}:") and message in str(err.value)


GUARD_MISSION = """\
mission: devices_guard
rate: 10
services: []
tree:
  reactive_fallback:
    name: Lifecycle
    children:
      - reactive_sequence:
          name: Healthy
          children:
            - DevicesOk
            - sequence:
                - MissionState: {state: Undocking}
                - Drive: {v: -0.05, seconds: 30}
      - sequence:
          name: ErrorState
          children:
            - MissionState: {state: Error}
            - Running
"""


def test_a_lost_device_sends_the_tree_to_error_and_back(emulation: Emulation, tmp_path: Path) -> None:
    from homing.missions.compiler import compile_mission
    from homing.missions.runner import Runner

    (tmp_path / "guard.yaml").write_text(GUARD_MISSION)
    robot = open_robot(emulation.robot_file)
    seen: list[tuple[float, str, int]] = []

    def tick(runner: Runner) -> None:
        t = runner.now - runner.start
        if 1.0 <= t < 1.1:
            emulation.unplug("base")
        if 3.0 <= t < 3.1:
            emulation.replug("base")
        seen.append((t, runner.read("/mission/state"), emulation.base.speed))

    try:
        runner = Runner(compile_mission(tmp_path / "guard.yaml"), robot, until=7.0, on_tick=tick)
        result = runner.run()
    finally:
        robot.close()
    assert result.reason == "time_limit"
    states = [s for _, s, _ in seen]
    first_error = states.index("Error")
    assert states[0] == "Undocking" and 1.0 < seen[first_error][0] < 2.0  # the base's silence is seen in 0.3 s
    back = states.index("Undocking", first_error)
    assert seen[back][0] < 6.5  # the base is opened again and the mission resumes
    assert seen[-1][2] == -50  # driving again at −0.05 m/s


def test_the_bundled_example_robot_file_is_valid() -> None:
    from homing.robot import hardware

    config = load_robot(Path(hardware.__file__).parent / "robot.example.yaml")
    assert config.base.port == "/dev/kobuki" and config.lidar.port == "/dev/rplidar"
    assert config.camera is not None and config.camera.source == 0 and config.camera.rate == 5.0
    assert config.computer_battery == Path("/sys/class/power_supply/BAT0")
