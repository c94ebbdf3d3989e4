"""``homing emulate --world WORLD``: serve a simulated TurtleBot 2 as real devices (pseudo-terminals, MJPEG)."""

from __future__ import annotations

import argparse
import signal
import sys
import tempfile
import threading
from types import FrameType
from typing import Any


def register(sub: argparse._SubParsersAction) -> None:
    parser = sub.add_parser(
        "emulate",
        help="emulate the robot's Kobuki, RPLIDAR and camera (ptys, MJPEG over HTTP), with the simulator as physics",
        description="Run the simulated robot on the wall clock behind a Kobuki and an RPLIDAR that speak their "
        "serial protocols on pseudo-terminals, and a camera streaming MJPEG over HTTP on localhost. Prints each "
        "device's path (the camera's URL) on a line naming it, and a robot file for "
        "'homing run MISSION --robot ROBOT.yaml'; runs until Ctrl-C.",
    )
    parser.add_argument("--world", required=True, help="a bundled world's name, a world YAML or a map_server YAML")
    parser.add_argument("--seed", type=int, default=0, help="the simulation's seed (same seed, same physics)")
    parser.add_argument("--dir", metavar="DIR", help="where to put the device links and the robot file "
                        "(default: a new temporary folder)")  # fmt: skip
    parser.add_argument("--noise", type=float, default=0.0, metavar="P",
                        help="line noise: each byte the devices send has a bit flipped with probability P")
    parser.add_argument("--dead-time", type=float, default=None, metavar="S",
                        help="seconds from a base command to the wheels' response (default: the real base's 0.2)")
    parser.add_argument("--camera-port", type=int, default=0, metavar="PORT",
                        help="serve the camera's MJPEG stream on this localhost port (default: a free one)")
    parser.add_argument("--no-camera", action="store_true", help="no camera (nothing rendered, no stream)")
    parser.add_argument("--until", metavar="DURATION", help="stop after this much time, e.g. 90s (default: Ctrl-C)")
    parser.add_argument("--ros2", action="store_true",
                        help="serve the robot as a ROS 2 robot over Zenoh in rmw_zenoh's format instead (a peer "
                        "listening on tcp/127.0.0.1:PORT, printed on a line of its own; needs homing[ros2])")
    parser.add_argument("--port", type=int, default=0, metavar="PORT",
                        help="with --ros2: the Zenoh endpoint's TCP port (default: a free one)")
    parser.add_argument("--router", metavar="ENDPOINT",
                        help="with --ros2: join this Zenoh router (e.g. tcp/127.0.0.1:7447, an rmw_zenohd) as "
                        "rmw_zenoh's nodes do, instead of listening; the robot file names the router")
    parser.set_defaults(func=run)


def _stop_on_signals() -> threading.Event:
    """An event set by SIGINT or SIGTERM (the emulator then stops its devices and says where the robot is)."""
    done = threading.Event()

    def stop(signum: int, frame: FrameType | None) -> None:
        done.set()

    signal.signal(signal.SIGINT, stop)
    signal.signal(signal.SIGTERM, stop)
    return done


