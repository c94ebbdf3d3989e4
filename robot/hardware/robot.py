"""The real TurtleBot 2 behind the adapter contract: Kobuki base, RPLIDAR A1, camera, on the wall clock.

``open_robot("robot.yaml")`` opens every device the robot file names and
returns a :class:`HardwareRobot` (a :class:`homing.robot.RobotAdapter`).
Opening fails with a one-line :class:`~homing.errors.UserError` at the
port's place in the robot file when a port is missing or busy, or when no
Kobuki feedback or lidar scan arrives in time (a wrong port or baud rate).

At run time the devices are read by their own threads; :meth:`observe`
gathers the latest of each and never blocks. A device lost mid-run (its
port fails, or it falls silent) is named in ``Observation.devices_lost``,
and while any device is lost the base is sent zero whatever the mission
commands: a robot blind without its lidar must not drive on. The devices'
threads reopen lost ports, so a device that comes back is picked up again
and the commands flow once more.

The on-board computer's battery is read from Linux's power_supply class
(``capacity``, ``status``, ``voltage_now`` in a folder such as
``/sys/class/power_supply/BAT0``), at most once a second.
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

import numpy as np
from homing.robot.frames import R_BODY_FROM_OPTICAL, homogeneous, rot_z
from homing.robot.hardware.camera import CameraError, UvcCamera, check_calibration
from homing.robot.hardware.kobuki import KobukiBase
from homing.robot.hardware.robot_file import RobotConfig, Where, load_robot
from homing.robot.hardware.rplidar import RPLidar
from homing.robot.hardware.serial_device import DeviceError
from homing.robot.turtlebot import RobotLimits
from homing.robot.types import BatteryState, ChargingSource, ChargingState, Observation, Twist2

from homing.errors import UserError

FIRST_DATA_TIMEOUT = 3.0  # [s] to hear from the base and see a scan after opening
BATTERY_PERIOD = 1.0  # [s] between reads of the computer's battery


class WallClock:
    """Monotonic seconds since the adapter opened (the hardware's clock)."""

    def __init__(self) -> None:
        self.t0 = time.monotonic()

    def now(self) -> float:
        return time.monotonic() - self.t0


def read_power_supply(folder: Path, on_dock: bool) -> BatteryState | None:
    """A Linux power_supply battery as the contract's reading (None if it cannot be read)."""
    try:
        percent = float((folder / "capacity").read_text().strip())
        status = (folder / "status").read_text().strip()
    except (OSError, ValueError):
        return None
    try:
        voltage = float((folder / "voltage_now").read_text().strip()) / 1e6  # [µV] → [V]
    except (OSError, ValueError):
        voltage = 0.0
    if status == "Charging":
        source = ChargingSource.DOCK if on_dock else ChargingSource.ADAPTER
        state = ChargingState.DOCKING_CHARGING if on_dock else ChargingState.ADAPTER_CHARGING
    elif status == "Full" and on_dock:
        source, state = ChargingSource.DOCK, ChargingState.DOCKING_CHARGED
    else:
        source, state = ChargingSource.NONE, ChargingState.DISCHARGING
    return BatteryState(voltage, min(100.0, max(0.0, percent)), source, state)


class HardwareRobot:
    """A TurtleBot 2 on serial ports and a camera (implements :class:`homing.robot.RobotAdapter`)."""

    def __init__(self, config: RobotConfig):
        self.config = config
        self._clock = WallClock()
        self._limits = RobotLimits()
        now = self._clock.now
        b, li = config.base, config.lidar
        self.base = KobukiBase(b.port, now, b.baud, b.wheel_separation, b.wheel_radius, b.cmd_timeout)
        self.lidar = RPLidar(li.port, now, li.baud, li.pose, li.range_min, li.range_max)
        self.camera: UvcCamera | None = None
        self._deadline: float | None = None
        self._battery: BatteryState | None = None
        self._battery_read = -float("inf")
        self._was_lost: tuple[str, ...] = ()
        self._cmd = Twist2()
        opened: list = []
        try:
            for device, at in ((self.base, b.at), (self.lidar, li.at)):
                _open(device, at)
                opened.append(device)
            if config.camera is not None:
                c = config.camera
                cal = check_calibration(c.info, c.info_at.file, c.info_at.line, c.info_at.col)
                x, y, z, yaw = c.pose
                mount = homogeneous(rot_z(yaw) @ R_BODY_FROM_OPTICAL, np.array([x, y, z]))
                self.camera = UvcCamera(c.source, cal, mount, now, c.rate, delay=c.delay)
                try:
                    self.camera.open()
                except CameraError as err:
                    raise UserError(f"camera: {err}", c.at.file, c.at.line, c.at.col) from None
                opened.append(self.camera)
            self._wait_for_data()
        except BaseException:
            for device in opened:
                device.close()
            raise

    def _wait_for_data(self) -> None:
        deadline = time.monotonic() + FIRST_DATA_TIMEOUT
        while time.monotonic() < deadline and not (self.base.ready and self.lidar.latest() is not None):
            time.sleep(0.02)
        b, li = self.config.base, self.config.lidar
        if not self.base.ready:
            raise UserError(f"base port {b.port}: no Kobuki feedback within {FIRST_DATA_TIMEOUT:g} s "
                            f"(wrong port or baud rate?)", b.at.file, b.at.line, b.at.col)  # fmt: skip
        if self.lidar.latest() is None:
            raise UserError(f"lidar port {li.port}: no scan within {FIRST_DATA_TIMEOUT:g} s "
                            f"(wrong port or baud rate?)", li.at.file, li.at.line, li.at.col)  # fmt: skip

    # --- the adapter contract ----------------------------------------------------------------
    @property
    def clock(self) -> WallClock:
        return self._clock

    @property
    def limits(self) -> RobotLimits:
        return self._limits

    def devices_lost(self) -> tuple[str, ...]:
        devices = [self.base, self.lidar] + ([self.camera] if self.camera is not None else [])
        return tuple(d.name for d in devices if d.lost)

    def observe(self) -> Observation:
        t = self._clock.now()
        lost = self.devices_lost()
        if lost and lost != self._was_lost:
            self.base.stop()
            print(f"[{t:8.2f} s] lost: {', '.join(lost)}; base stopped", file=sys.stderr)
        elif self._was_lost and not lost:
            print(f"[{t:8.2f} s] devices back: {', '.join(self._was_lost)}", file=sys.stderr)
        self._was_lost = lost
        with self.base.lock:
            odom, bumpers, ir = self.base.odometry(), self.base.bumpers, self.base.dock_ir
            battery, switches = self.base.battery, self.base.switches
        return Observation(
            stamp=t, odom=odom, scan=self.lidar.latest(),
            image=self.camera.latest() if self.camera is not None else None,
            bumpers=bumpers, dock_ir=ir, battery=battery, computer_battery=self._computer_battery(t, battery),
            switches=switches, devices_lost=lost,
        )  # fmt: skip

    def command(self, v: float, omega: float) -> Twist2:
        """Clip and send (v [m/s], ω [rad/s]); zero is sent instead while a device is lost."""
        cv, cw = self._limits.clip(v, omega)
        if self.devices_lost():
            cv, cw = 0.0, 0.0
        self.base.drive(cv, cw)
        self._cmd = Twist2(cv, cw)
        return self._cmd

    def step(self, dt: float) -> None:
        """Sleep until ``dt`` [s] after the last step's deadline (no drift; never sleeps to catch up)."""
        now = time.monotonic()
        deadline = (self._deadline if self._deadline is not None else now) + dt
        if deadline < now:
            deadline = now  # fell behind: start counting again from here
        time.sleep(max(0.0, deadline - now))
        self._deadline = deadline

    def close(self) -> None:
        """Stop the base, stop the lidar's motor, release every device."""
        self.base.stop()
        for device in (self.camera, self.lidar, self.base):
            if device is not None:
                device.close()

    def _computer_battery(self, t: float, base: BatteryState) -> BatteryState | None:
        folder = self.config.computer_battery
        if folder is None:
            return None
        if t - self._battery_read >= BATTERY_PERIOD:
            self._battery_read = t
            self._battery = read_power_supply(folder, base.on_dock)
        return self._battery


def _open(device: KobukiBase | RPLidar, at: Where) -> None:
    try:
        device.open()
    except DeviceError as err:
        raise UserError(f"{device.name} port {device.port}: {err}", at.file, at.line, at.col) from None


def open_robot(path: str | Path) -> HardwareRobot:
    """Read the robot file and open its devices (UserError, one line, if any cannot be opened)."""
    return HardwareRobot(load_robot(path))
