"""``homing run MISSION.yaml --world WORLD --seed N``: tick a mission against the simulator (or any adapter)."""

from __future__ import annotations

import argparse
import os
import sys
from pathlib import Path
from typing import Any

DEFAULT_VIEW_SPEED = 10.0  # [× real time] pace with the live view, so that it can be watched


def register(sub: argparse._SubParsersAction) -> None:
    from homing.missions.commands._args import output_file, output_map, positive, seed
    from homing.missions.commands.check import add_set_argument

    parser = sub.add_parser(
        "run",
        help="run a mission in the simulator (live view in a terminal; --no-view for a status log)",
        description="Check the mission, then tick it on the adapter's clock until the root finishes, "
        "the time limit passes or Ctrl-C (or SIGTERM, SIGHUP); the robot is stopped and the tree halted in "
        "every case, and the map and logs asked for are written. Output paths are checked before the run.",
    )
    parser.add_argument("mission", metavar="MISSION.yaml")
    robot = parser.add_mutually_exclusive_group()
    robot.add_argument("--world", help="a bundled world's name, a world YAML, a map_server YAML or a generated "
                       "building (office:SEED, hospital:SEED, slam_office:SEED)")
    robot.add_argument("--robot", metavar="ROBOT.yaml", help="drive the real robot its robot file describes (wall clock)")
    robot.add_argument(
        "--adapter", metavar="MODULE:CALLABLE",
        help="build the robot with CALLABLE(seed=N) from MODULE instead (any RobotAdapter)",
    )  # fmt: skip
    parser.add_argument("--seed", type=seed, default=None,
                        help="the run's seed, 0 or more (same seed, same run; default 0, or the resumed run's)")
    parser.add_argument(
        "--speed", type=positive, metavar="X",
        help=f"pace at X× real time (default: as fast as possible, or {DEFAULT_VIEW_SPEED:g}× with the view)",
    )  # fmt: skip
    parser.add_argument("--until", metavar="DURATION", help="stop after this much adapter time, e.g. 90s, 30min, 2h")
    parser.add_argument("--rate", type=positive, metavar="HZ", help="tick rate (default: the mission's rate)")
    parser.add_argument("--no-view", action="store_true", help="print timestamped status changes, no live view")
    parser.add_argument("--log", metavar="PATH", type=output_file("--log"),
                        help="also write every status change to PATH, as the run goes")
    parser.add_argument(
        "--record", metavar="RUN", type=output_file("--record"),
        help="write a run log of everything sensed and commanded to RUN (see 'homing replay')",
    )  # fmt: skip
    parser.add_argument("--record-images", action="store_true",
                        help="with --record: also log the camera images (JPEG; exported to MCAP by 'homing replay')")
    parser.add_argument("--save-map", metavar="PATH", type=output_map("--save-map"),
                        help="save the final /map/grid as a map_server map (PATH.yaml + .pgm)")
    parser.add_argument(
        "--serve", metavar="[HOST:]PORT",
        help="stream the tree to followers ('homing view --attach HOST:PORT'); binds 127.0.0.1 unless given a host",
    )  # fmt: skip
    parser.add_argument(
        "--groot", metavar="[HOST:]PORT", nargs="?", const="1667",
        help="serve the tree to Groot2's monitor (BT.CPP v4's protocol; PORT and PORT+1, default 1667 and 1668); "
        "binds 127.0.0.1 unless given a host; needs the groot extra",
    )  # fmt: skip
    parser.add_argument(
        "--foxglove", metavar="[HOST:]PORT", nargs="?", const="8765",
        help="serve the run to Foxglove (its WebSocket protocol: map, scan, tf, path, goal, frontiers, tags, "
        "batteries, state, tree, log; default port 8765; open live/foxglove_layout.json); binds 127.0.0.1 unless "
        "given a host; needs the foxglove extra",
    )  # fmt: skip
    parser.add_argument("--foxglove-record", metavar="PATH.mcap", type=output_file("--foxglove-record"),
                        help="record the same channels to an MCAP file as the run goes (needs the foxglove extra)")
    keep = parser.add_mutually_exclusive_group()
    keep.add_argument("--run-dir", metavar="DIR",
                      help="save a snapshot (map, tags, counters, the dock) into DIR whenever the mission asks "
                           "(the persistent mission: at every dock)")
    keep.add_argument("--resume", metavar="DIR",
                      help="carry on a run from its latest snapshot in DIR (world and seed from it unless given), "
                           "and keep saving there")
    add_set_argument(parser)
    parser.set_defaults(func=run)


