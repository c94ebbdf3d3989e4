"""Landmark map accuracy, thesis table 5.3: GTSAM iSAM2 vs the scan-matched grid vs raw odometry.

For each world and scenario the simulated TurtleBot drives while three
mappers watch the same data: the online GTSAM landmark SLAM
(:mod:`homing.mapping.landmark_slam`: odometry, tags, and lidar loop
closures that keep the heading consistent between passes), the scan-matched grid
(:mod:`homing.mapping.grid_slam`; each tag sighting placed through the grid's
pose and averaged per tag) and raw odometry (the same, through the odometry
pose). Each landmark map is compared with the world's true tags, aligned two
ways: on the dock's tag (as the thesis did: every map moved so that its dock
tag sits on the true one) and by the best-fit rigid transform (Kabsch). The
table gives the total and mean per-tag error [m], the keyframe trajectory
error (ATE, RMS after the best fit) and iSAM2's time per keyframe update.

Scenarios: ``loop`` — a driven loop past every tag and back to the dock
(the thesis's tele-operated run; the driver plans on the true map and steers
on the true pose, as a person with a joystick would); ``explore`` — the
autonomous exploration mission (``missions/explore.yaml`` with the
``tag_slam`` service added after ``grid_slam``) for ``--minutes`` of
simulated time; a world explored sooner (the lab: ~2 min) is then toured by
the robot itself from its own maps — alternately the next stretch of wall
its camera has not faced and the least-visited mapped tag (every third
tag visit the dock's) — until the time
is up (``--no-tour``: stop when exploration ends and measure
that); ``cycles`` — several
dock cycles in one map (undock, tour a share of the tags, return, drive onto
the dock, charge), driven like the loop. Every mapper sees the same tag
measurements (:class:`homing.perception.tag_wall.TagPerception`: the
detector, headings from the wall). ``synthetic`` times iSAM2 alone on a
10 000-keyframe graph (DESIGN.md quotes that median).

Worlds: ``--world`` (default ``lab``) and each ``--map-world`` map_server map
(default ``../shared/worlds/loop.yaml`` when run from the project root),
for which each run writes a world file in a temporary folder: the dock
auto-placed, the robot started docked and ``--tags`` tags added.

Runs go to ``--engine`` (:mod:`homing.benchmarks.engine`; ``local`` by
default, ``pool`` with ``--workers N``, ``ray [--address ADDR]``): one job
per world, scenario and seed, the same JSON for the same seeds on every
engine but the timings (``wall_s``, ``isam_update_ms_*``), a failed run
listed with its seed under ``failed``.

Scoring (alignments, errors, the collector): :mod:`homing.benchmarks.slam_score`.

Run: ``homing bench slam [--seeds N] [--scenarios loop,cycles] [--engine pool --workers 2] [--json PATH]``.
"""

from __future__ import annotations

import argparse
import math
import time
from pathlib import Path
from typing import Any

import numpy as np
from homing.benchmarks.common import find_plans, print_table, progress_bar, write_json
from homing.benchmarks.engine import add_engine_arguments
from homing.benchmarks.slam_score import Collector
from homing.mapping.landmark_slam import LandmarkSlam, SlamConfig
from homing.mapping.landmark_synthetic import synthetic_loop
from homing.robot import Pose2
from homing.robot.frames import wrap_angle

DT = 0.1  # [s] control period of the driver
VIEW_DISTANCE = 1.2  # [m] in front of a tag where the loop driver stops to look at it
DRIVE_V = 0.3  # [m/s]
ANCHOR_EVERY = 3  # the tour's every n-th tag visit is to the dock's tag (the anchor all tags are aligned on)
OPTIONS = {"scan_matched": False}  # set per run by run_one (in the worker that runs it)
SCENARIOS = ("loop", "explore", "cycles", "synthetic")
THESIS = {"teleoperated": (8.44, 7.04), "autonomous": (57.58, 72.96), "multiple": (7.02, 8.56)}


# -- scenarios ------------------------------------------------------------------


