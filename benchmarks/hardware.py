"""Hardware adapters over the emulated robot: packets per second, command-to-motion latency, line noise, camera stream.

Runs :class:`homing.emulators.emulation.Emulation` (the ``lab`` world) in
this process and drives it through :class:`homing.robot.hardware.robot.HardwareRobot`,
the real adapters reading the real bytes over pseudo-terminals, on the wall
clock. Reports:

- ``base_hz``, ``scan_hz``, ``nodes_per_s``: Kobuki feedback packets, lidar
  revolutions and lidar nodes the adapters decoded per second (targets: the
  base's 50 Hz, the lidar's 5.5 Hz × 360 nodes);
- ``latency_ms``: from ``command(0, 0.5)`` on a still robot to the first
  feedback packet whose gyro shows the turn (median and p95 over
  ``--trials``): the command's bytes, the emulated base's dead time (the
  real base's 200 ms, ``homing.emulators.kobuki.DEAD_TIME``), the
  firmware's 20 ms cycle, the feedback's bytes, the adapter's thread;
- per line-noise level (each byte the devices send has a bit flipped with
  probability ``flip``; each write also gets a garbage burst or is cut short
  with probability 20·flip): packets decoded, dropped for a bad checksum,
  resynchronisations and bytes skipped, for the base and the lidar, and the
  odometry's distance from the simulator's own odometry at the end [mm],
  and the camera's frames per second: published on the MJPEG stream and
  received by the camera adapter;
- ``camera_latency_ms``: from the moment a frame is rendered to the moment
  the camera adapter holds it, decoded and rectified (median and p95 over
  ``--frames`` frames at the simulator's 3 Hz, rendered at the dock's
  staging pose with the frame's number drawn in its top rows): rendering,
  JPEG encoding, HTTP on localhost, OpenCV's FFmpeg demuxer and decoder.
"""

from __future__ import annotations

import argparse
import statistics
import tempfile
import threading
import time
from typing import Any

import numpy as np
from homing.benchmarks.common import print_table, write_json

NOISE = (0.0, 1e-4, 1e-3, 1e-2)  # per-byte bit-flip probabilities


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--seconds", type=float, default=10.0, help="wall-clock seconds per noise level (default 10)")
    parser.add_argument("--trials", type=int, default=20, help="command-to-motion trials (default 20)")
    parser.add_argument("--frames", type=int, default=30, help="camera latency frames (default 30)")
    parser.add_argument("--seed", type=int, default=1)


def _session(flip: float, seed: int):  # noqa: ANN202 - (emulation, robot)
    from homing.emulators.emulation import Emulation
    from homing.emulators.pty_link import LineNoise
    from homing.robot.hardware.robot import open_robot
    from homing.sim import load_world

    noise = LineNoise(flip=flip, garbage=20 * flip, cut=20 * flip, seed=seed)
    emu = Emulation(load_world("lab"), tempfile.mkdtemp(prefix="homing-bench-hw-"), seed=seed, noise=noise)
    emu.start()
    try:
        return emu, open_robot(emu.robot_file)
    except BaseException:
        emu.stop()
        raise


def _drive(robot: Any, seconds: float) -> None:
    """Back out of the dock, then turn and creep, for ``seconds`` of wall clock."""
    start = time.monotonic()
    while (t := time.monotonic() - start) < seconds:
        robot.observe()
        robot.command(-0.1, 0.0) if t < 3.0 else robot.command(0.05, 0.4)
        robot.step(0.1)


def _latency(robot: Any, trials: int) -> list[float]:
    out = []
    for _ in range(trials):
        robot.command(0.0, 0.0)
        time.sleep(0.4)
        with robot.base.lock:
            before = robot.base.inertia.angle
        t0 = time.monotonic()
        robot.command(0.0, 0.5)
        while time.monotonic() - t0 < 1.0:
            with robot.base.lock:
                moved = abs(robot.base.inertia.angle - before) >= 3  # 0.03°: beyond the gyro's noise
            if moved:
                out.append((time.monotonic() - t0) * 1e3)
                break
            time.sleep(0.0005)
    robot.command(0.0, 0.0)
    return out


BAR_ROWS = 16  # [px] the frame number's stripe at the top of a latency frame
BAR_BITS = 10


def _draw_number(image: np.ndarray, k: int) -> None:
    """Draw ``k`` as BAR_BITS black/white blocks across the top rows (read back by :func:`_read_number`)."""
    w = image.shape[1] // BAR_BITS
    for b in range(BAR_BITS):
        image[:BAR_ROWS, b * w : (b + 1) * w] = 255 if k >> b & 1 else 0


