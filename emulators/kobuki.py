"""The Kobuki base's firmware, as seen from its serial port, over the simulator's physics.

Every 20 ms the emulator sends one feedback packet built from the simulated
robot: basic sensor data (firmware timestamp [ms]; bumpers; wheel drops,
cliffs and buttons as injected; both wheels' encoder ticks, wrapping at
65536; PWM; charger state and source; battery voltage [0.1 V]), the dock
IR codes per receiver, and the gyro (heading [0.01°], rate [0.01°/s]). The
encoders count the wheel motion the simulator's odometry measured (slip
included) and the gyro reports its heading, so the adapter reconstructs the
same odometry the simulator's adapter gives, up to the protocol's
quantisation. Commands it reads: base control (speed [mm/s], radius [mm],
held until replaced, as the firmware does) and request-extra (answered with
hardware/firmware versions and a unique id in the next packet).

A base control command reaches the wheels ``dead_time`` after it arrives:
the real base's firmware (1.2.0) shows about 200 ms between a command and
the first change in its odometry (measured by a user from a rosbag,
yujinrobot/kobuki#389; the firmware's source is not public), so the
controllers are tried against the base's real reaction time.
"""

from __future__ import annotations

import math
import struct
from collections import deque

from homing.robot.frames import wrap_angle
from homing.robot.hardware import kobuki_protocol as kp
from homing.robot.hardware.kobuki import charger_byte
from homing.robot.turtlebot import WHEEL_RADIUS
from homing.robot.types import Observation, Pose2

FIRMWARE = (1, 2, 0)  # major, minor, patch
HARDWARE = (1, 0, 4)
PWM_FULL = 0.7  # [m/s] a wheel at this speed runs at 100 % PWM
DEAD_TIME = 0.2  # [s] from a base control command's arrival to the wheels' response (yujinrobot/kobuki#389)


class KobukiFirmware:
    """The base's side of the protocol: commands in, feedback packets out (no port, no clock)."""

    def __init__(self, bias: float = kp.WHEEL_BIAS, wheel_radius: float = WHEEL_RADIUS,
                 dead_time: float = DEAD_TIME):
        self.bias = bias
        self.wheel_radius = wheel_radius
        self.dead_time = dead_time  # [s]
        self.reader = kp.PacketReader()
        self.speed, self.radius = 0, 0  # the command the wheels run at
        self._pending: deque[tuple[float, int, int]] = deque()  # (arrival [s], speed, radius) not yet applied
        self.commands = 0
        self.extra = 0  # request-extra flags to answer in the next packet
        self.ticks = [0.0, 0.0]  # [ticks] left, right, unwrapped
        self.wheel_drop = 0
        self.cliff = 0
        self.buttons = 0
        self._odom: Pose2 | None = None

    def receive(self, data: bytes, now: float = 0.0) -> None:
        """Parse command bytes from the host, arrived at ``now`` [s]; base control takes effect ``dead_time`` later."""
        for payload in self.reader.feed(data):
            parts, _ = kp.split_sub_payloads(payload)
            for ident, body in parts:
                if ident == kp.BASE_CONTROL and len(body) == 4:
                    speed, radius = struct.unpack("<hh", body)
                    self._pending.append((now, speed, radius))
                    self.commands += 1
                elif ident == kp.REQUEST_EXTRA and len(body) == 2:
                    self.extra |= struct.unpack("<H", body)[0]

    def velocity(self, now: float = math.inf) -> tuple[float, float]:
        """The body velocity (v [m/s], ω [rad/s]) the wheels run at at ``now`` [s] (the commands due by then)."""
        while self._pending and self._pending[0][0] + self.dead_time <= now:
            _, self.speed, self.radius = self._pending.popleft()
        left, right = kp.wheel_speeds(self.speed, self.radius, self.bias)
        return 0.5 * (left + right), (right - left) / self.bias

    def feedback(self, obs: Observation, time_ms: int) -> bytes:
        """One feedback packet for the simulated robot's observation ``obs`` at firmware time ``time_ms``."""
        pose = obs.odom.pose
        if self._odom is not None:
            d = self._odom.between(pose)
            dth = wrap_angle(pose.theta - self._odom.theta)
            chord = math.copysign(math.hypot(d.x, d.y), d.x)
            ds = chord if abs(dth) < 1e-9 else chord * (dth / 2) / math.sin(dth / 2)
            per_tick = kp.TICK_TO_RAD * self.wheel_radius  # [m]
            self.ticks[0] += (ds - dth * self.bias / 2) / per_tick
            self.ticks[1] += (ds + dth * self.bias / 2) / per_tick
        self._odom = pose
        left, right = kp.wheel_speeds(self.speed, self.radius, self.bias)
        b = obs.bumpers
        basic = kp.BasicSensorData(
            timestamp=time_ms & 0xFFFF,
            bumper=(kp.BUMPER_LEFT if b.left else 0) | (kp.BUMPER_CENTRE if b.centre else 0)
            | (kp.BUMPER_RIGHT if b.right else 0),
            wheel_drop=self.wheel_drop, cliff=self.cliff,
            left_encoder=math.floor(self.ticks[0]) & 0xFFFF, right_encoder=math.floor(self.ticks[1]) & 0xFFFF,
            left_pwm=_pwm(left), right_pwm=_pwm(right), buttons=self.buttons,
            charger=charger_byte(obs.battery), battery=min(255, max(0, round(obs.battery.voltage * 10))),
        )  # fmt: skip
        ir = obs.dock_ir
        parts = [
            basic.encode(),
            kp.DockingIR(int(ir.right), int(ir.centre), int(ir.left)).encode(),
            kp.InertialSensor(_centi_degrees(pose.theta), _centi_degrees(obs.odom.twist.omega, wrap=False)).encode(),
        ]
        if self.extra & kp.REQUEST_HARDWARE_VERSION:
            parts.append(kp.version_payload(kp.HARDWARE_VERSION, *HARDWARE))
        if self.extra & kp.REQUEST_FIRMWARE_VERSION:
            parts.append(kp.version_payload(kp.FIRMWARE_VERSION, *FIRMWARE))
        if self.extra & kp.REQUEST_UNIQUE_DEVICE_ID:
            parts.append(kp.sub_payload(kp.UNIQUE_DEVICE_ID, bytes(range(12))))
        self.extra = 0
        return kp.encode_packet(parts)


def _centi_degrees(rad: float, wrap: bool = True) -> int:
    deg = math.degrees(wrap_angle(rad) if wrap else rad)
    return int(max(kp.SHORT_MIN, min(kp.SHORT_MAX, round(deg * 100.0))))


def _pwm(speed: float) -> int:
    return int(max(-100, min(100, round(100.0 * speed / PWM_FULL))))