def _plan(world: Any, start: Pose2, goal: Pose2) -> list[tuple[float, float]]:
    """Waypoints [m] from start to goal on the true map, kept a robot radius from walls (A*)."""
    import pyastar2d
    from homing.sim.walls import world_to_cell
    from scipy import ndimage

    res = world.map.resolution
    solid = world.solid
    clearance = ndimage.distance_transform_edt(~solid) * res
    weights = np.where(clearance > 0.25, 1.0 + 2.0 / np.maximum(clearance, 0.05), np.inf).astype(np.float32)
    (r0,), (c0,) = world_to_cell(world.map, np.array([[start.x, start.y]]))
    (r1,), (c1,) = world_to_cell(world.map, np.array([[goal.x, goal.y]]))
    weights[r0, c0] = weights[r1, c1] = 1.0
    path = pyastar2d.astar_path(weights, (int(r0), int(c0)), (int(r1), int(c1)), allow_diagonal=True)
    if path is None:
        return [(goal.x, goal.y)]
    ox, oy = world.map.origin[0], world.map.origin[1]
    pts = [(ox + (c + 0.5) * res, oy + (r + 0.5) * res) for r, c in path[::6]]
    return pts[1:] + [(goal.x, goal.y)]


def _drive(robot: Any, col: Collector, waypoints: list[tuple[float, float]], face: float | None, limit: float) -> None:
    """Pure pursuit through ``waypoints`` on the true pose, then turn to ``face`` [rad] (the joystick)."""
    t_end = robot.clock.now() + limit
    for wx, wy in waypoints:
        while robot.clock.now() < t_end:
            obs = robot.observe()
            p = robot.truth_pose()
            col.step(obs, p)
            d = math.hypot(wx - p.x, wy - p.y)
            if d < 0.15:
                break
            err = wrap_angle(math.atan2(wy - p.y, wx - p.x) - p.theta)
            v = DRIVE_V * max(0.0, math.cos(err)) if abs(err) < 0.8 else 0.0
            robot.command(v, float(np.clip(1.5 * err, -1.0, 1.0)))
            robot.step(DT)
    while face is not None and robot.clock.now() < t_end:
        obs = robot.observe()
        p = robot.truth_pose()
        col.step(obs, p)
        err = wrap_angle(face - p.theta)
        if abs(err) < 0.05:
            break
        robot.command(0.0, float(np.clip(1.5 * err, -1.0, 1.0)))
        robot.step(DT)
    robot.command(0.0, 0.0)


def scenario_loop(world: Any, seed: int) -> dict[str, float]:
    """Drive past every tag (greedy nearest-first tour of view points) and back to face the dock."""
    from homing.sim import SimRobot

    robot = SimRobot(world, seed=seed)
    col = Collector(world.dock_tag_id, OPTIONS['scan_matched'])
    try:
        views = {t.id: Pose2(t.x, t.y, t.yaw).compose(Pose2(VIEW_DISTANCE, 0.0, math.pi)) for t in world.tags
                 if t.id != world.dock_tag_id}
        here = world.staging_pose(1.0)
        _drive(robot, col, [(here.x, here.y)], here.theta, 120.0)
        while views:
            i = min(views, key=lambda k: here.distance_to(views[k]))
            goal = views.pop(i)
            if not world.is_free(goal.x, goal.y):
                continue
            _drive(robot, col, _plan(world, robot.truth_pose(), goal), goal.theta, 240.0)
            here = goal
        stage = world.staging_pose(1.0)
        _drive(robot, col, _plan(world, robot.truth_pose(), stage), stage.theta, 300.0)
        return col.result({t.id: Pose2(t.x, t.y, t.yaw) for t in world.tags})
    finally:
        robot.close()


def _back_out(robot: Any, col: Collector, distance: float = 1.0) -> None:
    """Reverse straight out of the dock by ``distance`` [m] (the undock)."""
    for _ in range(int(round(distance / 0.2 / DT))):
        col.step(robot.observe(), robot.truth_pose())
        robot.command(-0.2, 0.0)
        robot.step(DT)
    robot.command(0.0, 0.0)


