"""The Kobuki base over its serial protocol: odometry, bumpers, dock IR, battery in; velocity out.

:class:`KobukiBase` reads the feedback the base streams at 50 Hz
(:mod:`homing.robot.hardware.kobuki_protocol`) in a thread and keeps the
latest state in the contract's types; :meth:`KobukiBase.drive` sends the
base control command. Odometry follows kobuki_core with
``use_imu_heading`` (kobuki_node's default), as the simulator models it
(:mod:`homing.sim.odometry`): the heading is the gyro's, taken relative to
its first reading; the distance is the mean of the two wheels' encoder
ticks, each difference taken as a signed 16-bit number so the counters'
wrap-around at 65536 is invisible; the pose integrates the distance along
the mean of the old and new headings. Speeds: the encoders' distance over
the firmware's own timestamp difference (ms, also 16-bit), the gyro's rate.

Battery: the voltage [0.1 V] becomes the contract's percentage with
Kobuki's formula (:func:`homing.robot.turtlebot.battery_percent`); the
charger byte's low nibble gives the charging state and its 0x10 bit the
source (dock or wall adapter), as kobuki_core's ``Battery`` reads them.

A command watchdog, as kobuki_node's ``cmd_vel_timeout``: if no command has
been given for ``cmd_timeout`` seconds the base is sent zero.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

from homing.robot.frames import wrap_angle
from homing.robot.hardware import kobuki_protocol as kp
from homing.robot.hardware.serial_device import SerialDevice
from homing.robot.turtlebot import WHEEL_RADIUS, battery_percent
from homing.robot.types import (
    IR,
    BaseSwitches,
    BatteryState,
    Bumpers,
    ChargingSource,
    ChargingState,
    DockIR,
    Odometry,
    Pose2,
    Twist2,
)

CMD_TIMEOUT = 0.6  # [s] kobuki_node's cmd_vel_timeout
SILENCE = 0.3  # [s] 15 missed feedback packets: the base is lost
IR_MASK = 0x3F  # the six dock codes


def ticks_delta(new: int, old: int) -> int:
    """Signed difference of two 16-bit counters (encoder ticks, ms timestamps): wrap-around is invisible."""
    d = (new - old) & 0xFFFF
    return d - 0x10000 if d >= 0x8000 else d


def battery_state(basic: kp.BasicSensorData) -> BatteryState:
    """The contract's battery reading from the base's voltage and charger byte."""
    state = basic.charger & kp.CHARGER_STATE_MASK
    voltage = basic.voltage
    if state == kp.CHARGING:
        charging = ChargingState.DOCKING_CHARGING
    elif state == kp.CHARGED:
        charging = ChargingState.DOCKING_CHARGED
    else:
        return BatteryState(voltage, battery_percent(voltage), ChargingSource.NONE, ChargingState.DISCHARGING)
    if basic.charger & kp.CHARGER_ADAPTER:
        source = ChargingSource.ADAPTER
        charging = ChargingState.ADAPTER_CHARGING if state == kp.CHARGING else ChargingState.ADAPTER_CHARGED
    else:
        source = ChargingSource.DOCK
    return BatteryState(voltage, battery_percent(voltage), source, charging)


def charger_byte(battery: BatteryState) -> int:
    """The charger byte a base in ``battery``'s state sends (the inverse of :func:`battery_state`)."""
    state = {ChargingState.DOCKING_CHARGING: kp.CHARGING, ChargingState.ADAPTER_CHARGING: kp.CHARGING,
             ChargingState.DOCKING_CHARGED: kp.CHARGED, ChargingState.ADAPTER_CHARGED: kp.CHARGED}.get(
        battery.state, kp.DISCHARGING)  # fmt: skip
    return state | (kp.CHARGER_ADAPTER if battery.source is ChargingSource.ADAPTER and state else 0)


def switches(basic: kp.BasicSensorData) -> BaseSwitches:
    b = basic.buttons
    return BaseSwitches(
        wheel_drop_left=bool(basic.wheel_drop & kp.WHEEL_DROP_LEFT),
        wheel_drop_right=bool(basic.wheel_drop & kp.WHEEL_DROP_RIGHT),
        cliff_left=bool(basic.cliff & kp.CLIFF_LEFT), cliff_centre=bool(basic.cliff & kp.CLIFF_CENTRE),
        cliff_right=bool(basic.cliff & kp.CLIFF_RIGHT),
        buttons=(bool(b & kp.BUTTON_0), bool(b & kp.BUTTON_1), bool(b & kp.BUTTON_2)),
    )  # fmt: skip


@dataclass
class KobukiOdometry:
    """Integrates encoder ticks and the gyro's heading into the pose of base_link in ``odom``."""

    wheel_radius: float = WHEEL_RADIUS  # [m]
    tick_to_rad: float = kp.TICK_TO_RAD  # [rad/tick]
    pose: Pose2 = Pose2()
    twist: Twist2 = Twist2()
    _ticks: tuple[int, int] | None = None
    _timestamp: int = 0
    _offset: float | None = None  # [rad] the gyro's first heading
    _heading: float = 0.0  # [rad]

    def update(self, basic: kp.BasicSensorData, inertia: kp.InertialSensor) -> Pose2:
        """Add one feedback packet's encoders and gyro; returns the new pose."""
        if self._ticks is None or self._offset is None:
            self._ticks, self._timestamp = (basic.left_encoder, basic.right_encoder), basic.timestamp
            self._offset = inertia.heading
            return self.pose
        dl = ticks_delta(basic.left_encoder, self._ticks[0])
        dr = ticks_delta(basic.right_encoder, self._ticks[1])
        dt = ticks_delta(basic.timestamp, self._timestamp) / 1000.0  # [s]
        self._ticks, self._timestamp = (basic.left_encoder, basic.right_encoder), basic.timestamp
        ds = 0.5 * (dl + dr) * self.tick_to_rad * self.wheel_radius  # [m]
        heading = wrap_angle(inertia.heading - self._offset)
        mid = self._heading + 0.5 * wrap_angle(heading - self._heading)
        p = self.pose
        self.pose = Pose2(p.x + ds * math.cos(mid), p.y + ds * math.sin(mid), heading)
        self._heading = heading
        self.twist = Twist2(ds / dt if dt > 0 else self.twist.v, inertia.rate)
        return self.pose