def _run_dir(args: argparse.Namespace) -> tuple[Any, Any]:
    """(RunDir or None, the Snapshot to resume or None), checked before anything starts."""
    from homing.lifecycle.rundir import RunDir

    from homing.errors import UserError

    if args.resume:
        run_dir = RunDir(args.resume)
        snap = run_dir.load()
        run_dir.check_writable()
        if not (args.world or args.robot or args.adapter):
            args.world = snap.meta.get("world")
            if not args.world:
                raise UserError("the run directory does not say which world: give --world", args.resume)
        if args.seed is None:
            args.seed = int(snap.meta.get("seed", 0) or 0)
        return run_dir, snap
    if args.run_dir:
        run_dir = RunDir(args.run_dir)
        if run_dir.has_run():
            raise UserError("already holds a run: continue it with --resume, or choose another directory", args.run_dir)
        run_dir.check_writable()
        return run_dir, None
    return None, None


def make_adapter(spec: str, seed: int) -> Any:
    """The robot built by ``--adapter MODULE:CALLABLE`` (CALLABLE defaults to ``make_robot``) with ``seed``.

    Anything that is not a factory of robot adapters — a module that does
    not import, a name it lacks, something that is not callable with
    ``seed=``, a factory that fails or returns something that is not a
    :class:`homing.robot.RobotAdapter` — is a one-line :class:`UserError`.
    """
    import importlib
    import inspect

    from homing.robot import RobotAdapter

    from homing.errors import UserError

    module_name, _, attr = spec.partition(":")
    attr = attr or "make_robot"
    where = f"--adapter {spec}"
    if not module_name.strip() or not attr.isidentifier():
        raise UserError(f"{where}: needs MODULE:CALLABLE, e.g. my_robot:make_robot")
    if "" not in sys.path and os.getcwd() not in sys.path:
        sys.path.insert(0, os.getcwd())  # as `python -m` does: modules beside the user
    try:
        module = importlib.import_module(module_name)
    except ImportError as err:
        raise UserError(f"{where}: cannot import {module_name}: {err}") from None
    except Exception as err:  # the user's module failed while importing: say how, in one line
        raise UserError(f"{where}: importing {module_name} failed: {type(err).__name__}: {err}") from None
    factory = getattr(module, attr, None)
    if factory is None:
        raise UserError(f"{where}: module {module_name} has no '{attr}'")
    if not callable(factory):
        raise UserError(f"{where}: '{attr}' is a {type(factory).__name__}, not a factory CALLABLE(seed=N)")
    try:
        inspect.signature(factory).bind(seed=seed)
    except TypeError as err:
        raise UserError(f"{where}: '{attr}' cannot be called as {attr}(seed=N): {err}") from None
    except ValueError:
        pass  # no signature to inspect (a builtin): let the call say
    try:
        robot = factory(seed=seed)
    except Exception as err:
        raise UserError(f"{where}: the factory failed: {type(err).__name__}: {err}") from None
    if not isinstance(robot, RobotAdapter):
        missing = [m for m in ("clock", "limits", "observe", "command", "step", "close") if not hasattr(robot, m)]
        close = getattr(robot, "close", None)
        if callable(close):
            close()
        raise UserError(f"{where}: the factory returned a {type(robot).__name__}, not a robot adapter "
                        f"(missing: {', '.join(missing)}; see homing.robot.RobotAdapter)")
    return robot


def _adapter(args: argparse.Namespace) -> Any:
    from homing.errors import UserError

    if args.adapter:
        return make_adapter(args.adapter, args.seed)
    if args.robot:
        from homing.robot.ros2.robot_file import robot_kind

        if robot_kind(args.robot) == "ros2":
            try:
                from homing.robot.ros2.adapter import open_ros2_robot
            except ImportError as err:
                raise UserError(f"a ros2 robot file needs the ros2 extra (pip install 'homing[ros2]'): {err}") from None
            return open_ros2_robot(args.robot)
        try:
            from homing.robot.hardware.robot import open_robot
        except ImportError as err:
            raise UserError(f"--robot needs the hardware extra (pip install 'homing[hardware]'): {err}") from None
        return open_robot(args.robot)
    try:
        from homing.sim import SimRobot, load_world
    except ImportError as err:
        raise UserError(f"--world needs the simulator (homing.sim), which cannot be loaded: {err}") from None
    return SimRobot(load_world(args.world), seed=args.seed)


def _recorder(args: argparse.Namespace, mission: Any, robot: Any) -> Any:
    """A run-log Recorder for ``--record`` with the run's metadata (None without the option)."""
    from homing.errors import UserError

    if not args.record:
        if getattr(args, "record_images", False):
            raise UserError("--record-images needs --record RUN")
        return None
    from homing.logs.runlog import Recorder

    meta: dict[str, Any] = {"world": args.world, "seed": args.seed, "mission": str(args.mission),
                            "adapter": args.adapter, "rate": args.rate or mission.rate}
    for spec, params in mission.services:
        if spec.name == "tag_slam":
            meta["tag_slam"] = {k: v for k, v in params.items() if isinstance(v, (int, float, str, bool))}
    try:
        return Recorder(args.record, meta, images=bool(getattr(args, "record_images", False)))
    except OSError as err:
        raise UserError(f"--record: cannot write the run log: {err.strerror}", args.record) from None


