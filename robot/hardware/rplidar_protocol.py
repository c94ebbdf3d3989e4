"""The RPLIDAR A1's serial protocol: requests, response descriptors, scan nodes, and 360° scans.

After Slamtec's "RPLIDAR Interface Protocol and Application Notes" (and the
open drivers that follow it: rplidar_sdk, SkoltechRobotics/rplidar). 115200
baud 8N1. The host sends requests ``0xA5 cmd`` (with a payload: ``0xA5 cmd
size payload checksum``, the checksum the XOR of every byte before it). The
device answers with a 7-byte descriptor::

    0xA5 0x5A | length (30 bits) and send mode (2 bits), u32 LE | data type

then the data: once (send mode 0) or repeatedly until STOP (mode 1). SCAN
(0x20) streams 5-byte measurement nodes, one per sample::

    byte 0: quality (6 bits) << 2 | !S << 1 | S     S: first node of a new revolution
    byte 1: angle_q6 bits 0..6 << 1 | C (= 1)        angle [1/64 °], clockwise seen from above
    byte 2: angle_q6 bits 7..14
    byte 3-4: distance_q2, u16 LE                   distance [1/4 mm]; 0 = no return

The A1's motor is switched by the USB adapter's DTR line (low: spinning).

:class:`NodeReader` finds descriptors and nodes in a byte stream and, like
the SDK, resynchronises after garbage by dropping one byte at a time until
the check bits (S ≠ !S, C = 1) hold again, counting what it drops.
:class:`ScanAssembler` turns the nodes of one revolution into the
contract's 360-ray :class:`~homing.robot.types.Scan` (REP-103:
counter-clockwise), one ray per degree. Pure functions over bytes.
"""

from __future__ import annotations

import math
import struct
from dataclasses import dataclass, field

import numpy as np
from homing.robot.hardware.resync import ResyncBuffer, ResyncStats
from homing.robot.types import Pose2, Scan

SYNC = 0xA5
SYNC2 = 0x5A
BAUD = 115200
# Requests
STOP = 0x25
RESET = 0x40
SCAN = 0x20
FORCE_SCAN = 0x21
GET_INFO = 0x50
GET_HEALTH = 0x52
GET_SAMPLERATE = 0x59
SET_MOTOR_PWM = 0xF0  # A2/A3 only; an A1 ignores it
# Response data types and sizes
TYPE_SCAN = 0x81
TYPE_INFO = 0x04
TYPE_HEALTH = 0x06
TYPE_SAMPLERATE = 0x15
SCAN_NODE_SIZE = 5
INFO_SIZE = 20
HEALTH_SIZE = 3
SAMPLERATE_SIZE = 4
MODE_SINGLE, MODE_MULTI = 0, 1
DESCRIPTOR_SIZE = 7
HEALTH_GOOD, HEALTH_WARNING, HEALTH_ERROR = 0, 1, 2
MAX_DISTANCE_Q2 = 0xFFFF  # [1/4 mm] 16.38 m
RAYS = 360  # one ray per degree in the assembled scan


def request(cmd: int, payload: bytes = b"") -> bytes:
    """A request: ``0xA5 cmd`` or, with a payload, ``0xA5 cmd size payload checksum``."""
    if not payload:
        return bytes((SYNC, cmd))
    body = bytes((SYNC, cmd, len(payload))) + payload
    cs = 0
    for b in body:
        cs ^= b
    return body + bytes((cs,))


def descriptor(length: int, mode: int, data_type: int) -> bytes:
    """A response descriptor: sync bytes, 30-bit length and 2-bit send mode (u32 LE), data type."""
    return bytes((SYNC, SYNC2)) + struct.pack("<I", (length & 0x3FFFFFFF) | (mode << 30)) + bytes((data_type,))