def _dock(robot: Any, col: Collector, world: Any, limit: float = 40.0) -> bool:
    """From the staging pose, drive onto the docked pose steering on the truth; True once charging."""
    goal = world.dock_pose
    t_end = robot.clock.now() + limit
    while robot.clock.now() < t_end and not robot.charging:
        col.step(robot.observe(), robot.truth_pose())
        p = robot.truth_pose()
        err = wrap_angle(math.atan2(goal.y - p.y, goal.x - p.x) - p.theta) if p.distance_to(goal) > 0.02 else 0.0
        robot.command(0.1 if abs(err) < 0.3 else 0.0, float(np.clip(2.0 * err, -0.5, 0.5)))
        robot.step(DT)
    robot.command(0.0, 0.0)
    return bool(robot.charging)


def _dwell(robot: Any, col: Collector, seconds: float) -> None:
    for _ in range(int(round(seconds / DT))):
        col.step(robot.observe(), robot.truth_pose())
        robot.command(0.0, 0.0)
        robot.step(DT)


def scenario_cycles(world: Any, seed: int, cycles: int = 3, dwell: float = 30.0) -> dict[str, float]:
    """Several dock cycles in one map: undock, tour a share of the tags, return, dock, charge; ``cycles`` times.

    Driven like the loop (on the true pose, as a person with a joystick):
    cycle k visits every ``cycles``-th tag's view point starting at k, so the
    map grows over the cycles and every return re-observes the dock's tag.
    """
    from homing.sim import SimRobot

    robot = SimRobot(world, seed=seed)
    col = Collector(world.dock_tag_id, OPTIONS['scan_matched'])
    try:
        views = [Pose2(t.x, t.y, t.yaw).compose(Pose2(VIEW_DISTANCE, 0.0, math.pi)) for t in world.tags
                 if t.id != world.dock_tag_id]
        views = [v for v in views if world.is_free(v.x, v.y)]
        stage = world.staging_pose(1.0)
        docked = 0
        for k in range(cycles):
            _back_out(robot, col)
            todo, here = views[k::cycles], stage
            while todo:
                goal = min(todo, key=here.distance_to)
                todo.remove(goal)
                _drive(robot, col, _plan(world, robot.truth_pose(), goal), goal.theta, 240.0)
                here = goal
            _drive(robot, col, _plan(world, robot.truth_pose(), stage), stage.theta, 300.0)
            docked += _dock(robot, col, world)
            _dwell(robot, col, dwell)
        out = col.result({t.id: Pose2(t.x, t.y, t.yaw) for t in world.tags})
        out.update(cycles=float(cycles), docked=float(docked))
        return out
    finally:
        robot.close()


def explore_mission() -> Path:
    """The bundled autonomous exploration mission (missions/explore.yaml)."""
    return Path(__file__).resolve().parents[1] / "missions" / "explore.yaml"


