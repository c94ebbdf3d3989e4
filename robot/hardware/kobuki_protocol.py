"""The Kobuki base's serial protocol: packets, sub-payloads and the base control command.

After the Kobuki protocol specification (kobuki_driver's "Appendix: Protocol
Specification", kobuki.readthedocs.io "Serial Protocol") and kobuki_core's
driver (``packet_finder.cpp``, ``core_sensors.hpp``, ``diff_drive.cpp``).
Both directions use one framing, 115200 baud 8N1::

    0xAA 0x55 | length | sub-payload … sub-payload | checksum
    sub-payload = id (1 byte) | size (1 byte) | data (size bytes)

``length`` counts the payload bytes only; ``checksum`` is the XOR of the
length and every payload byte, so the XOR of everything after the headers
is zero. Multi-byte fields are little-endian (LSB first). The base streams
one feedback packet every 20 ms (50 Hz): basic sensor data (id 1), docking
IR (3), inertial sensor (4), cliff (5), current (6) and general purpose
input (16), plus the version and controller replies (10, 11, 19, 21) when
asked for them. The host sends commands: base control (id 1: speed [mm/s],
radius [mm]), sound, request-extra, general purpose output…

:class:`PacketReader` finds packets in a byte stream the way kobuki_core's
``PacketFinder`` does, and counts what it throws away: a bad checksum drops
the packet, garbage between packets and a packet cut short by a new header
are skipped byte by byte until the next 0xAA 0x55 (a resynchronisation).
Nothing here touches a port: these are pure functions over bytes, shared by
the adapter (:mod:`homing.robot.hardware.kobuki`) and the emulator.
"""

from __future__ import annotations

import math
import struct
from collections.abc import Iterable
from dataclasses import dataclass, field

from homing.robot.hardware.resync import ResyncBuffer, ResyncStats

HEADER = b"\xaa\x55"
MAX_PAYLOAD = 255  # [bytes] the length field is one byte
FEEDBACK_PERIOD = 0.02  # [s] the base streams feedback at 50 Hz
BAUD = 115200

# Feedback sub-payload ids (kobuki_core payload_headers.hpp)
BASIC_SENSOR_DATA = 1
DOCKING_IR = 3
INERTIAL_SENSOR = 4
CLIFF = 5
CURRENT = 6
HARDWARE_VERSION = 10
FIRMWARE_VERSION = 11
RAW_GYRO = 13
GP_INPUT = 16
UNIQUE_DEVICE_ID = 19
CONTROLLER_INFO = 21

# Command sub-payload ids
BASE_CONTROL = 1
SOUND = 3
SOUND_SEQUENCE = 4
REQUEST_EXTRA = 9
GP_OUTPUT = 12
SET_CONTROLLER_GAIN = 13
GET_CONTROLLER_GAIN = 14

# Request-extra flags
REQUEST_HARDWARE_VERSION = 0x01
REQUEST_FIRMWARE_VERSION = 0x02
REQUEST_UNIQUE_DEVICE_ID = 0x08

# Basic sensor data flags
BUMPER_RIGHT, BUMPER_CENTRE, BUMPER_LEFT = 0x01, 0x02, 0x04
WHEEL_DROP_RIGHT, WHEEL_DROP_LEFT = 0x01, 0x02
CLIFF_RIGHT, CLIFF_CENTRE, CLIFF_LEFT = 0x01, 0x02, 0x04
BUTTON_0, BUTTON_1, BUTTON_2 = 0x01, 0x02, 0x04
CHARGER_ADAPTER = 0x10  # source bit: set for the wall adapter, clear for the dock
CHARGER_STATE_MASK = 0x0F
DISCHARGING, CHARGED, CHARGING = 0x00, 0x02, 0x06  # charger & CHARGER_STATE_MASK

# Kinematics and units (kobuki_core diff_drive.cpp)
WHEEL_BIAS = 0.230  # [m] wheel separation the firmware assumes for speed/radius
TICK_TO_RAD = 0.002436916871363930187454  # [rad] wheel turn per encoder tick (2578.33 ticks/turn)
PURE_ROTATION_RADIUS = 1  # [mm] radius value meaning "turn in place"
SHORT_MIN, SHORT_MAX = -32768, 32767


def checksum(body: bytes) -> int:
    """XOR of ``body`` (the length byte and the payload)."""
    cs = 0
    for b in body:
        cs ^= b
    return cs


def sub_payload(ident: int, data: bytes) -> bytes:
    """One sub-payload: id, size, data."""
    if len(data) > MAX_PAYLOAD - 2:
        raise ValueError(f"sub-payload {ident} too long: {len(data)} bytes")
    return bytes((ident, len(data))) + data