def parse_descriptor(raw: bytes) -> tuple[int, int, int]:
    """(length, send mode, data type) of a 7-byte descriptor; ValueError if it is not one."""
    if len(raw) != DESCRIPTOR_SIZE or raw[0] != SYNC or raw[1] != SYNC2:
        raise ValueError(f"not a response descriptor: {raw.hex(' ')}")
    word = struct.unpack("<I", raw[2:6])[0]
    return word & 0x3FFFFFFF, word >> 30, raw[6]


def encode_node(angle_deg: float, distance_mm: float, quality: int, start: bool) -> bytes:
    """One scan node: ``angle_deg`` clockwise in [0, 360), ``distance_mm`` (0: no return), quality 0..63."""
    angle_q6 = round(angle_deg * 64.0) % (360 * 64)
    dist_q2 = min(MAX_DISTANCE_Q2, max(0, round(distance_mm * 4.0)))
    s = 1 if start else 0
    b0 = ((quality & 0x3F) << 2) | ((1 - s) << 1) | s
    return bytes((b0, ((angle_q6 & 0x7F) << 1) | 1, angle_q6 >> 7)) + struct.pack("<H", dist_q2)


def node_ok(raw: bytes | bytearray) -> bool:
    """The node's check bits hold: S and !S differ, C is set."""
    return (((raw[0] >> 1) ^ raw[0]) & 1) == 1 and (raw[1] & 1) == 1


@dataclass(frozen=True)
class Node:
    """One measurement: ``angle`` [°] clockwise, ``distance`` [mm] (0: none), ``quality`` 0..63, ``start``."""

    angle: float
    distance: float
    quality: int
    start: bool
    stamp: float = 0.0  # [s] when it arrived, on the reader's clock


def decode_node(raw: bytes | bytearray, stamp: float = 0.0) -> Node:
    angle_q6 = (raw[1] >> 1) | (raw[2] << 7)
    dist_q2 = raw[3] | (raw[4] << 8)
    return Node(angle_q6 / 64.0, dist_q2 / 4.0, raw[0] >> 2, bool(raw[0] & 1), stamp)


@dataclass
class NodeStats(ResyncStats):
    """What a node reader made of its stream so far (and bytes fed, skipped, resynchronisations)."""

    nodes: int = 0
    descriptors: int = 0


@dataclass
class NodeReader:
    """Finds the scan descriptor, then nodes, in the bytes a device sends after SCAN."""

    stats: NodeStats = field(default_factory=NodeStats)
    streaming: bool = False
    _rx: ResyncBuffer = field(default_factory=ResyncBuffer)

    def reset(self) -> None:
        """Forget buffered bytes and wait for a new descriptor (after STOP and SCAN again)."""
        self._rx.buf.clear()
        self.streaming = False

    def feed(self, chunk: bytes, stamp: float = 0.0) -> list[Node]:
        self.stats.bytes += len(chunk)
        buf = self._rx.buf
        buf += chunk
        out: list[Node] = []
        if not self.streaming:
            while True:
                i = buf.find(bytes((SYNC, SYNC2)))
                if i < 0:
                    self._skip(len(buf) - (1 if buf.endswith(bytes((SYNC,))) else 0))
                    return out
                self._skip(i)
                if len(buf) < DESCRIPTOR_SIZE:
                    return out
                length, mode, kind = parse_descriptor(bytes(buf[:DESCRIPTOR_SIZE]))
                if kind == TYPE_SCAN and mode == MODE_MULTI and length == SCAN_NODE_SIZE:
                    del buf[:DESCRIPTOR_SIZE]
                    self.stats.descriptors += 1
                    self.streaming = True
                    self._rx.synced()
                    break
                self._skip(1)
        while len(buf) >= SCAN_NODE_SIZE:
            if not node_ok(buf):
                self._skip(1)
                continue
            out.append(decode_node(buf[:SCAN_NODE_SIZE], stamp))
            del buf[:SCAN_NODE_SIZE]
            self.stats.nodes += 1
            self._rx.synced()
        return out

    def _skip(self, n: int) -> None:
        self._rx.skip(n, self.stats)


