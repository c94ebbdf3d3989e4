"""The RPLIDAR A1's side of its serial protocol, streaming the simulator's scans.

Requests it answers: GET_HEALTH (Good), GET_INFO (model A1, firmware 1.29),
GET_SAMPLERATE, SCAN and FORCE_SCAN (descriptor, then nodes until STOP),
STOP and RESET (silence). Requests with a payload (command byte ≥ 0x80,
e.g. the A2's motor PWM) are read whole and ignored, as an A1 does.

While scanning, each new simulated scan (5.5 Hz) is sent as one
revolution of 360 nodes spread evenly over the scan period, so bytes flow
as they do from the device (≈ 10 kB/s, within 115200 baud); the first node
carries the start flag. Rays with no return go out with distance 0.
"""

from __future__ import annotations

import struct

import numpy as np
from homing.robot.hardware import rplidar_protocol as rp
from homing.robot.turtlebot import LIDAR_RATE


class RplidarFirmware:
    """The lidar's side of the protocol: requests in, replies and nodes out (no port, no clock)."""

    def __init__(self, period: float = 1.0 / LIDAR_RATE):
        self.period = period  # [s] one revolution
        self.scanning = False
        self.requests: list[int] = []
        self._buf = bytearray()
        self._out = bytearray()
        self._nodes: list[bytes] = []
        self._sent = 0
        self._start = 0.0  # [s] when the current revolution began

    def receive(self, data: bytes) -> None:
        """Parse request bytes; queue the replies."""
        buf = self._buf
        buf += data
        while buf:
            if buf[0] != rp.SYNC:
                del buf[0]
                continue
            if len(buf) < 2:
                return
            cmd = buf[1]
            if cmd & 0x80:  # a request with a payload: size, payload, checksum
                if len(buf) < 3 or len(buf) < 4 + buf[2]:
                    return
                del buf[: 4 + buf[2]]
                self.requests.append(cmd)
                continue
            del buf[:2]
            self.requests.append(cmd)
            self._answer(cmd)

    def _answer(self, cmd: int) -> None:
        if cmd in (rp.STOP, rp.RESET):
            self.scanning = False
            self._nodes, self._sent = [], 0
        elif cmd == rp.GET_HEALTH:
            self._out += rp.health_reply()
        elif cmd == rp.GET_INFO:
            self._out += rp.info_reply()
        elif cmd == rp.GET_SAMPLERATE:
            self._out += rp.descriptor(rp.SAMPLERATE_SIZE, rp.MODE_SINGLE, rp.TYPE_SAMPLERATE) + struct.pack(
                "<HH", round(self.period / rp.RAYS * 1e6), round(self.period / rp.RAYS * 1e6))
        elif cmd in (rp.SCAN, rp.FORCE_SCAN):
            self._out += rp.descriptor(rp.SCAN_NODE_SIZE, rp.MODE_MULTI, rp.TYPE_SCAN)
            self.scanning = True
            self._nodes, self._sent = [], 0

    def new_scan(self, ranges: np.ndarray, now: float) -> None:
        """A new simulated revolution at ``now`` [s]: its nodes go out over the next period."""
        if not self.scanning:
            return
        self._out += b"".join(self._nodes[self._sent :])  # finish the last revolution at once
        self._nodes, self._sent, self._start = rp.scan_nodes(ranges), 0, now

    def output(self, now: float) -> bytes:
        """Bytes due on the line by ``now`` [s]: replies, and the nodes whose time has come."""
        if self._nodes:
            due = min(len(self._nodes), int(len(self._nodes) * (now - self._start) / self.period) + 1)
            if due > self._sent:
                self._out += b"".join(self._nodes[self._sent : due])
                self._sent = due
        out, self._out = bytes(self._out), bytearray()
        return out
