"""Serve a running mission to Foxglove: the ``foxglove-sdk`` package's WebSocket server, and MCAP as it runs.

The server speaks the Foxglove WebSocket protocol (``foxglove/ws-protocol``,
``docs/spec.md``; the SDK's subprotocol is ``foxglove.sdk.v1``): on
connecting, a client gets ``serverInfo`` and an ``advertise`` of every
channel (topic, encoding, schema name and schema); it ``subscribe``s with
its own subscription ids, and each message then comes as a binary frame:
opcode ``0x01``, the subscription id (``uint32`` LE), the log time
(``uint64`` LE, ns) and the payload. The server also sends ``time``
(opcode ``0x02``) with the adapter's clock, so Foxglove's timeline follows
the robot's time (a simulated day in minutes).

| topic | schema | when |
| --- | --- | --- |
| ``/map`` | ``foxglove.Grid`` (int8 ``occupancy``: −1, 0, 100) | the grid's version changed (at most ``MAP_HZ``), and to a new subscriber |
| ``/scan`` | ``foxglove.LaserScan`` (``base_link``) | a new scan |
| ``/tf`` | ``foxglove.FrameTransforms``: ``map → odom → base_link`` | every snapshot |
| ``/pose`` | ``foxglove.PoseInFrame`` (``map``) | every snapshot |
| ``/plan`` | ``foxglove.SceneUpdate``: the navigator's path | every snapshot |
| ``/goal`` | ``foxglove.SceneUpdate``: the exploration goal | every snapshot |
| ``/frontiers`` | ``foxglove.SceneUpdate``: the smoothed frontier cells | the grid changed, at most ``FRONTIER_HZ`` |
| ``/landmarks`` | ``foxglove.SceneUpdate``: the tags' estimates and the dock | every snapshot |
| ``/battery`` | JSON ``homing.Batteries`` (base and computer, with their go-home and undock levels) | every snapshot |
| ``/mission/state`` | JSON ``homing.MissionState`` | every snapshot |
| ``/tree/status`` | JSON ``homing.TreeStatus``: every node's status | every snapshot |
| ``/log`` | ``foxglove.Log``: the run's status-change lines | every change |

A snapshot is taken after a tick (the runner's ``on_tick``) at most
``SNAPSHOT_HZ`` times a second of wall time, and not at all while no client
is subscribed and nothing records: at the tick rates of a run watched in
real time every tick is one; a run at 100× real time is sampled. The tick's
thread only copies (the grid only when its version changed, a 200 × 200
grid in ~10 µs) and hands the latest snapshot over; this module's thread
builds and sends the messages (and computes the frontiers), and a newer
snapshot replaces those not yet sent, so a slow client never slows the robot.
Log lines are all kept (up to ``LOG_BACKLOG`` waiting).

``record`` writes the same channels to an MCAP file as the run goes (the
SDK's ``open_mcap`` on the same context). Nothing listens beyond
``127.0.0.1`` unless a host is given.
"""

from __future__ import annotations

import collections
import queue
import socket
import sys
import threading
import time
from pathlib import Path
from typing import TYPE_CHECKING, Any

import foxglove
import numpy as np
import py_trees
from foxglove.channels import (
    FrameTransformsChannel,
    GridChannel,
    LaserScanChannel,
    LogChannel,
    PoseInFrameChannel,
    SceneUpdateChannel,
)
from foxglove.messages import Log, LogLevel
from foxglove.websocket import Capability, ServerListener
from homing.behaviours.keys import (
    CYCLES_KEY,
    DOCK_KEY,
    ENERGY_KEY,
    EXPLORE_GOAL_KEY,
    GRID_KEY,
    LOCALIZED_KEY,
    MAP_TO_ODOM_KEY,
    NAVIGATOR_KEY,
    POSE_KEY,
    STATE_KEY,
)
from homing.live.foxglove_messages import (
    BATTERY_SCHEMA,
    STATE_SCHEMA,
    TREE_SCHEMA,
    GridCopy,
    Snapshot,
    battery_json,
    frontiers_message,
    goal_message,
    grid_message,
    landmarks_message,
    nanoseconds,
    path_message,
    pose_message,
    scan_message,
    stamp,
    transforms_message,
)
from py_trees.common import Access, Status

from homing.errors import UserError

if TYPE_CHECKING:
    from homing.missions.compiler import CompiledMission
    from homing.missions.runner import Runner, StatusChange

