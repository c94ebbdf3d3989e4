"""Days of the persistent mission: dock cycles, interventions, batteries, map agreement, memory and speed.

``homing bench persist --days D`` runs the bundled persistent mission
(``missions/persistent.yaml``) on a simulated TurtleBot 2 for D simulated
days, in a world that changes (:func:`homing.sim.events.random_changes`:
parcels left for hours, chairs moved, doorways closed a while) and with a
seeded fault every ``--fault-every`` (lidar dropout, camera off, wheel slip,
kidnap, an obstacle at the dock, a bumper hit, in turn). Nobody touches it,
unless it cannot carry on — the mission ends, a battery runs flat, or no dock
for ``STUCK`` hours — and then the bench counts an **intervention**, puts the
robot back on its dock and resumes from its last snapshot (the target is none).

Reported, per day and in all: dock cycles, interventions, the lowest battery
levels, the area mapped, the map's cell agreement with the world as it
stands at each dock (:func:`homing.mapping.evaluate.cell_agreement`, the
map pinned at the robot's true start; and after the small rigid correction
that aligns it best, :func:`~homing.mapping.evaluate.aligned_agreement`),
resident memory over time (``--plot`` draws it), wall time and the real-time
factor, the process's CPU time per simulated day (``cpu_per_day_min``: what a
loaded machine's waits do not inflate) — and where the wall time went, part by part of the tick (the
runner's own timing). JSON keys: ``dock_cycles``, ``interventions``,
``min_battery_pct``, ``rss_growth_after_1h_pct``, ``rtf``, ``map_agreement_min``
(and ``map_agreement_aligned_min``). Stopped by Ctrl-C or SIGTERM, it prints
and writes the figures of the time it simulated (``interrupted``,
``simulated_days``) and exits with the signal's status: a week's run stopped on
day 5 keeps its five days.
"""

from __future__ import annotations

import argparse
import math
import resource
import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np

DAY = 86400.0  # [s]
FAULT_KINDS = ("lidar_dropout", "camera_off", "wheel_slip", "kidnap", "dock_obstacle", "bumper_hit")
FAULT_ARGS: dict[str, dict[str, Any]] = {
    "lidar_dropout": {"duration": 10.0}, "camera_off": {"duration": 60.0},
    "wheel_slip": {"duration": 30.0, "amount": 0.5}, "kidnap": {},
    "dock_obstacle": {"duration": 120.0, "distance": 0.6}, "bumper_hit": {"side": "left"},
}
STUCK = 4.0  # [h] no dock for this long: the robot needs a hand
SAMPLE = 600.0  # [s] simulated time between memory samples


def add_arguments(parser: argparse.ArgumentParser) -> None:
    from homing.missions.commands._args import output_file, positive, seed

    parser.add_argument("--days", type=positive, default=1.0, help="simulated days (default 1)")
    parser.add_argument("--world", default="lab", help="world to live in (default: the lab)")
    parser.add_argument("--seed", type=seed, default=1, help="seed of the run, its world changes and faults")
    parser.add_argument("--fault-every", default="2 h", help="one fault per this much simulated time (0: none)")
    parser.add_argument("--no-changes", action="store_true", help="a world that never changes")
    parser.add_argument("--loop-closure", choices=("on", "off"), default=None,
                        help="grid_slam's loop closure (homing.mapping.lifelong); default: the mission's")
    parser.add_argument("--plot", metavar="PNG", type=output_file("--plot"), help="draw resident memory over time into PNG")


def rss_mb() -> float:
    """Resident memory of this process [MB] now (Linux /proc; the peak elsewhere)."""
    try:
        pages = int(Path("/proc/self/statm").read_text().split()[1])
        return pages * resource.getpagesize() / 1e6
    except (OSError, ValueError, IndexError):
        return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1e3


