"""The ROS 2 adapter over the emulated ROS 2 robot: topic rates, command latency, CPU, a lost router.

Runs ``homing emulate --world lab --ros2`` in a subprocess (a Zenoh peer on
127.0.0.1 speaking rmw_zenoh's format) and drives it through
:class:`homing.robot.ros2.adapter.Ros2Robot` in this process, on the wall
clock, at ``--rate`` Hz for ``--seconds``. A second Zenoh client (a probe,
as RViz on the robot's network would be) subscribes ``/cmd_vel``. Reports:

- ``scan_hz``, ``odom_hz``, ``battery_hz``, ``tf_hz``: samples the adapter
  took per second (targets: the emulated lidar's 5.5 Hz, odometry's 50 Hz,
  the battery's 1 Hz), and ``skipped``: samples it counted and dropped;
- ``command_ms``: how long ``command()`` takes (clip, CDR, attachment, put);
- ``to_client_ms``: from ``command()`` to the probe holding the decoded
  Twist (median and p95): Zenoh's routing through the robot's session;
- ``cpu_percent``: this process's CPU time over the drive (the adapter, its
  Zenoh threads and the probe) as a percentage of one core;
- ``lost_s``: from killing the emulator (SIGKILL, as a robot losing power) to
  ``Observation.devices_lost`` naming the router; ``back_s``: from the new
  emulator listening on the same port to the adapter driving again (Zenoh's
  client reconnecting, the topics flowing).
"""

from __future__ import annotations

import argparse
import signal
import statistics
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path
from typing import Any

from homing.benchmarks.common import print_table, write_json


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--seconds", type=float, default=20.0, help="wall-clock seconds of driving (default 20)")
    parser.add_argument("--rate", type=float, default=10.0, help="the tick rate [Hz] (default 10, as the missions)")


def _emulator(folder: Path, port: int) -> subprocess.Popen:
    emu = subprocess.Popen([sys.executable, "-m", "homing.missions.cli", "emulate", "--world", "lab", "--ros2",
                            "--port", str(port), "--dir", str(folder)],
                           stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True)  # fmt: skip
    assert emu.stdout is not None
    emu.stdout.readline()  # the endpoint: the peer listens from here on
    emu.stdout.readline()  # the robot file
    return emu


def _percentiles(values: list[float]) -> tuple[float, float]:
    if not values:
        return float("nan"), float("nan")
    return statistics.median(values), sorted(values)[int(0.95 * (len(values) - 1))]


def _wait(predicate: Any, timeout: float) -> float:
    """Seconds until ``predicate()`` holds (polled every 5 ms), or nan after ``timeout``."""
    t0 = time.monotonic()
    while time.monotonic() - t0 < timeout:
        if predicate():
            return time.monotonic() - t0
        time.sleep(0.005)
    return float("nan")


def run(args: argparse.Namespace) -> int:
    from homing.robot.ros2.adapter import open_ros2_robot
    from homing.robot.ros2.node import Ros2Node, free_port
    from homing.robot.ros2.wire import Qos, Received

    folder = Path(tempfile.mkdtemp(prefix="homing-bench-ros2-"))
    port = free_port()
    emu = _emulator(folder, port)
    robot = open_ros2_robot(folder / "robot.yaml")
    probe = Ros2Node("probe", mode="client", connect=[f"tcp/127.0.0.1:{port}"])
    heard: dict[float, float] = {}
    cond = threading.Condition()

    def on_cmd(r: Received) -> None:
        with cond:
            heard[r.message.linear.x] = time.monotonic()
            cond.notify_all()

    probe.subscribe("/cmd_vel", "geometry_msgs/msg/Twist", Qos(), on_cmd)
    try:
        print(f"driving the emulated ROS 2 robot at {args.rate:g} Hz for {args.seconds:g} s", flush=True)
        subs = {e.topic: e.counters for e in robot.node.entities if hasattr(e, "counters")}
        taken0 = {k: c.taken for k, c in subs.items()}
        calls, latency = [], []
        cpu0, t0 = time.process_time(), time.monotonic()
        i = 0
        while time.monotonic() - t0 < args.seconds:
            robot.observe()
            v = round(0.001 * (i % 300 + 1), 6)  # a distinct speed each tick names its sample
            i += 1
            a = time.monotonic()
            robot.command(v, 0.0)
            calls.append(time.monotonic() - a)
            with cond:
                if cond.wait_for(lambda: v in heard, 1.0):  # noqa: B023 - waited on here, in this iteration
                    latency.append(heard[v] - a)
            robot.step(1.0 / args.rate)
        wall, cpu = time.monotonic() - t0, time.process_time() - cpu0
        hz = {k: (c.taken - taken0[k]) / wall for k, c in subs.items()}
        skipped = sum(c.skipped for c in subs.values())
        emu.send_signal(signal.SIGKILL)
        emu.wait(30)
        lost = _wait(lambda: robot.observe().devices_lost == ("router",), 10.0)
        emu = _emulator(folder, port)  # returns once the new peer listens
        back = _wait(lambda: robot.observe().devices_lost == (), 30.0)
    finally:
        robot.close()
        probe.close()
        emu.send_signal(signal.SIGINT)
        emu.wait(30)
    call_med, call_p95 = _percentiles(calls)
    lat_med, lat_p95 = _percentiles(latency)
    figures = {"scan_hz": hz.get("/scan", 0.0), "odom_hz": hz.get("/odom", 0.0),
               "battery_hz": hz.get("/battery_state", 0.0), "tf_hz": hz.get("/tf", 0.0), "skipped": skipped,
               "command_ms": call_med * 1e3, "command_p95_ms": call_p95 * 1e3, "to_client_ms": lat_med * 1e3,
               "to_client_p95_ms": lat_p95 * 1e3, "commands_heard": len(latency), "commands": len(calls),
               "cpu_percent": 100.0 * cpu / wall, "lost_s": lost, "back_s": back, "seconds": wall}  # fmt: skip
    print_table(f"homing bench ros2 (lab, {wall:.0f} s wall clock, {args.rate:g} Hz ticks)",
                ["scan Hz", "odom Hz", "battery Hz", "tf Hz", "skipped", "command ms", "to client ms",
                 "to client p95", "CPU %", "lost s", "back s"],
                [(figures["scan_hz"], figures["odom_hz"], figures["battery_hz"], figures["tf_hz"], skipped,
                  figures["command_ms"], figures["to_client_ms"], figures["to_client_p95_ms"],
                  figures["cpu_percent"], lost, back)])  # fmt: skip
    write_json(getattr(args, "json", None), figures)
    return 0
