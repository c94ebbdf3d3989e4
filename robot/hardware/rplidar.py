"""The RPLIDAR A1 over its serial protocol: start the motor and the scan, assemble 360° scans.

Why not a driver library: of those on PyPI, ``rplidar`` (SkoltechRobotics,
0.9.2) and ``rplidar-roboticia`` have not been released since 2017,
``pyrplidar`` since 2019; ``adafruit-circuitpython-rplidar`` is maintained
but pulls in Adafruit's board-support stack (Blinka, PlatformDetect,
pyftdi, pyusb, sysv_ipc: 13 packages) to read a serial port, and it raises
on the first node with bad check bits instead of resynchronising, so one
flipped bit on the line ends the scan loop; ``lds2d`` is alpha and stamps
nothing; ``pyrplidarsdk`` binds the C++ SDK for one Python version. The
protocol is small and documented (:mod:`homing.robot.hardware.rplidar_protocol`),
so it is spoken here over pyserial.

:class:`RPLidar` on (re)connect: motor on (DTR low), STOP, GET_HEALTH
(an Error status is reset once; a garbled answer is asked for again,
three times in all), then SCAN; a thread parses the node
stream and keeps the latest assembled :class:`~homing.robot.types.Scan`,
stamped on the adapter's clock when its first node arrived.
"""

from __future__ import annotations

import time
from collections.abc import Callable

import serial  # type: ignore[import-untyped]
from homing.robot.hardware import rplidar_protocol as rp
from homing.robot.hardware.serial_device import DeviceError, SerialDevice
from homing.robot.turtlebot import LIDAR_RANGE_MAX, LIDAR_RANGE_MIN
from homing.robot.types import Pose2, Scan

SILENCE = 1.0  # [s] more than five revolutions without a byte: the lidar is lost
REPLY_TIMEOUT = 0.3  # [s] for GET_HEALTH's answer (the A1 answers within milliseconds; a cut reply is asked again)
HANDSHAKE_TIME = 3.0  # [s] ask for the health again until this long has passed (a noisy line garbles replies)


class LidarError(DeviceError):
    """The lidar answered, but not as an RPLIDAR does (or reports a hardware error)."""


class RPLidar(SerialDevice):
    """An RPLIDAR A1 on a serial port (the adapter's lidar)."""

    def __init__(self, port: str, now: Callable[[], float], baud: int = rp.BAUD,
                 laser_pose: Pose2 | None = None, range_min: float = LIDAR_RANGE_MIN,
                 range_max: float = LIDAR_RANGE_MAX):
        super().__init__("lidar", port, baud, now, silence=SILENCE)
        self.reader = rp.NodeReader()
        self.assembler = rp.ScanAssembler(range_min, range_max, laser_pose or Pose2())
        self.scan: Scan | None = None
        self.scans = 0
        self.health: tuple[int, int] | None = None

    def on_connect(self) -> None:
        ser = self._serial
        if ser is None:
            return
        _set_dtr(ser, False)  # A1: the USB adapter's DTR drives MOTOCTL; low spins the motor
        try:
            self.health = self._handshake(ser)
            if self.health[0] == rp.HEALTH_ERROR:
                ser.write(rp.request(rp.RESET))
                time.sleep(0.01)
                self.health = self._handshake(ser)
                if self.health[0] == rp.HEALTH_ERROR:
                    raise LidarError(f"hardware error {self.health[1]} after a reset")
            self.reader.reset()
            ser.write(rp.request(rp.SCAN))
        except (serial.SerialException, OSError):
            self.connected = False
        with self.lock:
            self.assembler._nodes.clear()

    def _handshake(self, ser: serial.Serial) -> tuple[int, int]:
        """STOP, flush, GET_HEALTH; asked again for HANDSHAKE_TIME seconds (a noisy line can garble replies)."""
        deadline = time.monotonic() + HANDSHAKE_TIME
        while True:
            ser.write(rp.request(rp.STOP))
            time.sleep(0.002)
            ser.reset_input_buffer()
            try:
                return self._health(ser)
            except LidarError:
                if time.monotonic() >= deadline:
                    raise

    def _health(self, ser: serial.Serial) -> tuple[int, int]:
        ser.write(rp.request(rp.GET_HEALTH))
        deadline = time.monotonic() + REPLY_TIMEOUT
        buf = b""
        while time.monotonic() < deadline:
            buf += ser.read(max(1, ser.in_waiting))
            i = buf.find(bytes((rp.SYNC, rp.SYNC2)))
            if i >= 0 and len(buf) >= i + rp.DESCRIPTOR_SIZE + rp.HEALTH_SIZE:
                length, _, kind = rp.parse_descriptor(buf[i : i + rp.DESCRIPTOR_SIZE])
                if kind != rp.TYPE_HEALTH or length != rp.HEALTH_SIZE:
                    raise LidarError(f"unexpected reply to GET_HEALTH (type 0x{kind:02x})")
                data = buf[i + rp.DESCRIPTOR_SIZE : i + rp.DESCRIPTOR_SIZE + rp.HEALTH_SIZE]
                return data[0], data[1] | (data[2] << 8)
        raise LidarError("no answer to GET_HEALTH: is this an RPLIDAR?")

    def on_bytes(self, chunk: bytes, stamp: float) -> None:
        nodes = self.reader.feed(chunk, stamp)
        if not nodes:
            return
        with self.lock:
            for scan in self.assembler.add(nodes):
                self.scan = scan
                self.scans += 1

    def stop_scan(self) -> None:
        """STOP and motor off (DTR high), before closing."""
        self.write(rp.request(rp.STOP))
        if self._serial is not None:
            _set_dtr(self._serial, True)

    def close(self) -> None:
        self.stop_scan()
        super().close()

    def latest(self) -> Scan | None:
        with self.lock:
            return self.scan


def _set_dtr(ser: serial.Serial, level: bool) -> None:
    try:
        ser.dtr = level
    except (serial.SerialException, OSError):
        pass  # a pseudo-terminal (the emulator) has no modem lines