class KobukiBase(SerialDevice):
    """A Kobuki base on a serial port (the adapter's base half).

    ``now`` is the adapter's clock [s]. Read :meth:`odometry`,
    :attr:`bumpers`, :attr:`dock_ir`, :attr:`battery`, :attr:`switches`;
    command with :meth:`drive`. ``stats`` counts packets, checksum errors
    and resynchronisations.
    """

    def __init__(self, port: str, now: Callable[[], float], baud: int = kp.BAUD,
                 wheel_separation: float = kp.WHEEL_BIAS, wheel_radius: float = WHEEL_RADIUS,
                 cmd_timeout: float = CMD_TIMEOUT):
        super().__init__("base", port, baud, now, silence=SILENCE)
        self.wheel_separation = wheel_separation
        self.cmd_timeout = cmd_timeout
        self.reader = kp.PacketReader()
        self.odom = KobukiOdometry(wheel_radius=wheel_radius)
        self.odom_stamp = 0.0  # [s] adapter clock of the last feedback
        self.bumpers = Bumpers()
        self.dock_ir = DockIR()
        self.battery = BatteryState(0.0, 0.0)
        self.switches = BaseSwitches()
        self.basic: kp.BasicSensorData | None = None
        self.inertia: kp.InertialSensor | None = None
        self.versions: dict[int, bytes] = {}
        self.command = (0, 0)  # (speed [mm/s], radius [mm]) last sent
        self._command_time = -math.inf  # [s] when drive() was last called
        self._stopped_by_watchdog = False

    @property
    def stats(self) -> kp.StreamStats:
        return self.reader.stats

    @property
    def ready(self) -> bool:
        """True once a full feedback packet (sensors and gyro) has arrived."""
        return self.basic is not None and self.inertia is not None

    def odometry(self) -> Odometry:
        with self.lock:
            return Odometry(self.odom_stamp, self.odom.pose, self.odom.twist)

    def drive(self, v: float, omega: float) -> tuple[int, int]:
        """Send the base control command for (v [m/s], ω [rad/s]); returns (speed, radius) sent."""
        cmd = kp.speed_radius(v, omega, self.wheel_separation)
        self._command_time = self.now()
        self._stopped_by_watchdog = False
        self._send(cmd)
        return cmd

    def stop(self) -> None:
        self._send((0, 0))

    def _send(self, cmd: tuple[int, int]) -> None:
        self.command = cmd
        self.write(kp.encode_packet([kp.base_control(*cmd)]))

    def on_connect(self) -> None:
        self.reader = kp.PacketReader(stats=self.reader.stats)  # a new line: forget half a packet
        self.write(kp.encode_packet([kp.request_extra(
            kp.REQUEST_HARDWARE_VERSION | kp.REQUEST_FIRMWARE_VERSION | kp.REQUEST_UNIQUE_DEVICE_ID)]))

    def on_bytes(self, chunk: bytes, stamp: float) -> None:
        for payload in self.reader.feed(chunk):
            parts, clean = kp.split_sub_payloads(payload)
            if not clean:
                self.reader.stats.bad_payloads += 1
            with self.lock:
                self._apply(parts, stamp)
        if (not self._stopped_by_watchdog and self.command != (0, 0)
                and stamp - self._command_time > self.cmd_timeout):
            self._stopped_by_watchdog = True
            self.stop()

    def _apply(self, parts: list[tuple[int, bytes]], stamp: float) -> None:
        basic = inertia = None
        for ident, data in parts:
            if kp.FEEDBACK_SIZES.get(ident, -1) != len(data):
                if ident in kp.FEEDBACK_SIZES:
                    self.reader.stats.bad_payloads += 1
                continue  # unknown or mis-sized sub-payloads are skipped, as kobuki_core's fixPayload
            if ident == kp.BASIC_SENSOR_DATA:
                basic = kp.BasicSensorData.decode(data)
            elif ident == kp.INERTIAL_SENSOR:
                inertia = kp.InertialSensor.decode(data)
            elif ident == kp.DOCKING_IR:
                d = kp.DockingIR.decode(data)
                self.dock_ir = DockIR(IR(d.right & IR_MASK), IR(d.centre & IR_MASK), IR(d.left & IR_MASK))
            elif ident in (kp.HARDWARE_VERSION, kp.FIRMWARE_VERSION, kp.UNIQUE_DEVICE_ID):
                self.versions[ident] = data
        if basic is not None:
            self.basic = basic
            self.bumpers = Bumpers(left=bool(basic.bumper & kp.BUMPER_LEFT),
                                   centre=bool(basic.bumper & kp.BUMPER_CENTRE),
                                   right=bool(basic.bumper & kp.BUMPER_RIGHT))
            self.battery = battery_state(basic)
            self.switches = switches(basic)
        if inertia is not None:
            self.inertia = inertia
        if basic is not None and inertia is not None:
            self.odom.update(basic, inertia)
            self.odom_stamp = stamp