def encode_packet(sub_payloads: Iterable[bytes]) -> bytes:
    """Frame sub-payloads into one packet: headers, length, payload, checksum."""
    payload = b"".join(sub_payloads)
    if not 0 < len(payload) <= MAX_PAYLOAD:
        raise ValueError(f"payload must hold 1..{MAX_PAYLOAD} bytes, not {len(payload)}")
    body = bytes((len(payload),)) + payload
    return HEADER + body + bytes((checksum(body),))


def split_sub_payloads(payload: bytes) -> tuple[list[tuple[int, bytes]], bool]:
    """The (id, data) sub-payloads of a packet's payload, and whether it split cleanly.

    A size running past the payload's end stops the split (the rest is
    dropped, as kobuki_core's ``fixPayload`` does) and returns False.
    """
    out: list[tuple[int, bytes]] = []
    i = 0
    while i < len(payload):
        if i + 2 > len(payload) or i + 2 + payload[i + 1] > len(payload):
            return out, False
        size = payload[i + 1]
        out.append((payload[i], bytes(payload[i + 2 : i + 2 + size])))
        i += 2 + size
    return out, True


# --- feedback sub-payloads -------------------------------------------------------------------------
_BASIC = struct.Struct("<HBBBHHbbBBBB")  # 15 bytes


@dataclass(frozen=True)
class BasicSensorData:
    """Sub-payload 1: the base's core sensors, every 20 ms.

    ``timestamp`` [ms] wraps at 65536; encoders [ticks] wrap at 65536 (one
    tick = :data:`TICK_TO_RAD` of wheel turn); PWM [%] signed; ``battery``
    [0.1 V]; ``charger``: state in the low nibble (:data:`DISCHARGING`,
    :data:`CHARGED`, :data:`CHARGING`), :data:`CHARGER_ADAPTER` for the wall
    adapter. Flags: see the ``BUMPER_*``, ``WHEEL_DROP_*``, ``CLIFF_*``,
    ``BUTTON_*`` constants.
    """

    timestamp: int = 0
    bumper: int = 0
    wheel_drop: int = 0
    cliff: int = 0
    left_encoder: int = 0
    right_encoder: int = 0
    left_pwm: int = 0
    right_pwm: int = 0
    buttons: int = 0
    charger: int = DISCHARGING
    battery: int = 165
    over_current: int = 0

    def encode(self) -> bytes:
        return sub_payload(BASIC_SENSOR_DATA, _BASIC.pack(
            self.timestamp & 0xFFFF, self.bumper, self.wheel_drop, self.cliff, self.left_encoder & 0xFFFF,
            self.right_encoder & 0xFFFF, self.left_pwm, self.right_pwm, self.buttons, self.charger, self.battery,
            self.over_current,
        ))  # fmt: skip

    @staticmethod
    def decode(data: bytes) -> BasicSensorData:
        return BasicSensorData(*_BASIC.unpack(data))

    @property
    def voltage(self) -> float:
        """Battery voltage [V]."""
        return self.battery / 10.0


@dataclass(frozen=True)
class DockingIR:
    """Sub-payload 3: the dock IR codes each receiver sees (kobuki_msgs/DockInfraRed order: right, centre, left)."""

    right: int = 0
    centre: int = 0
    left: int = 0

    def encode(self) -> bytes:
        return sub_payload(DOCKING_IR, bytes((self.right, self.centre, self.left)))

    @staticmethod
    def decode(data: bytes) -> DockingIR:
        return DockingIR(data[0], data[1], data[2])


_INERTIA = struct.Struct("<hh3B")


@dataclass(frozen=True)
class InertialSensor:
    """Sub-payload 4: the factory-calibrated gyro's heading ``angle`` [0.01°] and ``angle_rate`` [0.01°/s]."""

    angle: int = 0
    angle_rate: int = 0
    acc: tuple[int, int, int] = (0, 0, 0)

    def encode(self) -> bytes:
        return sub_payload(INERTIAL_SENSOR, _INERTIA.pack(self.angle, self.angle_rate, *self.acc))

    @staticmethod
    def decode(data: bytes) -> InertialSensor:
        angle, rate, a0, a1, a2 = _INERTIA.unpack(data)
        return InertialSensor(angle, rate, (a0, a1, a2))

    @property
    def heading(self) -> float:
        """The gyro's heading [rad]."""
        return math.radians(self.angle / 100.0)

    @property
    def rate(self) -> float:
        """The yaw rate [rad/s]."""
        return math.radians(self.angle_rate / 100.0)


FEEDBACK_SIZES = {BASIC_SENSOR_DATA: 15, DOCKING_IR: 3, INERTIAL_SENSOR: 7, CLIFF: 6, CURRENT: 2,
                  HARDWARE_VERSION: 4, FIRMWARE_VERSION: 4, GP_INPUT: 16, UNIQUE_DEVICE_ID: 12,
                  CONTROLLER_INFO: 13}  # fmt: skip


