"""Simulator speed: real-time factor with lidar only and with camera rendering, cost of a scan and an image.

Drives the simulated TurtleBot along a fixed open-loop path (undock, turn,
drive, turn…; collisions allowed) for ``--seconds`` of simulated time in the
bundled ``lab`` world and in the public ``loop`` floor plan (when found), stepping at
10 Hz like the mission runner, once with ``camera=False`` and once with the
camera on (rendering only when a tag can be in view, DESIGN.md). Reports:

- ``rtf_lidar``, ``rtf_camera``: simulated / wall-clock seconds, the *worst*
  world's (targets: ≥ 300 and ≥ 20 on the 2-core development machine);
- ``rtf_lidar_cpu``: simulated / CPU seconds of this process with lidar only,
  the worst world's: the same figure, blind to other programs on the machine;
- ``scan_ms``: median cost of one 360-ray scan (``rayTestBatch`` + noise),
- ``image_ms``: median cost of one 320 × 240 tiny-renderer frame with noise,
  both over the path's poses every 2 s (frames rendered whatever is in view);
  the worst world's.
"""

from __future__ import annotations

import argparse
import statistics
import time

from homing.benchmarks.common import find_plans, print_table, write_json

CONTROL_DT = 0.1  # [s] the runner's tick
# (v [m/s], ω [rad/s], duration [s]): undock, spin, then a loop of drives and turns
PATH = ((-0.2, 0.0, 4.0), (0.0, 0.8, 8.0), (0.4, 0.0, 5.0), (0.0, 0.8, 2.0), (0.4, 0.1, 6.0),
        (0.0, -0.8, 2.0), (0.3, -0.1, 5.0), (0.0, 0.8, 4.0))


def add_arguments(parser: argparse.ArgumentParser) -> None:
    from homing.missions.commands._args import positive, seed

    parser.add_argument("--seconds", type=positive, default=120.0, help="simulated seconds per run (default 120)")
    parser.add_argument("--worlds", nargs="+",
                        help="worlds to drive in (default: lab and the public loop.yaml, see $HOMING_WORLDS)")
    parser.add_argument("--seed", type=seed, default=1)


def _commands(seconds: float):  # noqa: ANN202 - generator of (v, ω)
    t = 0.0
    while t < seconds:
        for v, w, dur in PATH:
            for _ in range(round(dur / CONTROL_DT)):
                if t >= seconds:
                    return
                yield v, w
                t += CONTROL_DT


def _drive(world, seed: int, seconds: float, camera: bool, poses: list | None = None):  # noqa: ANN001, ANN202
    """(real-time factor, CPU-time factor, frames rendered, camera slots); appends the true pose every 2 s
    to ``poses``."""
    from homing.sim.robot import SimRobot

    robot = SimRobot(world, seed=seed, camera=camera)
    frames, last = 0, None
    start, cpu = time.perf_counter(), time.process_time()
    for k, (v, w) in enumerate(_commands(seconds)):
        if poses is not None and k % 20 == 0:
            poses.append(robot.truth_pose())
        obs = robot.observe()
        if obs.image is not None and obs.image.stamp != last:
            frames, last = frames + 1, obs.image.stamp
        robot.command(v, w)
        robot.step(CONTROL_DT)
    wall, cpu = time.perf_counter() - start, time.process_time() - cpu
    robot.close()
    return seconds / wall, seconds / max(cpu, 1e-9), frames, round(seconds * robot.camera_period ** -1)


def _unit_costs(world, seed: int, poses: list) -> tuple[float, float]:  # noqa: ANN001
    """Median cost [ms] of one scan and one rendered frame at the path's poses (any view)."""
    import numpy as np
    from homing.sim.robot import SimRobot

    robot = SimRobot(world, seed=seed, camera=True)
    rng = np.random.default_rng(seed)
    scans, images = [], []
    for pose in poses:
        t = time.perf_counter()
        robot.lidar.scan(pose, 0.0, rng)
        scans.append(time.perf_counter() - t)
        t = time.perf_counter()
        assert robot.camera is not None, "the benchmark builds its robot with a camera"
        robot.camera.render(pose, 0.0, rng)
        images.append(time.perf_counter() - t)
    robot.close()
    return statistics.median(scans) * 1e3, statistics.median(images) * 1e3


def run(args: argparse.Namespace) -> int:
    from homing.sim.world import load_world

    rows, rtf_l, rtf_cpu, rtf_c, scan_ms, image_ms = [], [], [], [], [], []
    worlds = args.worlds or ["lab", *map(str, find_plans(("loop",), why="driving in lab only").values())]
    for spec in worlds:
        world = load_world(spec)
        poses: list = []
        lidar_rtf, lidar_cpu, _, _ = _drive(world, args.seed, args.seconds, camera=False, poses=poses)
        cam_rtf, _, frames, slots = _drive(world, args.seed, args.seconds, camera=True)
        s_ms, i_ms = _unit_costs(world, args.seed, poses)
        rtf_l.append(lidar_rtf)
        rtf_cpu.append(lidar_cpu)
        rtf_c.append(cam_rtf)
        scan_ms.append(s_ms)
        image_ms.append(i_ms)
        rows.append((world.name, lidar_rtf, cam_rtf, f"{frames}/{slots}", s_ms, i_ms))
    print_table(f"homing bench sim ({args.seconds:g} s simulated per run, 10 Hz control)",
                ["world", "rtf lidar", "rtf camera", "frames rendered", "scan ms", "image ms"], rows)
    write_json(args.json, {
        "rtf_lidar": min(rtf_l),
        "rtf_lidar_cpu": min(rtf_cpu),
        "rtf_camera": min(rtf_c),
        "scan_ms": max(scan_ms),
        "image_ms": max(image_ms),
        "seconds": args.seconds,
        "per_world": {r[0]: {"rtf_lidar": r[1], "rtf_camera": r[2], "frames": r[3], "scan_ms": r[4],
                             "image_ms": r[5]} for r in rows},
    })
    return 0