def run(args: argparse.Namespace) -> int:
    from homing.emulators.emulation import Emulation
    from homing.emulators.kobuki import DEAD_TIME
    from homing.emulators.pty_link import LineNoise
    from homing.missions.runner import parse_duration
    from homing.sim import load_world

    from homing.errors import UserError

    if not 0.0 <= args.noise < 1.0:
        raise UserError(f"--noise must be a probability in [0, 1), not {args.noise:g}")
    if args.dead_time is not None and not 0.0 <= args.dead_time <= 5.0:
        raise UserError(f"--dead-time must be in [0, 5] s, not {args.dead_time:g}")
    if not 0 <= args.camera_port <= 65535:
        raise UserError(f"--camera-port must be a TCP port in 0..65535, not {args.camera_port}")
    try:
        until = parse_duration(args.until) if args.until else None
    except ValueError as err:
        raise UserError(f"--until: {err}") from None
    world = load_world(args.world)
    folder = args.dir or tempfile.mkdtemp(prefix="homing-emulate-")
    if args.ros2:
        return _run_ros2(args, world, folder, until)
    if args.port or args.router:
        raise UserError(f"{'--port' if args.port else '--router'} is for the Zenoh endpoint: it needs --ros2")
    try:
        emulation = Emulation(world, folder, seed=args.seed, noise=LineNoise(flip=args.noise, seed=args.seed),
                              camera=not args.no_camera, camera_port=args.camera_port,
                              dead_time=DEAD_TIME if args.dead_time is None else args.dead_time)  # fmt: skip
    except OSError as err:
        raise UserError(f"--dir: cannot use {folder}: {err.strerror}", folder) from None
    done = _stop_on_signals()
    try:
        emulation.start()
    except OSError as err:
        emulation.robot.close()
        raise UserError(f"--camera-port: cannot serve the camera on 127.0.0.1:{args.camera_port}: "
                        f"{err.strerror or err}") from None  # fmt: skip
    print(f"kobuki: {emulation.base_link.link}")
    print(f"rplidar: {emulation.lidar_link.link}")
    if emulation.camera_url is not None:
        print(f"camera: {emulation.camera_url}")
    print(f"computer battery: {emulation.folder / 'computer_battery'}")
    print(f"robot file: {emulation.robot_file}")
    print(f"world {world.name}, seed {args.seed}: running until Ctrl-C", flush=True)
    return _serve(emulation, done, until, "{packets} packets sent, {commands} commands received, {frames} camera frames")


def _run_ros2(args: argparse.Namespace, world: object, folder: str, until: float | None) -> int:
    """``--ros2``: the simulator behind a Zenoh peer speaking rmw_zenoh's format (homing.emulators.ros2)."""
    from homing.errors import UserError

    for flag, value in (("--noise", args.noise), ("--dead-time", args.dead_time), ("--camera-port", args.camera_port)):
        if value:
            raise UserError(f"{flag} is for the emulated serial devices; it does not apply with --ros2")
    if not 0 <= args.port <= 65535:
        raise UserError(f"--port must be a TCP port in 0..65535, not {args.port}")
    try:
        from homing.emulators.ros2 import Ros2Emulation
    except ImportError as err:
        raise UserError(f"--ros2 needs the ros2 extra (pip install 'homing[ros2]'): {err}") from None
    try:
        emulation = Ros2Emulation(world, folder, seed=args.seed, port=args.port,  # type: ignore[arg-type]
                                  camera=not args.no_camera, router=args.router)
    except OSError as err:
        raise UserError(f"--dir: cannot use {folder}: {err.strerror}", folder) from None
    done = _stop_on_signals()
    try:
        emulation.start()
    except Exception as err:  # zenoh.ZError: the port is taken, the router unreachable
        emulation.robot.close()
        what = f"--router: cannot join {args.router}" if args.router else f"--port: cannot listen on {emulation.endpoint}"
        raise UserError(f"{what}: {str(err).split(' at /')[0]}") from None
    print(emulation.endpoint)
    print(f"robot file: {emulation.robot_file}")
    print(f"world {world.name}, seed {args.seed}: a ROS 2 robot over Zenoh, running until Ctrl-C", flush=True)  # type: ignore[attr-defined]
    return _serve(emulation, done, until, "{commands} commands received")


def _serve(emulation: Any, done: threading.Event, until: float | None, traffic: str) -> int:
    """Serve until a signal or ``until`` [s], stop, and print what passed (``traffic``: a format over the
    emulation's status) and where the robot ended."""
    try:
        done.wait(until)
    finally:
        emulation.stop()
    s = emulation.status()
    x, y, th = s["truth"]
    print(f"stopped at t={s['time']:.1f} s: {traffic.format(**s)}; robot at ({x:.2f}, {y:.2f}, {th:.2f}), "
          f"{s['distance']:.2f} m travelled")
    sys.stdout.flush()
    return 0
