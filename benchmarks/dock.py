"""Go home and dock, thesis table 5.2: arrival and autodock rates and docking time, recovery on and off.

Mata 2017 §5.2.2 measured, over five runs each, how often the TurtleBot got
back to its dock area once it decided to go home (*arrival*: from MapHome to
AutoDocking), how often it then docked (*autodock*), and how long that took,
with its recovery behaviours on and off (68 % / 80 % arrival, 68 % / 39 %
autodock, 95 s / 64 s docking). Here, ``--runs`` seeded runs per variant:

1. The robot explores the world once (the persistent mission, seed 0) and
   keeps its own map, tag estimates and dock: every run starts from that
   snapshot, as a robot that has lived there does.
2. Run *k* places the robot on a reachable floor cell a seeded 2–15 m path
   distance from the staging pose, any heading, with its map pose off by
   the drift of a trip (σ 0.10 m, 2°), and one fault of every kind in turn
   (lidar dropout, camera off, wheel slip, kidnap, an obstacle at the dock
   for a minute, a bumper hit) within the first 30 s; the low-friction
   patches of the world stay where they are.
3. It goes home and docks: ``recovery`` runs the persistent mission's own
   MapHome and AutoDocking subtrees (Error rounds, back-off and retry, a
   round-robin of recoveries); ``no_recovery`` the same leaves once each,
   with no retry, the thesis's baseline with its recoveries disabled.

Docked means charging (truth and the charger agree), within ``--time-limit``.
Times are from the decision to go home to charging. JSON keys, under
``recovery`` and ``no_recovery``: ``arrival_rate``, ``autodock_rate``,
``dock_time_median_s`` (and p90, attempts, per-fault docking rates).
"""

from __future__ import annotations

import argparse
import math
import tempfile
from pathlib import Path
from typing import Any

import numpy as np

FAULT_KINDS = ("lidar_dropout", "camera_off", "wheel_slip", "kidnap", "dock_obstacle", "bumper_hit")
FAULT_ARGS: dict[str, dict[str, Any]] = {
    "lidar_dropout": {"duration": 10.0}, "camera_off": {"duration": 40.0},
    "wheel_slip": {"duration": 20.0, "amount": 0.5}, "kidnap": {},
    "dock_obstacle": {"duration": 60.0, "distance": 0.6}, "bumper_hit": {"side": "left"},
}
VARIANTS = ("recovery", "no_recovery")
DRIFT_XY = 0.10  # [m] σ of the map pose's error at the start (a trip's drift)
DRIFT_THETA = math.radians(2.0)  # [rad]
MIN_DISTANCE, MAX_DISTANCE = 2.0, 15.0  # [m] path distance from the staging pose
EXPLORE_TIME = 900.0  # [s] the preliminary exploration's session

NO_RECOVERY = """
    sequence:
      name: GoHomeOnce
      children:
        - MissionState: {state: MapHome}
        - GoHome: {staging_distance: 1.0, timeout: 10 min}
        - ServoToStaging: {tag: $dock_tag, staging_distance: 1.0, timeout: 60 s}
        - MissionState: {state: AutoDocking}
        - AutoDock: {timeout: 90 s, approach: 1.0}
"""
RECOVERY = """
    recovery:
      name: GoHomeWithRecovery
      retries: 1000
      recovery: {Error: {name: CycleError}}
      child:
        sequence:
          - ReturnHome: {name: MapHome, dock_tag: $dock_tag, staging_distance: 1.0, recoveries: 50}
          - DockOnIR: {name: AutoDocking, dock_tag: $dock_tag, staging_distance: 1.0, dock_retries: 6}
"""


def add_arguments(parser: argparse.ArgumentParser) -> None:
    from homing.benchmarks.engine import add_engine_arguments
    from homing.missions.commands._args import count

    parser.add_argument("--runs", type=count, default=20, help="seeded runs per variant (the thesis: 5)")
    parser.add_argument("--world", default="lab", help="world to dock in (default: the lab)")
    parser.add_argument("--time-limit", default="15 min", help="a run that has not docked by then failed")
    parser.add_argument("--variants", nargs="+", choices=VARIANTS, default=list(VARIANTS))
    add_engine_arguments(parser)