def version_payload(ident: int, major: int, minor: int, patch: int) -> bytes:
    """Sub-payload 10 or 11: a hardware or firmware version (patch, minor, major, 0)."""
    return sub_payload(ident, bytes((patch, minor, major, 0)))


# --- commands --------------------------------------------------------------------------------------
def _bound(value: float) -> int:
    """kobuki_core's ``DiffDrive::bound``: clamp to a signed short (rounded here, not truncated)."""
    return int(min(SHORT_MAX, max(SHORT_MIN, round(value))))


def speed_radius(v: float, omega: float, bias: float = WHEEL_BIAS) -> tuple[int, int]:
    """The base control command (speed [mm/s], radius [mm]) for a body velocity ``v`` [m/s], ``omega`` [rad/s].

    kobuki_core's ``DiffDrive::velocityCommands``: radius 0 drives straight;
    radius 1 turns in place with speed ω·b/2; otherwise speed is the outer
    wheel's, (R ± b/2)·ω. Bounded to signed shorts.
    """
    eps = 1e-4
    if abs(omega) < eps:
        return _bound(1000.0 * v), 0
    radius = 1000.0 * v / omega
    if abs(v) < eps or abs(radius) <= 1.0:
        return _bound(1000.0 * bias * omega / 2.0), PURE_ROTATION_RADIUS
    half = 1000.0 * bias / 2.0
    speed = (radius + half) * omega if radius > 0 else (radius - half) * omega
    return _bound(speed), _bound(radius)


def wheel_speeds(speed: int, radius: int, bias: float = WHEEL_BIAS) -> tuple[float, float]:
    """The firmware's reading of a base control command: (left, right) wheel speeds [m/s].

    The inverse of :func:`speed_radius` (up to its rounding).
    """
    s = speed / 1000.0  # [m/s]
    half = bias / 2.0
    if radius == 0:
        return s, s
    if radius == PURE_ROTATION_RADIUS:
        return -s, s
    r = radius / 1000.0  # [m]
    omega = s / (r + half) if r > 0 else s / (r - half)
    return (r - half) * omega, (r + half) * omega


def base_control(speed: int, radius: int) -> bytes:
    """Sub-payload 1 of a command: speed [mm/s] and radius [mm], signed shorts."""
    return sub_payload(BASE_CONTROL, struct.pack("<hh", speed, radius))


def request_extra(flags: int) -> bytes:
    """Sub-payload 9: ask for hardware/firmware versions or the unique device id once."""
    return sub_payload(REQUEST_EXTRA, struct.pack("<H", flags))


# --- finding packets in a stream ---------------------------------------------------------------------
@dataclass
class StreamStats(ResyncStats):
    """What a reader made of its byte stream so far (and bytes fed, skipped, resynchronisations)."""

    packets: int = 0  # packets with a good checksum
    checksum_errors: int = 0  # framed packets dropped for a bad checksum
    bad_payloads: int = 0  # good-checksum packets whose sub-payloads did not split cleanly


@dataclass
class PacketReader:
    """Finds packets in a byte stream: ``feed(chunk)`` returns the payloads completed by it.

    A state machine like kobuki_core's ``PacketFinder``: wait for 0xAA 0x55,
    read the length, then length + 1 bytes, and check the XOR. A bad
    checksum drops the packet and restarts the search one byte after its
    header (a header inside garbage is not taken on trust); a length of 0
    is impossible and counts as lost sync. Each run of skipped bytes between
    two good packets counts as one resynchronisation.
    """

    stats: StreamStats = field(default_factory=StreamStats)
    _rx: ResyncBuffer = field(default_factory=ResyncBuffer)

    def feed(self, chunk: bytes) -> list[bytes]:
        self.stats.bytes += len(chunk)
        buf = self._rx.buf
        buf += chunk
        out: list[bytes] = []
        while True:
            start = buf.find(HEADER)
            if start < 0:
                keep = 1 if buf.endswith(HEADER[:1]) else 0  # a header split across chunks
                self._skip(len(buf) - keep)
                return out
            self._skip(start)
            if len(buf) < 3:
                return out
            length = buf[2]
            if length == 0:
                self._skip(1)
                continue
            if len(buf) < 4 + length:
                return out
            body = bytes(buf[2 : 4 + length])
            if checksum(body) != 0:
                self.stats.checksum_errors += 1
                self._skip(1)
                continue
            del buf[: 4 + length]
            self.stats.packets += 1
            self._rx.synced()
            out.append(body[1:-1])

    def _skip(self, n: int) -> None:
        self._rx.skip(n, self.stats)