def _read_number(image: np.ndarray) -> int:
    w = image.shape[1] // BAR_BITS
    return sum(1 << b for b in range(BAR_BITS) if image[BAR_ROWS // 2, b * w + w // 2].mean() > 128)


def _camera_latency(frames: int, seed: int) -> tuple[list[float], list[float]]:
    """Latencies [ms] of ``frames`` numbered frames streamed at the camera's rate: from rendering, and from
    publishing (JPEG encoding onwards), to the adapter holding the frame."""
    from homing.emulators.camera_stream import MjpegServer
    from homing.robot.hardware.camera import UvcCamera, pinhole
    from homing.sim import SimRobot, load_world

    world = load_world("lab")
    sim = SimRobot(world, seed=seed, start=world.staging_pose(1.0))
    assert sim.camera is not None
    info = sim.camera.info
    server = MjpegServer()
    server.start()
    camera = UvcCamera(server.url, pinhole(info.width, info.height, info.fx, info.fy, info.cx, info.cy), np.eye(4),
                       time.monotonic, rate=2.0 / sim.camera_period)  # fmt: skip (as the emulator writes it)
    out: list[float] = []
    sent: list[float] = []
    try:
        opener = threading.Thread(target=camera.open)  # FFmpeg probes two frames before it opens
        opener.start()
        due = time.monotonic()
        while opener.is_alive():
            server.publish(sim.render().image, time.monotonic())
            due += sim.camera_period
            opener.join(max(0.0, due - time.monotonic()))
        for k in range(1, frames + 1):
            time.sleep(max(0.0, due - time.monotonic()))  # frames one camera period apart, as the emulator's
            due += sim.camera_period
            t0 = time.monotonic()
            image = sim.render().image.copy()
            _draw_number(image, k)
            t1 = time.monotonic()
            server.publish(image, t0)
            while time.monotonic() - t0 < 1.0:
                got = camera.latest()
                if got is not None and _read_number(got.image) == k:
                    out.append((got.stamp - t0) * 1e3)
                    sent.append((got.stamp - t1) * 1e3)
                    break
                time.sleep(0.0005)
    finally:
        server.stop()  # first: the camera's read returns at once instead of timing out
        camera.close()
        sim.close()
    return out, sent


def _percentiles(values: list[float]) -> tuple[float, float]:
    if not values:
        return float("nan"), float("nan")
    return statistics.median(values), sorted(values)[int(0.95 * (len(values) - 1))]


def run(args: argparse.Namespace) -> int:
    rows, levels = [], {}
    latency: list[float] = []
    for flip in NOISE:
        print(f"line noise {flip:g}: driving for {args.seconds:g} s", flush=True)
        emu, robot = _session(flip, args.seed)
        try:
            b0, n0, s0, t0 = robot.base.stats.packets, robot.lidar.reader.stats.nodes, robot.lidar.scans, time.monotonic()
            f0, p0 = robot.camera.frames, emu.stream.frames
            _drive(robot, args.seconds)
            wall = time.monotonic() - t0
            bs, ls = robot.base.stats, robot.lidar.reader.stats
            with emu.lock:
                sim_odom = emu.robot.odometry.pose
            err_mm = robot.observe().odom.pose.distance_to(sim_odom) * 1e3
            level = {"base_hz": (bs.packets - b0) / wall, "scan_hz": (robot.lidar.scans - s0) / wall,
                     "nodes_per_s": (ls.nodes - n0) / wall, "base_packets": bs.packets,
                     "base_checksum_errors": bs.checksum_errors, "base_resyncs": bs.resyncs,
                     "base_skipped": bs.skipped, "lidar_nodes": ls.nodes, "lidar_resyncs": ls.resyncs,
                     "lidar_skipped": ls.skipped, "scans_dropped": robot.lidar.assembler.dropped,
                     "odom_error_mm": err_mm, "bits_flipped": emu.base_link.noise.flipped,
                     "camera_published_hz": (emu.stream.frames - p0) / wall,
                     "camera_hz": (robot.camera.frames - f0) / wall}  # fmt: skip
            levels[f"{flip:g}"] = level
            rows.append((f"{flip:g}", level["base_hz"], bs.checksum_errors, bs.resyncs, level["scan_hz"],
                         level["nodes_per_s"], ls.resyncs, ls.skipped, err_mm))  # fmt: skip
            if flip == 0.0:
                latency = _latency(robot, args.trials)
        finally:
            robot.close()
            emu.stop()
    print_table(f"homing bench hardware (lab, {args.seconds:g} s wall clock per noise level)",
                ["bit flip p", "base Hz", "bad cs", "resync", "scan Hz", "nodes/s", "l.resync", "l.skip",
                 "odom mm"], rows)  # fmt: skip
    med, p95 = _percentiles(latency)
    clean = levels["0"]
    print(f"command to motion: median {med:.1f} ms, p95 {p95:.1f} ms over {len(latency)} trials")
    print(f"camera stream while driving: {clean['camera_published_hz']:.2f} frames/s published, "
          f"{clean['camera_hz']:.2f} received by the adapter", flush=True)  # fmt: skip
    frames, sent = _camera_latency(args.frames, args.seed)
    cam_med, cam_p95 = _percentiles(frames)
    sent_med, sent_p95 = _percentiles(sent)
    print(f"camera, rendered to adapter: median {cam_med:.1f} ms, p95 {cam_p95:.1f} ms; published to adapter: "
          f"median {sent_med:.1f} ms, p95 {sent_p95:.1f} ms ({len(frames)} of {args.frames} frames)")  # fmt: skip
    write_json(args.json, {"base_hz": clean["base_hz"], "scan_hz": clean["scan_hz"],
                           "nodes_per_s": clean["nodes_per_s"], "latency_ms": med, "latency_p95_ms": p95,
                           "camera_hz": clean["camera_hz"], "camera_published_hz": clean["camera_published_hz"],
                           "camera_latency_ms": cam_med, "camera_latency_p95_ms": cam_p95,
                           "camera_stream_latency_ms": sent_med, "camera_stream_latency_p95_ms": sent_p95,
                           "camera_frames": len(frames), "seconds": args.seconds, "noise": levels})  # fmt: skip
    return 0
