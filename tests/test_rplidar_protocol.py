"""RPLIDAR bytes against the protocol document's examples; the emulator, read by the adapter over a pty, gives the sim's scans."""

from __future__ import annotations

import math
import threading
import time
from pathlib import Path

import numpy as np
import pytest
from homing.emulators.pty_link import PtyLink
from homing.emulators.rplidar import RplidarFirmware
from homing.robot.hardware import rplidar_protocol as rp
from homing.robot.hardware.rplidar import RPLidar
from homing.robot.types import Pose2


def test_descriptors_and_requests_byte_for_byte() -> None:
    # The protocol document's answers to SCAN and GET_HEALTH.
    assert rp.descriptor(5, rp.MODE_MULTI, rp.TYPE_SCAN) == bytes.fromhex("a5 5a 05 00 00 40 81")
    assert rp.descriptor(3, rp.MODE_SINGLE, rp.TYPE_HEALTH) == bytes.fromhex("a5 5a 03 00 00 00 06")
    assert rp.parse_descriptor(bytes.fromhex("a5 5a 14 00 00 00 04")) == (20, rp.MODE_SINGLE, rp.TYPE_INFO)
    assert rp.request(rp.SCAN) == bytes.fromhex("a5 20")
    # A request with a payload: size, payload, XOR of every byte before the checksum.
    assert rp.request(rp.SET_MOTOR_PWM, bytes.fromhex("94 02")) == bytes.fromhex("a5 f0 02 94 02") + bytes(
        (0xA5 ^ 0xF0 ^ 0x02 ^ 0x94 ^ 0x02,))


def test_node_byte_for_byte() -> None:
    # quality 47, start of a revolution, 90.000°, 1000.00 mm:
    # byte 0 = 47 << 2 | !S << 1 | S = 0xBD; angle_q6 = 5760 = 0x1680: byte 1 = (0x1680 & 0x7F) << 1 | C = 0x01,
    # byte 2 = 0x1680 >> 7 = 0x2D; distance_q2 = 4000 = 0x0FA0, LSB first.
    raw = rp.encode_node(90.0, 1000.0, 47, True)
    assert raw == bytes.fromhex("bd 01 2d a0 0f")
    node = rp.decode_node(raw)
    assert (node.angle, node.distance, node.quality, node.start) == (90.0, 1000.0, 47, True)
    assert rp.decode_node(rp.encode_node(359.99, 0.3, 0, False)).angle == pytest.approx(359.984375)  # 1/64°


def test_reader_resynchronises_after_garbage() -> None:
    nodes = rp.scan_nodes(np.linspace(0.5, 5.0, 360))
    stream = b"\x11" + rp.descriptor(5, rp.MODE_MULTI, rp.TYPE_SCAN) + b"".join(nodes[:100]) + b"\x00\x00\x00" \
        + b"".join(nodes[100:])  # fmt: skip
    reader = rp.NodeReader()
    out = []
    for i in range(0, len(stream), 64):
        out += reader.feed(stream[i : i + 64])
    assert len(out) == 360 and reader.stats.descriptors == 1
    assert reader.stats.skipped == 4 and reader.stats.resyncs == 2  # one stray byte before, three inside
    sent = np.linspace(500.0, 5000.0, 360)[(-np.arange(360)) % 360]  # node k measures ray −k (clockwise)
    assert [n.distance for n in out] == pytest.approx(sent, abs=0.125)


def test_assembler_turns_clockwise_nodes_into_a_ccw_scan() -> None:
    ranges = np.full(360, np.inf)
    ranges[10] = 2.0  # 10° counter-clockwise: the device reports it at 350° clockwise
    ranges[200] = 0.1  # under range_min: no return
    nodes = [rp.decode_node(b, stamp=1.5 + k * 1e-4) for k, b in enumerate(rp.scan_nodes(ranges))]
    assert nodes[350].angle == 350.0 and nodes[350].distance == 2000.0
    asm = rp.ScanAssembler(0.15, 6.0, Pose2(0.1, 0.0, math.pi))
    assert asm.add(nodes) == []  # a revolution is complete when the next one starts
    (scan,) = asm.add(nodes[:1])
    assert scan.stamp == 1.5 and scan.laser_pose == Pose2(0.1, 0.0, math.pi)
    assert np.isfinite(scan.ranges).sum() == 1 and scan.ranges[10] == pytest.approx(2.0)
    # a start flag where the angle does not wrap (a node misread from noise) does not split the revolution
    spurious = rp.decode_node(rp.encode_node(180.0, 3000.0, 10, True))
    asm = rp.ScanAssembler(0.15, 6.0)
    scans = asm.add(nodes[:180] + [spurious] + nodes[180:] + nodes[:1])
    assert len(scans) == 1 and asm.dropped == 0


def _serve(firmware: RplidarFirmware, link: PtyLink, scans: list[np.ndarray], stop: threading.Event) -> None:
    start = time.monotonic()
    k = -1
    while not stop.is_set():
        now = time.monotonic() - start
        firmware.receive(link.read())
        if int(now / firmware.period) > k and firmware.scanning:
            k = int(now / firmware.period)
            firmware.new_scan(scans[k % len(scans)], now)
        link.write(firmware.output(now))
        time.sleep(0.005)


def test_emulated_lidar_read_by_the_adapter_gives_the_sims_scans(tmp_path: Path) -> None:
    from homing.sim import SimRobot, load_world

    robot = SimRobot(load_world("lab"), seed=3, camera=False)
    truth = []
    for _ in range(3):  # three different noisy scans, sent in turn
        robot.step(0.2)
        truth.append(robot.observe().scan.ranges.astype(float))
    robot.close()
    link = PtyLink(tmp_path / "rplidar")
    link.open()
    firmware = RplidarFirmware(period=0.1)
    stop = threading.Event()
    server = threading.Thread(target=_serve, args=(firmware, link, truth, stop), daemon=True)
    server.start()
    lidar = RPLidar(str(link.link), time.monotonic)
    try:
        lidar.open()
        deadline = time.monotonic() + 10.0
        while lidar.scans < 6 and time.monotonic() < deadline:
            time.sleep(0.02)
        scan = lidar.latest()
    finally:
        lidar.close()
        stop.set()
        server.join()
        link.unplug()
    assert firmware.requests[:3] == [rp.STOP, rp.GET_HEALTH, rp.SCAN]
    assert scan is not None and lidar.scans >= 6
    got = scan.ranges.astype(float)
    matches = [t for t in truth if np.array_equal(np.isfinite(t), np.isfinite(got))]
    assert len(matches) == 1, "the scan is one of the sim's, whole"
    ok = np.isfinite(got)
    diff = np.abs(got[ok] - matches[0][ok])
    assert diff.max() <= 0.125e-3 + 1e-6  # distance quantised to 1/4 mm (float32 aside)
    assert lidar.reader.stats.skipped == 0 and rp.RAYS == len(got)
