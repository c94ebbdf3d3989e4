"""Tick a compiled mission against a robot adapter, on the adapter's clock (ARCHITECTURE.md, one tick).

Each tick: observe and publish ``/robot/observation`` and ``/robot/time``;
update the services in order; clear ``/cmd_vel`` and ``/runner/idle_until``
and tick the tree once; send ``/cmd_vel`` (zero if no leaf wrote it); step
the adapter by ``1/rate`` seconds — or, when a leaf said the tree has
nothing to do until a later time (``/runner/idle_until``; the charging robot
does) and no leaf drives, straight to that time in one step (at most
``MAX_IDLE``), so a docked robot costs one tick per poll, not ten a second.

The run ends when the root finishes, when ``until`` seconds of adapter time have passed, or on Ctrl-C; in every case the robot is sent a
zero command and the tree is halted (running leaves get ``terminate(INVALID)``
and cancel their work) before the services shut down.

Every status change of every node is reported with the adapter time to
``on_change``: changes the tick walks through (a recovery node's child
failing and starting again inside one tick) and halts it does not (a
branch preempted by a higher priority).

With a ``recorder`` (:class:`homing.logs.runlog.Recorder`) every tick is
logged in the order ``homing replay`` needs to reproduce SLAM: the
observation, then the tag sightings the services took at it
(``/perception/tags``), then the command; status changes as they happen,
and the simulator's truth (from ``truth``, evaluation only) apart.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import py_trees
from homing.behaviours.keys import (
    CYCLES_KEY,
    DOCK_KEY,
    EXPLORE_GOAL_KEY,
    GRID_KEY,
    IDLE_KEY,
    LANDMARKS_KEY,
    MAP_TO_ODOM_KEY,
    NAVIGATOR_KEY,
    SAVE_KEY,
    STATE_KEY,
    TAGS_KEY,
)
from homing.behaviours.registry import Service
from homing.missions.compiler import CompiledMission
from homing.robot import Observation, RobotAdapter, Twist2
from py_trees.common import Access, Status

from homing.signals import stop_requested

UNTIL_SLACK = 1e-6  # [s] float steps of 1/rate must not cost an extra tick at the limit
STOP_REASONS = ("success", "failure", "time_limit", "interrupted")
MAX_IDLE = 60.0  # [s] longest single step the runner takes on a leaf's word that nothing needs a tick


@dataclass(frozen=True)
class StatusChange:
    """Node ``node`` went from ``old`` to ``new`` at adapter time ``time`` [s]."""

    time: float
    node: str
    old: Status
    new: Status

    def line(self) -> str:
        return f"[{self.time:10.2f} s] {self.node}: {self.old.value} -> {self.new.value}"


@dataclass
class RunResult:
    """How a run ended: ``reason`` (one of STOP_REASONS), adapter time, ticks and the last command sent."""

    reason: str
    time: float  # [s] adapter clock at the end
    ticks: int
    final_command: Twist2
    wall: float  # [s] real time taken
    changes: int = 0
    root_status: Status = Status.INVALID

    @property
    def rtf(self) -> float:
        """Real-time factor: adapter seconds per real second."""
        return self.time / self.wall if self.wall > 0 else math.inf


@dataclass
class Runner:
    """Owns the tick loop for one mission on one adapter.

    ``rate`` [Hz] defaults to the mission's; ``until`` [s] of adapter time
    since the start (None = no limit); ``speed`` paces the loop at that many
    times real time (None = as fast as possible; only meaningful for a
    simulator, whose ``step`` returns at once). Callbacks: ``on_change`` per
    status change, ``on_tick`` after every tick (the live view).
    """

    mission: CompiledMission
    robot: RobotAdapter
    seed: int = 0
    rate: float | None = None
    until: float | None = None
    speed: float | None = None
    on_change: Callable[[StatusChange], None] | None = None
    on_tick: Callable[[Runner], None] | None = None
    ticks: int = 0
    now: float = 0.0  # [s] adapter time of the last tick
    start: float = 0.0  # [s] adapter time at the first tick
    wall_start: float = 0.0  # [s] real
    last_command: Twist2 = field(default_factory=Twist2)
    observation: Observation | None = None
    services: list[Service] = field(default_factory=list)
    changes: int = 0
    recorder: Any = None  # a homing.logs.runlog.Recorder (or None: nothing is logged)
    truth: Callable[[], Any] | None = None  # the simulator's true pose, for the log only
    run_dir: Any = None  # a homing.lifecycle.rundir.RunDir: a snapshot is saved there when a leaf asks (SaveRun)
    resume: Any = None  # a homing.lifecycle.rundir.Snapshot to start from (--resume)
    meta: dict[str, Any] = field(default_factory=dict)  # what the run is (mission, world, seed), kept in snapshots
    snapshots: int = 0
    timing: dict[str, float] | None = None  # set to {} to add up the time [s] of each part of a tick
    timing_clock: Callable[[], float] = time.perf_counter  # what ``timing`` adds up (time.process_time: CPU)

    def __post_init__(self) -> None:
        # py_trees keeps one blackboard per process: a run starts from an empty one, not from the last run's values.
        py_trees.blackboard.Blackboard.storage.clear()
        _steady_heap()  # a mission may live for days: keep the heap from creeping (see MMAP_THRESHOLD)
        self.tree = py_trees.trees.BehaviourTree(self.mission.root)
        self.bb = py_trees.blackboard.Client(name="runner")
        for key in ("/robot/observation", "/robot/time", "/cmd_vel", "/mission/state", IDLE_KEY, SAVE_KEY, CYCLES_KEY,
                    DOCK_KEY):
            self.bb.register_key(key=key, access=Access.WRITE)
        for key in (TAGS_KEY, NAVIGATOR_KEY, EXPLORE_GOAL_KEY, GRID_KEY, MAP_TO_ODOM_KEY, LANDMARKS_KEY):  # --record, ROS 2 robots
            if key not in self.bb.remappings:
                self.bb.register_key(key=key, access=Access.READ)
        for key in self.mission.source.view_keys:
            if key not in self.bb.remappings:
                self.bb.register_key(key=key, access=Access.READ)
        self._nodes = list(self.mission.root.iterate())
        self._status: dict[Any, Status] = {n.id: n.status for n in self._nodes}
        self._names = {n.id: n.name for n in self.mission.root.iterate()}
        self.tree.visitors.append(_ChangeVisitor(self))
        self._setup_done = False
        self._stop_requested = False
        self._idling = False  # the last step idled (see next_step)

    def request_stop(self) -> None:
        """End the run after this tick, as Ctrl-C does (reason ``interrupted``): for callbacks and tests."""
        self._stop_requested = True

    @property
    def period(self) -> float:
        """Seconds of adapter time between ticks."""
        return 1.0 / (self.rate or self.mission.rate)

    def setup(self) -> None:
        """Build and set up the services, then the tree (``setup(robot=..., seed=...)``); restore ``resume``."""
        if self.resume is not None:  # what the mission counted and where the dock is, before anyone reads them
            self.bb.set(CYCLES_KEY, int(self.resume.cycles), overwrite=True)
            if self.resume.dock is not None:
                self.bb.set(DOCK_KEY, self.resume.dock, overwrite=True)
        for spec, params in self.mission.services:
            service = spec.factory(**params)
            client = py_trees.blackboard.Client(name=f"service:{spec.name}")
            for key in spec.writes:
                client.register_key(key=key, access=Access.WRITE)
            for key in ("/robot/observation", "/robot/time"):
                client.register_key(key=key, access=Access.READ)
            service.setup(self.robot, client)
            self.services.append(service)
        initial = py_trees.blackboard.Client(name="mission:blackboard")
        for key, value in self.mission.blackboard.items():  # the mission's blackboard: entries
            initial.register_key(key=key, access=Access.WRITE)
            initial.set(key, value, overwrite=True)
        if self.resume is not None:
            obs = self.robot.observe()
            for service in self.services:
                restore = getattr(service, "restore", None)
                if restore is not None:
                    restore(self.resume, obs)
        self.tree.setup(robot=self.robot, seed=self.seed)
        self.start = self.now = float(self.robot.clock.now())
        self.wall_start = time.monotonic()
        self._setup_done = True

    def tick(self) -> Status:
        """One tick of ARCHITECTURE.md: observe, services, tree, command; the caller steps."""
        timing, clock = self.timing, self.timing_clock
        lap = clock() if timing is not None else 0.0
        obs = self.robot.observe()
        if timing is not None:
            lap = _lap(timing, "adapter: observe", lap, clock)
        self.observation = obs
        self.now = float(obs.stamp)
        self.bb.set("/robot/observation", obs, overwrite=True)
        self.bb.set("/robot/time", self.now, overwrite=True)
        rec = self.recorder
        if rec is not None:
            rec.record_observation(obs)
            if self.truth is not None:
                rec.record_truth(self.truth(), obs.stamp)
        for service in self.services:
            service.update(obs)
            if timing is not None:
                lap = _lap(timing, f"service: {service.name}", lap, clock)
        if rec is not None:
            rec.record_tags(obs.stamp, self.read(TAGS_KEY) or [])
        self.bb.set("/cmd_vel", None, overwrite=True)
        self.bb.set(IDLE_KEY, None, overwrite=True)
        self.bb.set(SAVE_KEY, False, overwrite=True)
        self.tree.tick()
        self._sweep()
        if timing is not None:
            lap = _lap(timing, "tree: leaves and runner", lap, clock)
        if self.run_dir is not None and self.read(SAVE_KEY):
            self.save_snapshot()
            if timing is not None:
                lap = _lap(timing, "run directory", lap, clock)
        cmd = self.bb.get("/cmd_vel")
        self.last_command = self.robot.command(cmd.v, cmd.omega) if isinstance(cmd, Twist2) else self.robot.command(0.0, 0.0)
        publish_world = getattr(self.robot, "publish_world", None)
        if callable(publish_world):  # a ROS 2 robot shows homing's world model in its graph
            nav = self.read(NAVIGATOR_KEY)
            publish_world(grid=self.read(GRID_KEY), map_to_odom=self.read(MAP_TO_ODOM_KEY),
                          path=getattr(nav, "path", None), goal=self.read(EXPLORE_GOAL_KEY),
                          state=self.read(STATE_KEY), statuses={n.name: n.status.value for n in self._nodes},
                          landmarks=self.read(LANDMARKS_KEY))  # fmt: skip
        if rec is not None:
            rec.record_command(obs.stamp, self.last_command)
            rec.record_image(obs.image)
            nav = self.read(NAVIGATOR_KEY)
            rec.record_plan(obs.stamp, getattr(nav, "path", None), self.read(EXPLORE_GOAL_KEY))
        self.ticks += 1
        return self.mission.root.status

    def run(self) -> RunResult:
        """Tick until the root finishes, the time limit or Ctrl-C; always stop and halt cleanly."""
        if not self._setup_done:
            self.setup()
        reason = "interrupted"
        try:
            while True:
                if self.until is not None and self.robot.clock.now() - self.start >= self.until - UNTIL_SLACK:
                    reason = "time_limit"
                    break
                status = self.tick()
                if self.on_tick is not None:
                    self.on_tick(self)
                if status in (Status.SUCCESS, Status.FAILURE):
                    reason = status.value.lower()
                    break
                if self._stop_requested or stop_requested():
                    break  # asked to stop (request_stop, or a signal whose exception was swallowed on its way)
                if self.timing is not None:
                    lap = self.timing_clock()
                    self.robot.step(self.next_step())
                    _lap(self.timing, "adapter: step (simulation)", lap, self.timing_clock)
                else:
                    self.robot.step(self.next_step())
                self._pace()
        except KeyboardInterrupt:
            reason = "interrupted"
        finally:
            root_status = self.mission.root.status
            self.shutdown()
        return RunResult(
            reason, self.robot.clock.now() - self.start, self.ticks, self.last_command,
            time.monotonic() - self.wall_start, self.changes, root_status,
        )  # fmt: skip

    def shutdown(self) -> None:
        """Zero command, halt the tree (running leaves cancel), record the halts, shut services down."""
        self.last_command = self.robot.command(0.0, 0.0)
        self.now = float(self.robot.clock.now())
        if self.recorder is not None:
            self.recorder.record_command(self.now, self.last_command)  # the log shows the robot stopped
        if self.mission.root.status == Status.RUNNING:
            self.mission.root.stop(Status.INVALID)
        self._sweep()
        for service in self.services:
            service.shutdown()
        self.tree.shutdown()
        if self.on_tick is not None:
            self.on_tick(self)

    def save_snapshot(self) -> Any:
        """Save what the robot keeps (services' state, counters, the dock, the simulator's) to ``run_dir``."""
        from homing.lifecycle.rundir import Snapshot

        snap = Snapshot(time=self.now, cycles=int(self.read(CYCLES_KEY) or 0), dock=self.read(DOCK_KEY),
                        meta=dict(self.meta))
        for service in self.services:
            keep = getattr(service, "snapshot", None)
            if keep is not None:
                keep(snap)
        state = getattr(self.robot, "state", None)
        snap.sim = state() if callable(state) else None
        folder = self.run_dir.save(snap)
        self.snapshots += 1
        return folder

    def next_step(self) -> float:
        """Seconds of adapter time to the next tick: one period, or up to the time a leaf said it may idle to."""
        idle_until = self.read(IDLE_KEY)
        cmd = self.last_command
        if idle_until is None or cmd.v != 0.0 or cmd.omega != 0.0:
            self._idling = False
            return self.period
        step = min(float(idle_until) - self.now, MAX_IDLE)
        if self.until is not None:
            step = min(step, self.start + self.until - self.now)
        if not self._idling:
            _release_memory()  # the first idle step of a stretch (a robot starting to charge): hand back what is free
        self._idling = True
        return max(self.period, step)

    def _pace(self) -> None:
        if not self.speed:
            return
        ahead = (self.robot.clock.now() - self.start) / self.speed - (time.monotonic() - self.wall_start)
        if ahead > 0:
            time.sleep(min(ahead, 1.0))

    def record(self, node: py_trees.behaviour.Behaviour) -> None:
        old = self._status.get(node.id, Status.INVALID)
        if node.status != old:
            self._status[node.id] = node.status
            self.changes += 1
            if self.recorder is not None:
                self.recorder.record_status(node.name, node.status.value, self.now)
            if self.on_change is not None:
                self.on_change(StatusChange(self.now, node.name, old, node.status))

    def _sweep(self) -> None:
        statuses = self._status
        for node in self._nodes:  # a flat list: walking py_trees' recursive iterate() every tick costs more
            if node.status is not statuses.get(node.id, Status.INVALID):
                self.record(node)

    def read(self, key: str) -> Any:
        """A blackboard entry for the view (None when unset)."""
        try:
            return self.bb.get(key)
        except KeyError:
            return None


def _lap(timing: dict[str, float], part: str, since: float, clock: Callable[[], float] = time.perf_counter) -> float:
    """Add the time on ``clock`` since ``since`` to ``timing[part]``; return now (the next part's start)."""
    now = clock()
    timing[part] = timing.get(part, 0.0) + (now - since)
    return now


class _ChangeVisitor(py_trees.visitors.VisitorBase):
    """Sees every node a tick yields, so changes inside one tick are logged too."""

    def __init__(self, runner: Runner):
        super().__init__(full=False)
        self.runner = runner

    def run(self, behaviour: py_trees.behaviour.Behaviour) -> None:
        self.runner.record(behaviour)


def _release_memory() -> None:
    """Return the C heap's free pages to the system (glibc's ``malloc_trim``; nothing elsewhere).

    A trip allocates and frees many large arrays (likelihood fields, costmaps, path searches); glibc keeps freed
    pages for reuse, so a process living for days showed a resident size that crept up in steps while what
    Python holds stayed flat (``bench persist``: tracemalloc +3 MB where RSS grew 25 MB in five hours).
    """
    libc = _libc()
    if libc:
        libc.malloc_trim(0)


# Blocks of at least this many bytes get a mapping of their own, handed back to the system when freed. glibc's
# default threshold (128 KiB) rises to the size of each mapped block freed, up to 32 MiB: after the first
# megabyte-sized likelihood field or costmap was freed, every later one came from the heap, whose holes then kept
# the resident size creeping up even after malloc_trim (bench persist, lab, one day: +13 MB with the default,
# +3 MB with this, for 7 % more wall time; every block from 128 KiB mapped: +5 MB, 35 % more wall time).
MMAP_THRESHOLD = 1 << 20  # [bytes]
M_MMAP_THRESHOLD = -3  # mallopt's parameter number (malloc.h)


def _steady_heap() -> None:
    """Fix glibc's mmap threshold at MMAP_THRESHOLD for this process (once; nothing elsewhere)."""
    global _STEADY
    libc = _libc()
    if libc and not _STEADY:
        _STEADY = bool(libc.mallopt(M_MMAP_THRESHOLD, MMAP_THRESHOLD))


def _libc() -> Any:
    """glibc's malloc controls, or False where there are none (not Linux, or another C library)."""
    global _LIBC
    if _LIBC is None:
        import ctypes
        import ctypes.util

        try:
            _LIBC = ctypes.CDLL(ctypes.util.find_library("c") or "libc.so.6")
            _LIBC.malloc_trim.argtypes = [ctypes.c_size_t]
            _LIBC.mallopt.argtypes = [ctypes.c_int, ctypes.c_int]
        except (OSError, AttributeError):
            _LIBC = False
    return _LIBC


_LIBC: Any = None
_STEADY = False


def parse_duration(text: str) -> float:
    """``"2h"``, ``"90 min"``, ``"30"`` (seconds) → seconds; raises ValueError."""
    from homing.missions.schema import parse_quantity

    value = parse_quantity(text, "s")
    if not value > 0:
        raise ValueError(f"a duration must be positive, not '{text}'")
    return value