def fault_schedule(seed: int, horizon: float, every: float) -> list[Any]:
    """One fault per ``every`` [s], seeded time within its window, the kinds in turn."""
    from homing.sim import Fault

    if every <= 0:
        return []
    rng = np.random.default_rng([seed, 9173])
    out = []
    for k in range(int(horizon // every)):
        kind = FAULT_KINDS[k % len(FAULT_KINDS)]
        out.append(Fault(kind, at=float(k * every + rng.uniform(0.1, 0.9) * every), **FAULT_ARGS[kind]))
    return out


class Life:
    """What the bench watches while the robot lives (called by the runner after every tick)."""

    def __init__(self, robot: Any, world: Any, horizon: float, progress: Any) -> None:
        self.robot, self.world, self.horizon, self.progress = robot, world, horizon, progress
        self.cycles = 0
        self.last_dock = 0.0
        self.lowest = {"base": math.inf, "computer": math.inf}
        self.agreement: list[tuple[float, float]] = []  # (time, cell agreement) at each dock
        self.aligned: list[tuple[float, float]] = []  # (time, cell agreement after aligning the map) at each dock
        self.rss: list[tuple[float, float]] = [(0.0, rss_mb())]
        self.area = 0.0
        self.stuck: str | None = None
        self.next_sample = SAMPLE
        self.next_progress = 0.0
        self.states: dict[str, list[float]] = {}  # mission state -> [simulated s, wall s] spent in it
        self.coverage: list[tuple[float, float]] = []  # (time, coverage of the navigable area) at each dock
        self.keyframes: list[tuple[float, int]] = []  # (time, keyframes of grid_slam's pose graph) at each dock
        self.errors: dict[str, list[float]] = {}  # why the robot entered Error -> [times, simulated s in Error]
        self._error_reason: str | None = None  # the reason of the Error stretch under way
        self._last: tuple[float, float, str] | None = None  # (sim time, wall time, state) at the last call

    def __call__(self, runner: Any) -> None:
        from homing.mapping.evaluate import aligned_agreement, cell_agreement, coverage

        obs, now = runner.observation, runner.now
        wall, state = time.perf_counter(), str(runner.read("/mission/state") or "Starting")
        if self._last is not None:
            spent = self.states.setdefault(self._last[2], [0.0, 0.0])
            spent[0] += now - self._last[0]
            spent[1] += wall - self._last[1]
            if self._error_reason is not None:
                self.errors[self._error_reason][1] += now - self._last[0]
        if state == "Error" and (self._last is None or self._last[2] != "Error"):
            self._error_reason = error_cause(runner)
            self.errors.setdefault(self._error_reason, [0.0, 0.0])[0] += 1
        elif state != "Error":
            self._error_reason = None
        if obs is not None:
            self.lowest["base"] = min(self.lowest["base"], obs.battery.percent)
            if obs.computer_battery is not None:
                self.lowest["computer"] = min(self.lowest["computer"], obs.computer_battery.percent)
            if min(self.lowest.values()) <= 0.0:
                self.stuck = "a battery ran flat"
        cycles = int(runner.read("/mission/cycles") or 0)
        if cycles != self.cycles:
            self.cycles, self.last_dock = cycles, now
            grid = runner.services[0].slam.grid
            truth = self.robot.truth_map()
            self.agreement.append((now, cell_agreement(grid, truth, self.world.dock_pose)))
            self.aligned.append((now, aligned_agreement(grid, truth, self.world.dock_pose)[0]))
            self.keyframes.append((now, len(getattr(runner.services[0].slam, "nodes", ()))))
            self.area = float((grid.data == 0).sum()) * grid.resolution**2
            start = (self.world.start.x, self.world.start.y)  # the building's navigable area, as bench explore
            self.coverage.append((now, coverage(grid, self.world.map, start, self.world.dock_pose).coverage))
        if now - self.last_dock > STUCK * 3600.0 and not obs.battery.on_dock:
            self.stuck = f"no dock for {STUCK:g} h"
        if now >= self.next_sample:
            self.next_sample = now + SAMPLE
            self.rss.append((now, rss_mb()))
        if now >= self.next_progress:
            self.next_progress = now + 60.0
            self.progress(now)
        if self.stuck is not None:
            runner.request_stop()
        # This benchmark's own work (the agreement with the truth at a dock, RSS samples) is no mission state's.
        self._last = (now, time.perf_counter(), state)


def error_cause(runner: Any) -> str:
    """Which Error is running (named for the state it recovers) and the typed failure that sent the robot there:
    the failure reason of the leaf that failed beside it (its recovery node's child)."""
    from py_trees.common import Status

    error = next((n for n in runner.mission.root.iterate()
                  if n.status == Status.RUNNING and n.name.endswith("Error")), None)
    if error is None:
        return "Error: no Error node running"
    node = error
    while node.parent is not None:
        for sibling in node.parent.children:
            if sibling is node:
                continue
            failed = next((n for n in sibling.iterate()
                           if n.status == Status.FAILURE and getattr(n, "failure_reason", None)), None)
            if failed is not None:
                return f"{error.name}: {failed.name} {failed.failure_reason}"
        node = node.parent
    return f"{error.name}: no typed reason"


def live(world_spec: str, seed: int, horizon: float, fault_every: float, changes: bool,
         progress: Any, loop_closure: bool | None = None) -> dict[str, Any]:
    """Run the persistent mission for ``horizon`` [s]; resets (interventions) when it cannot carry on. A stop
    signal ends it early with ``interrupted`` True and the figures of the time simulated so far."""
    from homing.lifecycle.rundir import RunDir
    from homing.missions.compiler import compile_mission
    from homing.missions.loader import resolve_mission
    from homing.missions.runner import Runner
    from homing.sim import SimRobot, load_world
    from homing.sim.events import random_changes

    world = load_world(world_spec)
    world_changes = (random_changes(world.map, world.reachable_free(), world.staging_pose(1.0), seed, horizon)
                     if changes else [])
    robot = SimRobot(world, seed=seed, faults=fault_schedule(seed, horizon, fault_every), changes=world_changes)
    mission = compile_mission(resolve_mission("persistent"),
                              None if loop_closure is None else {"loop_closure": loop_closure})
    life = Life(robot, world, horizon, progress)
    timing: dict[str, float] = {}
    interventions: list[tuple[float, str]] = []
    interrupted = False
    wall0, cpu0 = time.monotonic(), time.process_time()
    with tempfile.TemporaryDirectory() as tmp:
        run_dir = RunDir(Path(tmp) / "run")
        snap = None
        try:
            while robot.clock.now() < horizon - 1e-6:
                runner = Runner(mission, robot, seed=seed, until=horizon - robot.clock.now(), run_dir=run_dir,
                                resume=snap, on_tick=life, timing=timing)
                result = runner.run()
                if result.reason == "interrupted" and life.stuck is None:
                    interrupted = True  # Ctrl-C or SIGTERM stops the benchmark, not one life of the robot
                    break
                if result.reason == "time_limit":
                    break
                # It could not carry on: a person puts it back on its dock, charged, and restarts it.
                interventions.append((robot.clock.now(), life.stuck or f"the mission ended ({result.reason})"))
                life.stuck, life.last_dock = None, robot.clock.now()
                robot.set_truth_pose(world.dock_pose)
                robot.base_battery.soc = robot.computer_battery.soc = 1.0
                snap = run_dir.load() if run_dir.has_run() else None
                if snap is not None:
                    snap.sim = None
        finally:
            robot.close()
    wall, cpu = time.monotonic() - wall0, time.process_time() - cpu0
    return {"life": life, "timing": timing, "interventions": interventions, "wall": wall, "cpu": cpu,
            "changes": len(world_changes), "faults": len(robot.faults), "time": robot.clock.now(),
            "interrupted": interrupted}


def run(args: argparse.Namespace) -> int:
    from homing.benchmarks.common import print_table, write_json
    from homing.missions.runner import parse_duration
    from rich.progress import BarColumn, Progress, TextColumn, TimeElapsedColumn

    from homing.errors import UserError
    from homing.signals import exit_status, received, signal_name

    if not (math.isfinite(args.days) and args.days > 0):
        raise UserError(f"--days must be a positive number, not {args.days:g}")
    try:
        every = 0.0 if str(args.fault_every).strip() in ("0", "0 h", "0h") else parse_duration(args.fault_every)
    except ValueError as err:
        raise UserError(f"--fault-every: {err}") from None
    horizon = args.days * DAY
    with Progress(TextColumn("[bold]simulated"), BarColumn(), TextColumn("{task.description}"),
                  TimeElapsedColumn()) as bar:
        task = bar.add_task("", total=horizon)
        out = live(args.world, args.seed, horizon, every, not args.no_changes,
                   lambda t: bar.update(task, completed=t, description=f"{t / 3600:5.1f} h"),
                   None if args.loop_closure is None else args.loop_closure == "on")
    life: Life = out["life"]
    wall, sim = out["wall"], out["time"]
    rss = life.rss
    at_1h = next((m for t, m in rss if t >= 3600.0), rss[0][1])
    growth = 100.0 * (rss[-1][1] - at_1h) / at_1h
    agree = [a for _, a in life.agreement]
    days = []
    # A stop signal ends the run early: its figures are the time simulated so far, printed and written as such.
    cut = f", interrupted by {signal_name(received())} at {sim / 3600:.2f} h" if out["interrupted"] else ""
    for d in range(max(1, math.ceil(min(args.days, sim / DAY)))):
        lo, hi = d * DAY, (d + 1) * DAY
        # RSS swings by tens of MB within a day (allocator and arrays that come and go): the day's median shows
        # growth, the max the peak, the last sample against the first hour's (the JSON key) neither reliably.
        held = [m for t, m in rss if lo <= t < hi and t >= 3600.0]
        days.append([d + 1, sum(1 for t, _ in life.agreement if lo <= t < hi),
                     next((c for t, c in reversed(life.coverage) if t < hi), math.nan),
                     min((a for t, a in life.agreement if lo <= t < hi), default=math.nan),
                     min((a for t, a in life.aligned if lo <= t < hi), default=math.nan),
                     float(np.median(held)) if held else math.nan,
                     max((m for t, m in rss if lo <= t < hi), default=math.nan)])
    print_table(f"bench persist: {args.world}, {args.days:g} day(s){cut}, seed {args.seed}, {out['changes']} world "
                f"changes, {out['faults']} faults; coverage of the navigable area at the day's last dock",
                ["day", "dock cycles", "coverage", "agreement min", "aligned min", "RSS MB median", "RSS MB max"],
                days)
    summary = [["dock cycles", life.cycles], ["interventions", len(out["interventions"])],
               ["lowest battery, base %", life.lowest["base"]], ["lowest battery, computer %", life.lowest["computer"]],
               ["area mapped m²", life.area], ["map agreement min", min(agree, default=math.nan)],
               ["map agreement min, aligned", min((a for _, a in life.aligned), default=math.nan)],
               ["RSS growth after 1 h %", growth], ["wall time s", wall], ["real-time factor", sim / wall],
               ["wall per simulated day min", wall / max(sim / DAY, 1e-9) / 60.0],
               # CPU time (one process, the simulator in it) does not count the waits for a loaded machine's cores.
               ["CPU time s", out["cpu"]], ["CPU per simulated day min", out["cpu"] / max(sim / DAY, 1e-9) / 60.0]]
    print_table("in all", ["figure", "value"], summary)
    total = sum(out["timing"].values())
    parts = sorted(out["timing"].items(), key=lambda kv: -kv[1])
    print_table("where the wall time went (the runner's timing)", ["part", "% of ticks", "ms per sim min"],
                [[k, 100 * v / total, 1e3 * v / max(sim / 60.0, 1e-9)] for k, v in parts])
    states = sorted(life.states.items(), key=lambda kv: -kv[1][1])
    print_table("where the wall time went, by mission state", ["state", "% of sim time", "% of wall", "wall ms per sim s"],
                [[k, 100 * v[0] / max(sim, 1e-9), 100 * v[1] / max(wall, 1e-9), 1e3 * v[1] / max(v[0], 1e-9)]
                 for k, v in states])
    error_s = sum(v[1] for v in life.errors.values())
    print_table(f"why it entered Error ({100 * error_s / max(sim, 1e-9):.2f} % of the simulated time)",
                ["reason", "times", "simulated s", "% of sim time"],
                [[k, int(v[0]), v[1], 100 * v[1] / max(sim, 1e-9)]
                 for k, v in sorted(life.errors.items(), key=lambda kv: -kv[1][1])] or [["none", 0, 0.0, 0.0]])
    if args.plot:
        _plot(args.plot, rss)
    write_json(args.json, {
        "dock_cycles": life.cycles, "interventions": len(out["interventions"]),
        "intervention_reasons": out["interventions"], "min_battery_pct": min(life.lowest.values()),
        "min_battery_base_pct": life.lowest["base"], "min_battery_computer_pct": life.lowest["computer"],
        "rss_growth_after_1h_pct": growth, "rss_mb": rss, "rtf": sim / wall, "wall_s": wall,
        "cpu_s": out["cpu"], "cpu_per_day_min": out["cpu"] / max(sim / DAY, 1e-9) / 60.0,
        "map_agreement_min": min(agree, default=math.nan), "map_agreement": life.agreement,
        "map_agreement_aligned_min": min((a for _, a in life.aligned), default=math.nan),
        "map_agreement_aligned": life.aligned,
        "keyframes_at_dock": life.keyframes,
        "area_mapped_m2": life.area, "timing_s": out["timing"], "days": args.days, "world": args.world,
        "interrupted": out["interrupted"], "simulated_days": sim / DAY,
        "seed": args.seed, "loop_closure": args.loop_closure, "rss_median_by_day_mb": [row[5] for row in days],
        "coverage_navigable": life.coverage, "coverage_navigable_by_day": [row[2] for row in days],
        "error_pct": 100 * error_s / max(sim, 1e-9),
        "error_reasons": {k: {"times": int(v[0]), "sim_s": v[1]} for k, v in life.errors.items()}, "states_s": {k: {"sim": v[0], "wall": v[1]} for k, v in life.states.items()},
    })
    return exit_status(received()) if out["interrupted"] else 0


def _plot(path: str, rss: list[tuple[float, float]]) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import io

    import matplotlib.pyplot as plt

    from homing.atomic import atomic_write

    t = np.array([a for a, _ in rss]) / 3600.0
    m = np.array([b for _, b in rss])
    fig, ax = plt.subplots(figsize=(8, 3.5))
    ax.plot(t, m, lw=1.2)
    ax.set_xlabel("simulated time [h]")
    ax.set_ylabel("resident memory [MB]")
    ax.set_ylim(0, max(m) * 1.15)
    ax.grid(alpha=0.3)
    fig.tight_layout()
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=110)
    plt.close(fig)
    atomic_write(path, buf.getvalue())
    print(f"memory plot: {path}")