DEFAULT_PORT = 8765  # Foxglove's usual WebSocket port
SNAPSHOT_HZ = 20.0  # [Hz] wall-clock snapshots at most
MAP_HZ = 4.0  # [Hz] wall-clock grids at most (a 300 × 200 grid is 60 kB a message)
FRONTIER_HZ = 1.0  # [Hz] wall-clock frontier computations at most (a smoothed-frontier pass costs ~10 ms)
LOG_BACKLOG = 10_000  # log lines waiting for the server thread, at most (the oldest are dropped)
# [s] how long close() waits for the port to be free once the server is told to stop: the SDK's stop() returns
# before its runtime has closed the listening socket (a test listing listeners saw it still open 1 time in 15),
# and a server started again on the same port would then fail to bind.
RELEASE_WAIT = 2.0
LANDMARKS_KEY = "/slam/landmarks"  # homing.behaviours.tag_slam_service's
READS = (GRID_KEY, POSE_KEY, MAP_TO_ODOM_KEY, LOCALIZED_KEY, NAVIGATOR_KEY, EXPLORE_GOAL_KEY, DOCK_KEY, ENERGY_KEY,
         CYCLES_KEY, STATE_KEY, LANDMARKS_KEY)


class _Listener(ServerListener):
    """The SDK's ServerListener: a new subscriber to ``/map`` gets the latest grid at once."""

    def __init__(self, owner: FoxgloveServer):
        self.owner = owner

    def on_subscribe(self, client: Any, channel: Any) -> None:
        if channel.topic == "/map":
            self.owner.resend_grid.set()


