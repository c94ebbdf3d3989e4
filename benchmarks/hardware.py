"""Hardware adapters over the emulated robot: packets per second, command-to-motion latency, line noise.

Runs :class:`homing.emulators.emulation.Emulation` (the ``lab`` world) in
this process and drives it through :class:`homing.robot.hardware.robot.HardwareRobot`,
the real adapters reading the real bytes over pseudo-terminals, on the wall
clock. Reports:

- ``base_hz``, ``scan_hz``, ``nodes_per_s``: Kobuki feedback packets, lidar
  revolutions and lidar nodes the adapters decoded per second (targets: the
  base's 50 Hz, the lidar's 5.5 Hz × 360 nodes);
- ``latency_ms``: from ``command(0, 0.5)`` on a still robot to the first
  feedback packet whose gyro shows the turn (median and p95 over
  ``--trials``): the command's bytes, the firmware's 20 ms cycle, the
  feedback's bytes, the adapter's thread;
- per line-noise level (each byte the devices send has a bit flipped with
  probability ``flip``; each write also gets a garbage burst or is cut short
  with probability 20·flip): packets decoded, dropped for a bad checksum,
  resynchronisations and bytes skipped, for the base and the lidar, and the
  odometry's distance from the simulator's own odometry at the end [mm].
"""

from __future__ import annotations

import argparse
import statistics
import tempfile
import time
from typing import Any

from homing.benchmarks.common import print_table, write_json

NOISE = (0.0, 1e-4, 1e-3, 1e-2)  # per-byte bit-flip probabilities


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--seconds", type=float, default=10.0, help="wall-clock seconds per noise level (default 10)")
    parser.add_argument("--trials", type=int, default=20, help="command-to-motion trials (default 20)")
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


def run(args: argparse.Namespace) -> int:
    rows, levels = [], {}
    latency: list[float] = []
    for flip in NOISE:
        print(f"line noise {flip:g}: driving for {args.seconds:g} s", flush=True)
        emu, robot = _session(flip, args.seed)
        try:
            b0, n0, s0, t0 = robot.base.stats.packets, robot.lidar.reader.stats.nodes, robot.lidar.scans, time.monotonic()
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
                     "odom_error_mm": err_mm, "bits_flipped": emu.base_link.noise.flipped}  # fmt: skip
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
    med = statistics.median(latency) if latency else float("nan")
    p95 = sorted(latency)[int(0.95 * (len(latency) - 1))] if latency else float("nan")
    print(f"command to motion: median {med:.1f} ms, p95 {p95:.1f} ms over {len(latency)} trials")
    clean = levels["0"]
    write_json(args.json, {"base_hz": clean["base_hz"], "scan_hz": clean["scan_hz"],
                           "nodes_per_s": clean["nodes_per_s"], "latency_ms": med, "latency_p95_ms": p95,
                           "seconds": args.seconds, "noise": levels})  # fmt: skip
    return 0