def explore_tour_mission(folder: Path, dock_tag: int = 0, tour: bool = True) -> Path:
    """missions/explore.yaml with ``tag_slam`` after ``grid_slam`` and, when ``tour``, a tag tour after it.

    Written to ``folder`` (the bundled file is left alone). Exploration of a
    small world ends long before 30 minutes (lab and loop: ~2 min: the lidar
    maps a corridor from afar, the camera reads tags within 3 m), so the
    tour keeps the robot going on its own, forever, alternating: a view pose
    facing the next unvisited stretch of wall of its own grid
    (``NextWallView``: finds tags exploration drove past) and the
    least-visited tag of its own landmark map (``NextTagView``: re-observes
    tags, closing loops; every ``ANCHOR_EVERY``-th tag visit is to the dock's
    tag, which every tag is aligned on, so its link to the rest of the map is
    measured from more than the first few minutes' passes — the returns a
    persistent robot makes to charge); ``NavigateToPose`` drives each on the
    tag-corrected map (a failed visit is skipped); the runner's time limit
    ends the run.
    """
    import yaml

    from homing.atomic import atomic_write

    src = explore_mission()
    if not src.is_file():
        raise FileNotFoundError(f"{src} is not there yet")
    doc = yaml.safe_load(src.read_text())
    services = list(doc.get("services") or [])
    names = [s if isinstance(s, str) else next(iter(s)) for s in services]
    if "tag_slam" not in names:
        services.insert(names.index("grid_slam") + 1 if "grid_slam" in names else 0, {"tag_slam": {"dock_tag": dock_tag}})
    doc["services"] = services
    if tour:
        def visit(name: str, pick: dict[str, Any]) -> dict[str, Any]:
            go = {"NavigateToPose": {"name": f"GoTo{name}", "goal_key": "/tag_tour/goal", "timeout": "120 s"}}
            return {"force_success": {"child": {"sequence": {"name": f"Visit{name}", "children": [pick, go]}}}}

        lap = {"sequence": {"name": "SearchThenRevisit", "children": [
            visit("Wall", {"NextWallView": {"distance": VIEW_DISTANCE}}),
            visit("Tag", {"NextTagView": {"distance": VIEW_DISTANCE, "anchor_tag": dock_tag,
                                          "anchor_every": ANCHOR_EVERY}}),
        ]}}
        doc["tree"] = {"sequence": {"name": "ExploreThenTour", "children": [
            doc["tree"],
            {"MissionState": {"name": "TourState", "state": "TouringTags"}},
            {"repeat": {"name": "TagTour", "times": -1, "child": lap}},
        ]}}
    out = folder / ("explore_tour.yaml" if tour else "explore_tags.yaml")
    atomic_write(out, yaml.safe_dump(doc, sort_keys=False, allow_unicode=True))
    return out


def _bb(r: Any, key: str) -> Any:
    try:
        return r.bb.get(key)
    except KeyError:
        return None


def scenario_explore(world: Any, seed: int, minutes: float, tour: bool = True) -> dict[str, float]:
    """The autonomous exploration mission with ``tag_slam`` online for ``minutes`` of sim time (then a tag tour).

    GTSAM is the mission's own ``tag_slam`` service (its landmarks steer the
    tour and its grid the navigation); the grid and odometry estimates place
    the very tag measurements that service took, through the ``grid_slam``
    service's scan-matched pose and through odometry.
    """
    import tempfile

    from homing.benchmarks.common import run_to_end
    from homing.missions.compiler import compile_mission
    from homing.missions.runner import Runner
    from homing.sim import SimRobot

    with tempfile.TemporaryDirectory(prefix="homing-explore-") as tmp:
        mission = compile_mission(explore_tour_mission(Path(tmp), world.dock_tag_id, tour), {"time_limit": f"{minutes:g} min"})
    robot = SimRobot(world, seed=seed)
    col = Collector(world.dock_tag_id, external=True)
    explored: list[float] = []

    def watch(r: Runner) -> None:
        obs = r.observation
        if obs is None or obs.stamp <= col.last_stamp:
            return
        svc: dict[str, Any] = {s.name: s for s in r.services}  # concrete services: their .slam
        col.slam = svc["tag_slam"].slam
        col.step_external(obs, robot.truth_pose(), _bb(r, "/perception/tags") or [], svc["grid_slam"].slam.pose)
        if not explored and _bb(r, "/mission/state") in ("Done", "TouringTags"):
            explored.append(obs.stamp)

    try:
        runner = Runner(mission, robot, seed=seed, until=60.0 * minutes, on_tick=watch)
        result = run_to_end(runner)
        out = col.result({t.id: Pose2(t.x, t.y, t.yaw) for t in world.tags})
        out.update(sim_minutes=result.time / 60.0, rtf=result.rtf,
                   explore_minutes=(explored[0] if explored else result.time) / 60.0)
        return out
    finally:
        robot.close()


