"""``homing emulate --world WORLD``: serve a simulated TurtleBot 2 as real devices on pseudo-terminals."""

from __future__ import annotations

import argparse
import signal
import sys
import tempfile
import threading
from types import FrameType


def register(sub: argparse._SubParsersAction) -> None:
    parser = sub.add_parser(
        "emulate",
        help="emulate the robot's Kobuki base and RPLIDAR on pseudo-terminals, with the simulator as physics",
        description="Run the simulated robot on the wall clock behind a Kobuki and an RPLIDAR that speak their "
        "serial protocols on pseudo-terminals. Prints each device's path on a line naming it, and a robot "
        "file for 'homing run MISSION --robot ROBOT.yaml'; runs until Ctrl-C.",
    )
    parser.add_argument("--world", required=True, help="a bundled world's name, a world YAML or a map_server YAML")
    parser.add_argument("--seed", type=int, default=0, help="the simulation's seed (same seed, same physics)")
    parser.add_argument("--dir", metavar="DIR", help="where to put the device links and the robot file "
                        "(default: a new temporary folder)")  # fmt: skip
    parser.add_argument("--noise", type=float, default=0.0, metavar="P",
                        help="line noise: each byte the devices send has a bit flipped with probability P")
    parser.add_argument("--until", metavar="DURATION", help="stop after this much time, e.g. 90s (default: Ctrl-C)")
    parser.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from homing.emulators.emulation import Emulation
    from homing.emulators.pty_link import LineNoise
    from homing.missions.runner import parse_duration
    from homing.sim import load_world

    from homing.errors import UserError

    if not 0.0 <= args.noise < 1.0:
        raise UserError(f"--noise must be a probability in [0, 1), not {args.noise:g}")
    try:
        until = parse_duration(args.until) if args.until else None
    except ValueError as err:
        raise UserError(f"--until: {err}") from None
    world = load_world(args.world)
    folder = args.dir or tempfile.mkdtemp(prefix="homing-emulate-")
    try:
        emulation = Emulation(world, folder, seed=args.seed,
                              noise=LineNoise(flip=args.noise, seed=args.seed))  # fmt: skip
    except OSError as err:
        raise UserError(f"--dir: cannot use {folder}: {err.strerror}", folder) from None
    done = threading.Event()

    def stop(signum: int, frame: FrameType | None) -> None:
        done.set()

    signal.signal(signal.SIGINT, stop)
    signal.signal(signal.SIGTERM, stop)
    emulation.start()
    print(f"kobuki: {emulation.base_link.link}")
    print(f"rplidar: {emulation.lidar_link.link}")
    print(f"computer battery: {emulation.folder / 'computer_battery'}")
    print(f"robot file: {emulation.robot_file}")
    print(f"world {world.name}, seed {args.seed}: running until Ctrl-C", flush=True)
    try:
        done.wait(until)
    finally:
        emulation.stop()
    s = emulation.status()
    x, y, th = s["truth"]
    print(f"stopped at t={s['time']:.1f} s: {s['packets']} packets sent, {s['commands']} commands received; "
          f"robot at ({x:.2f}, {y:.2f}, {th:.2f}), {s['distance']:.2f} m travelled")  # fmt: skip
    sys.stdout.flush()
    return 0