def _save_map(args: argparse.Namespace, runner: Any) -> None:
    from homing.mapping.grid import OccupancyGrid
    from homing.mapping.map_io import save_grid

    from homing.errors import UserError

    grid = runner.read("/map/grid")
    if not isinstance(grid, OccupancyGrid):
        raise UserError("--save-map: the mission has no occupancy grid (/map/grid): add a mapping service", args.mission)
    print(f"map saved: {save_grid(args.save_map, grid)}")


def check_timing(rate: float, until: float | None) -> None:
    """A tick rate within [MIN_RATE, MAX_RATE] Hz and a time limit of at least one tick, or :class:`UserError`."""
    from homing.missions.schema import MAX_RATE, MIN_RATE

    from homing.errors import UserError

    if not MIN_RATE <= rate <= MAX_RATE:
        raise UserError(f"tick rate {rate:g} Hz is outside {MIN_RATE:g} … {MAX_RATE:g} Hz (below {MIN_RATE:g} Hz the "
                        "robot would drive blind on one command for over a second)")
    if until is not None and until < 1.0 / rate:
        raise UserError(f"--until {until:g} s is shorter than one tick ({1.0 / rate:g} s at {rate:g} Hz)")


def _server(args: argparse.Namespace, mission: Any) -> Any:
    """The tree server for ``--serve`` (bound before the run starts, so a taken port fails at once), or None."""
    if not args.serve:
        return None
    from homing.missions.remote import TreeServer, parse_address
    from homing.missions.view import LiveView

    from homing.errors import UserError

    try:
        host, port = parse_address(args.serve)
    except ValueError as err:
        raise UserError(f"--serve: {err}") from None
    server = TreeServer(host, port, lambda console: LiveView(mission, console))
    print(f"serving the tree on {server.host}:{server.port} (follow with: homing view --attach {server.host}:{server.port})",
          file=sys.stderr, flush=True)  # fmt: skip
    return server


def _groot(args: argparse.Namespace, mission: Any) -> Any:
    """The Groot2 server for ``--groot`` (both ports bound before the run starts), or None."""
    if args.groot is None:
        return None
    from homing.missions.remote import parse_address

    from homing.errors import UserError

    try:
        host, port = parse_address(args.groot)
    except ValueError as err:
        raise UserError(f"--groot: {err}") from None
    if port == 65535:
        raise UserError("--groot: port 65535 leaves no port for the publisher (PORT + 1)")
    try:
        from homing.live.groot2 import Groot2Server
    except ImportError as err:
        raise UserError(f"--groot needs the groot extra (pip install 'homing[groot]'): {err}") from None
    server = Groot2Server(mission, host, port)
    print(f"serving Groot2 on {server.host}:{server.port} (publisher {server.publisher_port}): "
          f"connect Groot2's monitor to {server.host}, port {server.port}", file=sys.stderr, flush=True)  # fmt: skip
    return server


def _foxglove(args: argparse.Namespace, mission: Any) -> Any:
    """The Foxglove server (bound before the run starts) and/or MCAP recorder, or None."""
    record = getattr(args, "foxglove_record", None)
    if args.foxglove is None and record is None:
        return None
    from homing.missions.remote import parse_address

    from homing.errors import UserError

    host, port = "127.0.0.1", None
    if args.foxglove is not None:
        try:
            host, port = parse_address(args.foxglove)
        except ValueError as err:
            raise UserError(f"--foxglove: {err}") from None
    try:
        from homing.live.foxglove import FoxgloveServer
    except ImportError as err:
        option = "--foxglove" if args.foxglove is not None else "--foxglove-record"
        raise UserError(f"{option} needs the foxglove extra (pip install 'homing[foxglove]'): {err}") from None
    server = FoxgloveServer(mission, host, port, record=record)
    if server.port is not None:
        where = f"[{host}]" if ":" in host else host
        print(f"serving Foxglove on ws://{where}:{server.port} (Foxglove: Open connection, Foxglove WebSocket; "
              "layout: live/foxglove_layout.json)", file=sys.stderr, flush=True)  # fmt: skip
    return server