def tagged_world(map_yaml: Path, folder: Path, n_tags: int = 10) -> Path:
    """A world YAML in ``folder`` over a map_server map, with the dock auto-placed and ``n_tags`` tags added."""
    from homing.atomic import atomic_write

    world = folder / f"{map_yaml.stem}_tags.yaml"
    atomic_write(world, f"name: {map_yaml.stem}_tags\nmap: {map_yaml.resolve()}\ndock: auto\n"
                        f"start: docked\ntags: {{auto: {n_tags}}}\n")
    return world


def synthetic_timing(poses: int, seed: int = 0) -> dict[str, float]:
    """iSAM2 update time per keyframe on a long synthetic drive (laps of a tagged loop) of ``poses`` keyframes."""
    laps = max(2, int(math.ceil(poses / 88)))
    run = synthetic_loop(seed, laps=laps)
    slam = LandmarkSlam(SlamConfig())
    t0 = time.perf_counter()
    for stamp, _, odom, seen in run.ticks:
        slam.update(stamp, odom, None, seen)
        if len(slam.keyframes) >= poses:
            break
    wall = time.perf_counter() - t0
    u = np.array(slam.update_ms)
    last = u[-1000:]
    return {"poses": float(len(slam.keyframes)), "landmarks": float(len(slam.landmark_ids)),
            "isam_update_ms_median": float(np.median(last)), "isam_update_ms_p95": float(np.percentile(last, 95)),
            "isam_update_ms_max": float(last.max()), "isam_update_ms_median_all": float(np.median(u)),
            "wall_s": wall}


# -- the command ----------------------------------------------------------------


def add_arguments(parser: argparse.ArgumentParser) -> None:
    from homing.missions.commands._args import count, positive, whole

    parser.add_argument("--seeds", type=count, default=1, help="runs per scenario and world (seeds 0..N-1)")
    parser.add_argument("--world", action="append", help="world name or YAML (repeatable; default: lab)")
    parser.add_argument(
        "--map-world", action="append", metavar="MAP.yaml",
        help="a map_server map to run in too, with the dock auto-placed and --tags tags added "
        "(repeatable; default: the public loop.yaml when found, see $HOMING_WORLDS)",
    )  # fmt: skip
    parser.add_argument("--tags", type=whole(0), default=10, help="tags added to each --map-world")
    parser.add_argument("--scenarios", default="loop,explore,cycles,synthetic",
                        help="comma-separated subset of loop, explore, cycles, synthetic")
    parser.add_argument("--minutes", type=positive, default=30.0, help="simulated minutes of the explore scenario")
    parser.add_argument("--no-tour", action="store_true",
                        help="explore scenario: end when exploration ends instead of touring the mapped tags")
    parser.add_argument("--cycles", type=count, default=3, help="dock cycles in the cycles scenario")
    parser.add_argument("--scan-matched", action="store_true",
                        help="also give GTSAM the grid's scan-matched motion between keyframes (robust factor)")
    parser.add_argument("--poses", type=count, default=10_000, help="keyframes in the synthetic iSAM2 timing graph")
    add_engine_arguments(parser, workers=1)


def _worlds(args: argparse.Namespace) -> list[tuple[str, str, int]]:
    """(label, world spec, tags to add) of every world to run: the named ones, then the map_server maps.

    A map_server map travels as its path and tag count: each run writes its
    own tagged world file (:func:`tagged_world`), so a worker on another
    machine needs only the map, at the same path.
    """
    out: list[tuple[str, str, int]] = [(w, w, 0) for w in (args.world or ["lab"])]
    maps = args.map_world
    if maps is None:
        maps = [str(p) for p in find_plans(("loop",), why="no --map-world run").values()]
    for m in maps:
        out.append((Path(m).stem + "+tags", str(Path(m).resolve()), args.tags))
    return out