@dataclass
class ScanAssembler:
    """Collects the nodes of one revolution into a 360-ray :class:`Scan` in the ``laser`` frame.

    The device's angles are clockwise; the scan's are counter-clockwise
    (REP-103): ray ``i`` points at ``i``° CCW and takes the node nearest to
    it within half a degree (quantisation: angle 1/64°, distance 1/4 mm).
    Rays with no node, a zero distance or ``quality`` under
    ``min_quality`` hold ``inf``. A scan is stamped with the arrival time
    of its first node. A start flag begins a new revolution only where the
    angle wraps (a node misread out of line noise may carry one). A
    revolution with fewer than ``min_nodes`` nodes
    (the partial one after start-up or a resync) is dropped.
    """

    range_min: float
    range_max: float
    laser_pose: Pose2 = field(default_factory=Pose2)
    min_nodes: int = 90
    min_quality: int = 1
    dropped: int = 0  # partial revolutions thrown away
    _nodes: list[Node] = field(default_factory=list)

    def add(self, nodes: list[Node]) -> list[Scan]:
        """Add nodes in arrival order; returns the scans of the revolutions they complete."""
        out: list[Scan] = []
        for node in nodes:
            # a start flag counts only where the angle wraps: a node misread out of garbage can carry one
            if node.start and self._nodes and self._nodes[-1].angle - node.angle > 180.0:
                scan = self._finish()
                if scan is not None:
                    out.append(scan)
            if node.start or self._nodes:
                self._nodes.append(node)
        return out

    def _finish(self) -> Scan | None:
        nodes, self._nodes = self._nodes, []
        if len(nodes) < self.min_nodes:
            self.dropped += 1
            return None
        ranges = np.full(RAYS, np.inf)
        best = np.full(RAYS, np.inf)  # angular distance of the node kept per ray [°]
        for n in nodes:
            ccw = (-n.angle) % 360.0
            i = int(round(ccw)) % RAYS
            off = abs(ccw - round(ccw))
            if off >= best[i] or off > 0.5:
                continue
            best[i] = off
            r = n.distance / 1000.0
            ok = n.distance > 0 and n.quality >= self.min_quality and self.range_min <= r <= self.range_max
            ranges[i] = r if ok else math.inf
        return Scan(nodes[0].stamp, 0.0, 2.0 * math.pi / RAYS, ranges.astype(np.float32), self.range_min,
                    self.range_max, self.laser_pose)  # fmt: skip


def scan_nodes(scan_ranges: np.ndarray, quality: int = 47) -> list[bytes]:
    """The nodes of one revolution for ``scan_ranges`` (N,) [m] at ``i·360/N``° CCW, ``inf`` = no return.

    The device side of :class:`ScanAssembler`: nodes go out in the order the
    clockwise-turning head measures them, the first carries the start flag, and a ray with no return is sent with
    distance 0 and quality 0 (as the A1 does).
    """
    ranges = np.asarray(scan_ranges, dtype=float)
    n = len(ranges)
    out = []
    for k in range(n):  # the head turns clockwise: device angles rise through the revolution
        r = ranges[(-k) % n]
        ok = math.isfinite(r) and r > 0
        out.append(encode_node(k * 360.0 / n, r * 1000.0 if ok else 0.0, quality if ok else 0, k == 0))
    return out


def health_reply(status: int = HEALTH_GOOD, error: int = 0) -> bytes:
    """Descriptor and data answering GET_HEALTH."""
    return descriptor(HEALTH_SIZE, MODE_SINGLE, TYPE_HEALTH) + struct.pack("<BH", status, error)


def info_reply(model: int = 0x18, firmware: tuple[int, int] = (1, 29), hardware: int = 7,
               serial: bytes = bytes(range(16))) -> bytes:
    """Descriptor and data answering GET_INFO: model, firmware (major, minor), hardware, 16-byte serial."""
    return descriptor(INFO_SIZE, MODE_SINGLE, TYPE_INFO) + bytes((model, firmware[1], firmware[0], hardware)) + serial