class FoxgloveServer:
    """Serves one run on ``(host, port)`` with the Foxglove SDK (``port`` 0: a free port), and/or records it.

    ``port=None`` serves nothing (``record`` alone). A port that is taken or
    a host that cannot be bound, and a recording that cannot be written, are
    a :class:`UserError` here, before the run.
    """

    def __init__(self, mission: CompiledMission, host: str = "127.0.0.1", port: int | None = DEFAULT_PORT,
                 record: str | Path | None = None):
        self.context = foxglove.Context()
        self.host = host
        self.server: Any = None
        self.writer: Any = None
        self.resend_grid = threading.Event()
        if port is not None:
            try:
                self.server = foxglove.start_server(
                    name=f"homing: {mission.name}", host=host, port=port, context=self.context,
                    capabilities=[Capability.Time], server_listener=_Listener(self))
            except RuntimeError as err:  # "FoxgloveError: Failed to bind port: <the OS's reason>"
                why = str(err).rsplit(": ", 1)[-1]
                raise UserError(f"--foxglove {host}:{port}: {why}") from None
        self.port = self.server.port if self.server is not None else None
        if record is not None:
            try:
                self.writer = foxglove.open_mcap(str(record), allow_overwrite=True, context=self.context)
            except OSError as err:
                if self.server is not None:
                    self.server.stop()
                    _wait_released(self.host, self.server.port)
                raise UserError(f"--foxglove-record: cannot write: {err.strerror or err}", str(record)) from None
        ctx = self.context
        self.channels: dict[str, Any] = {
            "/map": GridChannel("/map", context=ctx), "/scan": LaserScanChannel("/scan", context=ctx),
            "/tf": FrameTransformsChannel("/tf", context=ctx), "/pose": PoseInFrameChannel("/pose", context=ctx),
            "/plan": SceneUpdateChannel("/plan", context=ctx), "/goal": SceneUpdateChannel("/goal", context=ctx),
            "/frontiers": SceneUpdateChannel("/frontiers", context=ctx),
            "/landmarks": SceneUpdateChannel("/landmarks", context=ctx),
            "/battery": foxglove.Channel("/battery", schema=BATTERY_SCHEMA, context=ctx),
            "/mission/state": foxglove.Channel("/mission/state", schema=STATE_SCHEMA, context=ctx),
            "/tree/status": foxglove.Channel("/tree/status", schema=TREE_SCHEMA, context=ctx),
            "/log": LogChannel("/log", context=ctx),
        }
        self._nodes = [(node, depth) for node, depth in _preorder(mission.root)]
        self._bb: Any = None  # the blackboard client, made at the first tick (the runner clears the blackboard)
        self._grid_version: int | None = None
        self._next_grid = 0.0  # [s] wall (monotonic): the next grid copy, at the earliest
        self._scan_stamp: float | None = None
        self._next_snapshot = 0.0  # [s] wall (monotonic)
        self._logs: collections.deque[tuple[float, str, Status]] = collections.deque(maxlen=LOG_BACKLOG)
        self._queue: queue.SimpleQueue[Snapshot | None] = queue.SimpleQueue()  # None: close
        self.snapshots = 0
        self.errors = 0  # snapshots the server thread could not send
        self.sent: collections.Counter[str] = collections.Counter()  # messages logged per topic
        self.worker_cpu = 0.0  # [s] CPU time of the server thread (its own work: building and logging messages)
        self._thread = threading.Thread(target=self._serve, name="foxglove", daemon=True)
        self._thread.start()

    # --- the runner's thread ---------------------------------------------------------------------------------

    def on_change(self, change: StatusChange) -> None:
        """Queue one status change as a log line (the runner's ``on_change``; sent with the next snapshot)."""
        self._logs.append((change.time, change.line(), change.new))

    def on_tick(self, runner: Runner, force: bool = False) -> None:
        """Copy what the channels show, at most ``SNAPSHOT_HZ`` a second, and hand it to the server thread."""
        now = time.monotonic()
        if not force and now < self._next_snapshot:
            return
        self._next_snapshot = now + 1.0 / SNAPSHOT_HZ
        if not self._logs and not any(ch.has_sinks() for ch in self.channels.values()):
            return  # nobody is watching and nothing records
        snap = self._snapshot(runner, force)
        self._queue.put(snap)  # C-level and lock-free for the caller: the tick never waits on the server's thread

    def _read(self, key: str) -> Any:
        try:
            return self._bb.get(key)
        except KeyError:
            return None

    def _snapshot(self, runner: Runner, force: bool = False) -> Snapshot:
        if self._bb is None:
            self._bb = py_trees.blackboard.Client(name="foxglove")
            for key in READS:
                self._bb.register_key(key=key, access=Access.READ)
        obs = runner.observation
        s = Snapshot(time=float(runner.now), ticks=runner.ticks)
        s.pose, s.map_to_odom = self._read(POSE_KEY), self._read(MAP_TO_ODOM_KEY)
        grid = self._read(GRID_KEY)
        now = time.monotonic()
        changed = grid is not None and grid.version != self._grid_version and (force or now >= self._next_grid)
        if grid is not None and (changed or self.resend_grid.is_set()):
            self.resend_grid.clear()
            self._grid_version, self._next_grid = grid.version, now + 1.0 / MAP_HZ
            s.grid = GridCopy(grid.version, grid.data.copy(), float(grid.resolution), tuple(grid.origin))
        nav = self._read(NAVIGATOR_KEY)
        path = getattr(nav, "path", None)
        s.path = None if path is None else np.array(path, dtype=float)[:, :2]
        s.goal = self._read(EXPLORE_GOAL_KEY)
        s.landmarks = dict(self._read(LANDMARKS_KEY) or {})
        s.dock = self._read(DOCK_KEY)
        if obs is not None:
            s.odom = obs.odom.pose
            scan = obs.scan
            if scan is not None and scan.stamp != self._scan_stamp:
                self._scan_stamp = scan.stamp
                s.scan = {"stamp": scan.stamp, "angle_min": scan.angle_min, "angle_increment": scan.angle_increment,
                          "ranges": np.array(scan.ranges, dtype=float), "laser_pose": scan.laser_pose}
            policy = self._read(ENERGY_KEY) or {}
            s.batteries = {"base": battery_json(obs.battery, policy.get("base"))}
            if obs.computer_battery is not None:
                s.batteries["computer"] = battery_json(obs.computer_battery, policy.get("computer"))
        localized = self._read(LOCALIZED_KEY)
        s.state = {"time": s.time, "ticks": s.ticks, "state": str(self._read(STATE_KEY) or ""),
                   "cycles": int(self._read(CYCLES_KEY) or 0), "localized": None if localized is None else bool(localized)}
        nodes = [{"name": n.name, "depth": d, "status": n.status.value} for n, d in self._nodes]
        running = [n.name for n, _ in self._nodes if not n.children and n.status is Status.RUNNING]
        s.tree = {"time": s.time, "tick": s.ticks, "root": self._nodes[0][0].status.value, "running": running,
                  "nodes": nodes}
        return s

    def close(self) -> None:
        """Send what is waiting, stop the thread, stop the server, finish the MCAP file."""
        self._queue.put(None)
        self._thread.join(5.0)
        for channel in getattr(self, "channels", {}).values():
            channel.close()
        if self.server is not None:
            self.server.stop()
            self.server = None
            _wait_released(self.host, self.port)
        if self.writer is not None:
            self.writer.close()
            self.writer = None

    # --- the server's thread ---------------------------------------------------------------------------------

    def _serve(self) -> None:
        frontier_at, frontier_grid = -1.0, None
        last_grid: GridCopy | None = None
        stop = False
        while not stop:
            snap, stop = _latest(self._queue)
            cpu = time.thread_time()
            try:
                self._send_logs()
                if snap is not None:
                    self._send(snap)
                    if snap.grid is not None:
                        last_grid = snap.grid
                    now = time.monotonic()
                    if (last_grid is not None and last_grid is not frontier_grid
                            and now - frontier_at >= 1.0 / FRONTIER_HZ and self.channels["/frontiers"].has_sinks()):
                        frontier_at, frontier_grid = now, last_grid
                        cells = _frontier_cells(last_grid)
                        self._log("/frontiers", frontiers_message(snap.time, cells, last_grid), snap.time)
            except Exception as err:  # a message that cannot be built must not end the run: say it once, go on
                self.errors += 1
                if self.errors == 1:
                    print(f"foxglove: {type(err).__name__}: {err} (the server goes on)", file=sys.stderr, flush=True)
            self.worker_cpu += time.thread_time() - cpu

    def _log(self, topic: str, message: Any, t: float) -> None:
        self.channels[topic].log(message, log_time=nanoseconds(t))
        self.sent[topic] += 1

    def _send_logs(self) -> None:
        while self._logs:
            t, line, status = self._logs.popleft()
            level = LogLevel.Warning if status is Status.FAILURE else LogLevel.Info
            self._log("/log", Log(timestamp=stamp(t), level=level, message=line, name="homing"), t)

    def _send(self, s: Snapshot) -> None:
        self.snapshots += 1
        if self.server is not None:
            self.server.broadcast_time(nanoseconds(s.time))
        if s.grid is not None:
            self._log("/map", grid_message(s.time, s.grid), s.time)
        if s.scan is not None:
            self._log("/scan", scan_message(s.time, s.scan), s.scan["stamp"])
        self._log("/tf", transforms_message(s), s.time)
        pose = pose_message(s)
        if pose is not None:
            self._log("/pose", pose, s.time)
        self._log("/plan", path_message(s), s.time)
        self._log("/goal", goal_message(s), s.time)
        self._log("/landmarks", landmarks_message(s), s.time)
        self._log("/battery", s.batteries, s.time)
        self._log("/mission/state", s.state, s.time)
        self._log("/tree/status", s.tree, s.time)