def mission_file(folder: Path, variant: str, dock_tag: int) -> Path:
    """The go-home mission of ``variant``, using the bundled persistent mission's subtrees."""
    from homing.missions.loader import resolve_mission

    body = RECOVERY if variant == "recovery" else NO_RECOVERY
    text = (f"mission: dock_{variant}\nrate: 5\ninclude: [{resolve_mission('persistent')}]\n"
            f"services:\n  - grid_slam\n  - tag_slam: {{grid: false, dock_tag: {dock_tag}, image_rate: 0.5 Hz}}\n"
            f"  - navigation: {{planner: astar}}\n  - energy\nparams: {{dock_tag: {dock_tag}}}\ntree:\n{body}")
    path = folder / f"dock_{variant}.yaml"
    path.write_text(text)
    return path


def explored(world_spec: str, folder: Path) -> Path:
    """Explore the world once with the persistent mission and keep the robot's snapshot (its map, tags, dock)."""
    from homing.benchmarks.common import run_to_end
    from homing.lifecycle.rundir import RunDir
    from homing.missions.compiler import compile_mission
    from homing.missions.loader import resolve_mission
    from homing.missions.runner import Runner
    from homing.sim import SimRobot, load_world

    run_dir = RunDir(folder / "explored")
    robot = SimRobot(load_world(world_spec), seed=0)
    mission = compile_mission(resolve_mission("persistent"), {"session": f"{EXPLORE_TIME:g} s", "cycles": 1})
    runner = Runner(mission, robot, seed=0, until=EXPLORE_TIME + 900.0, run_dir=run_dir)
    try:
        run_to_end(runner)
    finally:
        robot.close()
    if not run_dir.has_run():
        raise RuntimeError(f"the preliminary exploration of {world_spec} never docked")
    return run_dir.path


def _path_distance(world: Any) -> np.ndarray:
    """(H, W) path distance [m] from the staging pose over the true floor the robot fits on (evaluation code)."""
    import skfmm
    from homing.sim.walls import world_to_cell
    from scipy import ndimage

    free = world.reachable_free()
    room = ndimage.distance_transform_edt(free) * world.map.resolution >= 0.25
    stage = world.staging_pose(1.0)
    r, c = world_to_cell(world.map, np.array([[stage.x, stage.y]]))
    phi = np.ones(room.shape)
    phi[int(r[0]), int(c[0])] = -1.0
    d = skfmm.distance(np.ma.MaskedArray(phi, ~room), dx=world.map.resolution)
    return np.asarray(d.filled(np.inf))


def one_run(world_spec: str, snapshot_dir: str, variant: str, seed: int, time_limit: float) -> dict[str, Any]:
    """One go-home-and-dock run; its outcome and times."""
    from homing.benchmarks.common import run_to_end
    from homing.lifecycle.rundir import RunDir
    from homing.missions.compiler import compile_mission
    from homing.missions.runner import Runner
    from homing.robot import Pose2
    from homing.sim import Fault, SimRobot, load_world
    from homing.sim.walls import cell_to_world
    from py_trees.common import Status

    world = load_world(world_spec)
    rng = np.random.default_rng([seed, 5201])
    dist = _path_distance(world)
    reach = float(np.nanmax(np.where(np.isfinite(dist), dist, np.nan)))
    want = float(rng.uniform(MIN_DISTANCE, min(MAX_DISTANCE, reach)))
    cells = np.argwhere(np.abs(dist - want) <= 0.5)
    r, c = cells[rng.integers(len(cells))]
    xy = cell_to_world(world.map, np.array([r]), np.array([c]))[0]
    start = Pose2(float(xy[0]), float(xy[1]), float(rng.uniform(-math.pi, math.pi)))
    kind = FAULT_KINDS[seed % len(FAULT_KINDS)]
    fault = Fault(kind, at=float(rng.uniform(2.0, 30.0)), **FAULT_ARGS[kind])
    snap = RunDir(snapshot_dir).load()
    snap.sim = None
    in_map = world.dock_pose.inverse().compose(start)  # the exploration's map frame is the docked pose's
    snap.pose = in_map.compose(Pose2(*rng.normal(0.0, [DRIFT_XY, DRIFT_XY, DRIFT_THETA])))
    robot = SimRobot(world, seed=seed, start=start, faults=[fault])
    with tempfile.TemporaryDirectory() as tmp:
        mission = compile_mission(mission_file(Path(tmp), variant, world.dock_tag_id))
    arrived: list[float] = []
    attempts = 0

    def on_change(change: Any) -> None:
        nonlocal attempts
        if change.node == "AutoDock" and change.new is Status.RUNNING:
            attempts += 1
            if not arrived:
                arrived.append(change.time)

    runner = Runner(mission, robot, seed=seed, until=time_limit, resume=snap, on_change=on_change)
    try:
        result = run_to_end(runner)
        docked = robot.charging and result.root_status is Status.SUCCESS
    finally:
        robot.close()
    return {"variant": variant, "seed": seed, "fault": kind, "distance": want, "arrived": bool(arrived),
            "docked": bool(docked), "time": result.time if docked else math.nan, "attempts": attempts,
            "wall": result.wall}