def run_one(label: str, spec: str, tags: int, scen: str, seed: int, minutes: float, tour: bool, cycles: int,
            scan_matched: bool) -> dict[str, float]:
    """One scenario run, in whichever process the engine chose (all its options passed in, none global)."""
    import tempfile

    from homing.sim import load_world

    OPTIONS["scan_matched"] = scan_matched
    t0 = time.perf_counter()
    with tempfile.TemporaryDirectory(prefix="homing-bench-slam-") as tmp:
        world = load_world(tagged_world(Path(spec), Path(tmp), tags) if tags else spec)
        if scen == "loop":
            r = scenario_loop(world, seed)
        elif scen == "explore":
            r = scenario_explore(world, seed, minutes, tour=tour)
        elif scen == "cycles":
            r = scenario_cycles(world, seed, cycles)
        else:
            raise KeyError(f"unknown scenario '{scen}'")
    r["wall_s"] = time.perf_counter() - t0
    return r


def run(args: argparse.Namespace) -> int:
    from homing.benchmarks.engine import engine_from_args, failures_table, run_jobs

    from homing.errors import UserError

    scenarios = [s.strip() for s in args.scenarios.split(",") if s.strip()]
    unknown = [s for s in scenarios if s not in SCENARIOS]
    if unknown:
        raise UserError(f"unknown scenario {', '.join(unknown)} (known: {', '.join(SCENARIOS)})")
    engine = engine_from_args(args)
    worlds = _worlds(args) if any(s != "synthetic" for s in scenarios) else []
    for _, spec, _ in worlds:
        from homing.sim.world import resolve

        resolve(spec)  # a missing world is the user's mistake: say so before starting workers
    out: dict[str, Any] = {"scan_matched": bool(args.scan_matched)}
    rows: list[list[Any]] = []
    jobs = [(label, spec, tags, scen, seed, args.minutes, not args.no_tour, args.cycles, bool(args.scan_matched))
            for label, spec, tags in worlds for scen in scenarios if scen != "synthetic" for seed in range(args.seeds)]
    with progress_bar("slam", len(jobs)) as advance:
        outcomes = run_jobs(run_one, jobs, engine,
                            lambda o: advance(f"{o.job[0]}/{o.job[3]} seed {o.job[4]}" + ("" if o.ok else ": failed")))
    for label, _, _ in worlds:
        for scen in (s for s in scenarios if s != "synthetic"):
            key = f"{label}/{scen}"
            results = [o.result for o in outcomes if o.ok and o.job[0] == label and o.job[3] == scen]
            if not results:
                out[key] = {"failed": True}
                rows.append([key, "failed (see below)"] + [""] * 8)
                continue
            agg = {k: float(np.nanmean([r[k] for r in results])) for k in results[0]}
            agg["seeds"] = float(len(results))
            enough = agg["tags_seen"] >= 3 and agg["grid_total_m"] > 0  # a ratio of one or two tags means nothing
            agg["gtsam_over_grid"] = agg["gtsam_total_m"] / agg["grid_total_m"] if enough else math.nan
            out[key] = agg
            rows.append([key, agg["gtsam_total_m"], agg["grid_total_m"], agg["odom_total_m"], agg["gtsam_mean_m"],
                         agg["gtsam_fit_total_m"], agg["grid_fit_total_m"], agg["ate_m"],
                         agg["isam_update_ms_median"], f"{int(agg['tags_seen'])}/{int(agg['tags_total'])}"])
    if "synthetic" in scenarios:
        syn = synthetic_timing(args.poses)
        out["synthetic"] = syn
        rows.append([f"synthetic ({int(syn['poses'])} poses)", "", "", "", "", "", "", "", syn["isam_update_ms_median"], ""])
    print_table(
        "Landmark error vs truth (thesis table 5.3: GTSAM 24.36 m / grid 29.52 m total, averaged)",
        ["scenario", "GTSAM total (dock) m", "grid total m", "odom total m", "GTSAM mean m",
         "GTSAM total (fit) m", "grid total (fit) m", "ATE m", "iSAM2 ms median", "tags"],
        rows,
    )
    out["failed"] = failures_table(outcomes)
    for f in out["failed"]:
        print(f"failed: {f['job'][0]}/{f['job'][3]} seed {f['job'][4]}: {f['error']}")
    out["thesis_table_5_3"] = {k: {"gtsam_total_m": v[0], "grid_total_m": v[1]} for k, v in THESIS.items()}
    write_json(args.json, out)
    return 0