def run(args: argparse.Namespace) -> int:
    from homing.missions.commands.check import overrides
    from homing.missions.compiler import compile_mission
    from homing.missions.runner import Runner, parse_duration
    from homing.missions.view import LiveView, PlainLog
    from py_trees.common import Access

    from homing.errors import UserError
    from homing.signals import exit_status, received, signal_name

    try:
        until = parse_duration(args.until) if args.until else None
    except ValueError as err:
        raise UserError(f"--until: {err}") from None
    mission = compile_mission(args.mission, overrides(args))
    run_dir, snap = _run_dir(args)
    if not (args.world or args.robot or args.adapter):
        raise UserError("say which robot to run on: --world, --robot or --adapter (or --resume a run)")
    args.seed = 0 if args.seed is None else args.seed
    for warning in mission.warnings:
        print(f"warning: {warning}", file=sys.stderr)
    check_timing(args.rate or mission.rate, until)
    live = not args.no_view and sys.stdout.isatty()
    speed = args.speed if args.speed is not None else (DEFAULT_VIEW_SPEED if live else None)
    status_log = open_status_log(args.log) if args.log else None
    plain = PlainLog(sys.stdout)

    def on_change(change: Any) -> None:
        if groot is not None:
            groot.on_change(change)
        if fox is not None:
            fox.on_change(change)
        if status_log is not None:
            status_log(change)
        if not live:
            plain(change)

    server = _server(args, mission)
    groot = fox = None
    robot = recorder = None
    try:
        groot = _groot(args, mission)
        fox = _foxglove(args, mission)
        robot = _adapter(args)
        if snap is not None and snap.sim is not None and hasattr(robot, "restore_state"):
            try:
                robot.restore_state(snap.sim)
            except ValueError as err:
                raise UserError(f"damaged snapshot: {err}", args.resume) from None
        recorder = _recorder(args, mission, robot)
        truth = getattr(robot, "truth_pose", None) if recorder is not None else None
        runner = Runner(mission, robot, seed=args.seed, rate=args.rate, until=until, speed=speed, on_change=on_change,
                        recorder=recorder, truth=truth, run_dir=run_dir, resume=snap,
                        meta={"mission": mission.name, "world": args.world, "seed": args.seed})
        if args.save_map:
            runner.bb.register_key(key="/map/grid", access=Access.READ)
        callbacks: list[Any] = [server.publish] if server is not None else []  # after each tick, in order
        if groot is not None:
            callbacks.append(groot.on_tick)
        if fox is not None:
            callbacks.append(fox.on_tick)

        def on_tick(r: Any) -> None:
            for callback in callbacks:
                callback(r)

        runner.on_tick = on_tick
        if live:
            with LiveView(mission) as view:
                callbacks.append(view.attach(runner))
                result = runner.run()
                view.update(runner, force=True)
        else:
            callbacks.append(plain.attach(runner))
            result = runner.run()
        if server is not None:
            server.publish(runner, force=True)
        if fox is not None:
            fox.on_tick(runner, force=True)
    finally:
        if fox is not None:
            fox.close()
        if groot is not None:
            groot.close()
        if server is not None:
            server.close()
        if recorder is not None:
            recorder.close()
        if robot is not None:
            robot.close()
        if status_log is not None:
            status_log.stream.close()
    if args.save_map:
        _save_map(args, runner)
    cmd = result.final_command
    why = f" by {signal_name(received())}" if result.reason == "interrupted" else ""
    print(f"stopped: {result.reason}{why} at t={result.time:.2f} s after {result.ticks} ticks "
          f"({result.rtf:.1f}× real time)")  # two lines within 80 columns
    print(f"final command v={cmd.v:.3f} m/s ω={cmd.omega:.3f} rad/s (robot stopped); root {result.root_status.value}")
    for node in mission.root.iterate():
        report = getattr(node, "end_report", None)
        line = report() if callable(report) else None
        if line:
            print(f"{node.name}: {line}")  # the view shows it live; a log ends with it
    if run_dir is not None:
        print(f"run directory: {run_dir.path} ({runner.snapshots} snapshots saved this run"
              f"{f', resumed at t={snap.time:.0f} s after {snap.cycles} cycles' if snap is not None else ''})")
    if result.reason == "interrupted":
        return exit_status(received())
    return {"success": 0, "time_limit": 0, "failure": 1}[result.reason]


def open_status_log(path: str | Path) -> Any:
    """A :class:`~homing.missions.view.PlainLog` streaming to ``path``, line by line (a kill loses no whole line)."""
    from homing.missions.view import PlainLog

    from homing.errors import UserError

    target = Path(path)
    try:
        target.parent.mkdir(parents=True, exist_ok=True)
        stream = open(target, "w", encoding="utf-8", buffering=1)  # noqa: SIM115 - closed by the caller
    except OSError as err:
        raise UserError(f"--log: cannot write: {err.strerror}", path) from None
    return PlainLog(stream)