def _latest(waiting: queue.SimpleQueue[Snapshot | None]) -> tuple[Snapshot | None, bool]:
    """(the newest snapshot waiting, whether close was asked): blocks until there is something.

    Snapshots the server had no time for are dropped, but a grid or a scan
    that only an older one carried is kept with the newest.
    """
    snap: Snapshot | None = None
    item = waiting.get()  # an idle server sleeps here and never takes the GIL
    while True:
        if item is None:
            return snap, True
        if snap is not None:
            item.grid = item.grid or snap.grid
            item.scan = item.scan or snap.scan
        snap = item
        try:
            item = waiting.get_nowait()
        except queue.Empty:
            return snap, False


def _preorder(node: Any, depth: int = 0) -> Any:
    yield node, depth
    for child in node.children:
        yield from _preorder(child, depth + 1)


def _frontier_cells(g: GridCopy) -> np.ndarray:
    """The smoothed frontiers' cells (thesis algorithm 1, :func:`homing.mapping.frontier.smoothed_frontiers`)."""
    from homing.mapping.frontier import smoothed_frontiers

    segments = [s.cells for s in smoothed_frontiers(g.data, g.resolution)]
    return np.concatenate(segments) if segments else np.zeros((0, 2), np.int64)


def _wait_released(host: str, port: int | None, wait: float = RELEASE_WAIT) -> bool:
    """Whether ``port`` on ``host`` can be bound again (nothing listens there) within ``wait`` [s]; tried every 10 ms."""
    if port is None:
        return True
    family = socket.AF_INET6 if ":" in host else socket.AF_INET
    deadline = time.monotonic() + wait
    while True:
        with socket.socket(family, socket.SOCK_STREAM) as probe:
            probe.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)  # as a server binds: TIME_WAIT is no listener
            try:
                probe.bind((host, port))
                return True
            except OSError:
                pass
        if time.monotonic() >= deadline:
            return False
        time.sleep(0.01)