def summary(rows: list[dict[str, Any]]) -> dict[str, Any]:
    """The table 5.2 figures of one variant's runs."""
    n = len(rows)
    arrived = [r for r in rows if r["arrived"]]
    docked = [r for r in rows if r["docked"]]
    times = np.array([r["time"] for r in docked], dtype=float)
    out: dict[str, Any] = {
        "runs": n,
        "arrival_rate": len(arrived) / n if n else math.nan,
        "autodock_rate": len(docked) / len(arrived) if arrived else math.nan,
        "docked_rate": len(docked) / n if n else math.nan,
        "dock_time_median_s": float(np.median(times)) if len(times) else math.nan,
        "dock_time_p90_s": float(np.percentile(times, 90)) if len(times) else math.nan,
        "attempts_mean": float(np.mean([r["attempts"] for r in arrived])) if arrived else math.nan,
        "by_fault": {k: float(np.mean([r["docked"] for r in rows if r["fault"] == k]))
                     for k in FAULT_KINDS if any(r["fault"] == k for r in rows)},
    }
    return out


def _one(x: float) -> str:
    """A rate [%] or a time [s] to one decimal (the table's cells)."""
    return "–" if math.isnan(x) else f"{x:.1f}"


def run(args: argparse.Namespace) -> int:
    from homing.benchmarks.common import print_table, progress_bar, write_json
    from homing.benchmarks.engine import engine_from_args, failures_table, run_jobs
    from homing.missions.runner import parse_duration
    from homing.sim import load_world

    from homing.errors import UserError

    if args.runs < 1:
        raise UserError(f"--runs must be ≥ 1, not {args.runs}")
    try:
        limit = parse_duration(args.time_limit)
    except ValueError as err:
        raise UserError(f"--time-limit: {err}") from None
    world = load_world(args.world)
    engine = engine_from_args(args)
    with tempfile.TemporaryDirectory() as tmp:
        print(f"exploring {world.name} once for the robot's own map (up to {EXPLORE_TIME / 60:g} simulated minutes)…")
        snapshot = str(explored(args.world, Path(tmp)))
        jobs = [(args.world, snapshot, v, seed, limit) for v in args.variants for seed in range(1, args.runs + 1)]
        with progress_bar("dock runs", len(jobs)) as done:
            outcomes = run_jobs(one_run, jobs, engine,
                                on_done=lambda o: done(f"{o.job[2]} seed {o.job[3]}: "
                                                       f"{'docked' if o.ok and o.result['docked'] else 'failed'}"))
    rows = [o.result for o in outcomes if o.ok]
    figures: dict[str, Any] = {v: summary([r for r in rows if r["variant"] == v]) for v in args.variants}
    thesis = {"recovery": (68, 68, 95), "no_recovery": (80, 39, 64)}
    table = []
    for v in args.variants:
        f = figures[v]
        t = thesis[v]
        table.append([v, f["runs"], _one(100 * f["arrival_rate"]), _one(100 * f["autodock_rate"]),
                      _one(f["dock_time_median_s"]), _one(f["dock_time_p90_s"]), f"{f['attempts_mean']:.2f}",
                      f"{t[0]}/{t[1]}/{t[2]} s"])
    print_table(f"bench dock: {world.name}, {args.runs} runs per variant, one fault each",
                ["variant", "runs", "arrive %", "dock %", "median s", "p90 s", "tries", "thesis a/d/t"], table)
    fault_rows = [[k, *(_one(100 * figures[v]["by_fault"].get(k, math.nan)) for v in args.variants)]
                  for k in FAULT_KINDS]
    print_table("docked per fault [%]", ["fault", *args.variants], fault_rows)
    failed = failures_table(outcomes)
    if failed:
        figures["failed"] = failed
    figures["runs"] = rows
    write_json(args.json, figures)
    return 0
