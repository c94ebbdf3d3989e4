"""Navigation in the simulator: success, bumper presses, time and path length against the planner's optimum, per controller.

For every world (the six public floor plans, when found: ``$HOMING_WORLDS`` or
``../shared/worlds``; and the bundled ``lab``) and seed, the simulated TurtleBot backs off its dock and is
sent through ``--goals`` seeded random goals, each at least ``MIN_LEG`` away
from the last, among the reachable free cells with room for the robot
(truth, evaluation only). Every controller (``rpp`` with its ``dwb``
fallback, ``dwb`` alone) drives the same legs from the same seed.

Grid sources (``--grids``):

- ``true``: the world's map and the simulator's true pose (a perfect
  localiser: this measures navigation alone);
- ``slam``: :class:`homing.mapping.grid_slam.GridSlam` on odometry and scans,
  starting from nothing — goals in unknown space are planned through, and
  the grid and the scan-matched pose are what the navigator sees.

The dock is below the lidar's plane; as a mission would, the benchmark
marks it as a keep-out zone from where the robot started (docked), in the
navigator's map frame (:func:`homing.navigation.layers.dock_keepout`).

Per leg: success (the navigator reports the goal reached *and* the true
pose is within the tolerance plus ``TRUTH_SLACK``), success in the map
(the same, with the pose the navigator was given: navigation's share), bumper presses (rising
edges of any bumper), simulated time, and the true path length divided by
the planner's optimum on the true map from where the leg started
(``fmm`` on the same costmap the navigator uses). With ``slam``, the
localisation error at the leg's end (the scan-matched pose moved into the
world frame against the true pose; the map frame is the odometry frame at
the start, whose place in the world the evaluation knows) tells SLAM's share
of a miss from navigation's (``nav_miss``: believed pose to goal, in ``map``).
"""

from __future__ import annotations

import argparse
import math
import time
from typing import Any

import numpy as np
from homing.benchmarks.common import PUBLIC_PLANS, find_plans, print_table, write_json

RATE = 10.0  # [Hz] control ticks
MIN_LEG = 3.0  # [m] straight-line distance between consecutive goals
GOAL_CLEARANCE = 0.45  # [m] goals this far from any wall (truth)
LEG_LIMIT = 180.0  # [s] simulated time allowed per leg
BACK_OFF = 0.3  # [m] off the dock before the first leg
TRUTH_SLACK = 0.10  # [m] the true pose may miss the goal by the tolerance plus this


def add_arguments(parser: argparse.ArgumentParser) -> None:
    from homing.missions.commands._args import count

    parser.add_argument("--worlds", nargs="*",
                        help="bundled world names, public floor plan names, world YAMLs or map_server YAMLs "
                             "(default: the six public maps found + lab)")
    parser.add_argument("--goals", type=count, default=5, help="goals per world and seed")
    parser.add_argument("--seeds", type=count, default=1, help="seeds 1..N")
    parser.add_argument("--controllers", nargs="*", default=["rpp", "dwb"])
    parser.add_argument("--grids", nargs="*", default=["true"], choices=["true", "slam"],
                        help="grid and pose source: the true map and pose, or live grid SLAM")


def _world(name: str) -> Any:
    from homing.sim import load_world

    if name in PUBLIC_PLANS:
        found = find_plans((name,), why=f"'{name}' is not a bundled world either")
        if found:
            return load_world(found[name])
    return load_world(name)


def _goals(world: Any, start: Any, n: int, seed: int) -> list[tuple[float, float]]:
    """``n`` seeded goals (x, y) [m] among reachable cells with ``GOAL_CLEARANCE``, each ≥ MIN_LEG from the last."""
    import zlib

    from homing.sim.walls import cell_to_world
    from scipy import ndimage

    reach = world.reachable_free()
    clear = ndimage.distance_transform_edt(reach) * world.map.resolution
    rows, cols = np.nonzero(clear >= GOAL_CLEARANCE)
    xy = cell_to_world(world.map, rows, cols)
    rng = np.random.default_rng([seed, zlib.crc32(world.name.encode())])
    out: list[tuple[float, float]] = []
    last = np.array([start.x, start.y])
    for _ in range(n):
        far = np.flatnonzero(np.hypot(*(xy - last).T) >= MIN_LEG)
        pool = far if len(far) else np.arange(len(xy))
        p = xy[int(rng.choice(pool))]
        out.append((float(p[0]), float(p[1])))
        last = p
    return out


def _back_off(robot: Any) -> int:
    from homing.navigation.recovery import BackUp, MotionStatus

    backup, presses = BackUp(BACK_OFF, 0.1), 0
    obs = robot.observe()
    backup.start(obs.stamp, obs.odom.pose)
    for _ in range(int(20 * RATE)):
        obs = robot.observe()
        status, cmd = backup.step(obs.stamp, obs.odom.pose, obs.scan.points() if obs.scan else None)
        if status is not MotionStatus.RUNNING:
            break
        robot.command(cmd.v, cmd.omega)
        robot.step(1.0 / RATE)
        presses += int(robot.observe().bumpers.any() and not obs.bumpers.any())
    return presses


def _optimum(world: Any, start: Any, goal: tuple[float, float]) -> float:
    from homing.navigation.costmap import Costmap
    from homing.navigation.planner import PlanningError, make_planner, path_length
    from homing.robot import Pose2

    cm = Costmap()
    cm.update_static(world.map)
    try:
        return path_length(make_planner("fmm").plan(cm, start, Pose2(goal[0], goal[1], 0.0)))
    except PlanningError:
        return math.nan


def run_world(name: str, seed: int, controller: str, grid_source: str, n_goals: int) -> list[dict[str, Any]]:
    """Drive one world's legs with one controller and grid source; one dict per leg."""
    from homing.mapping.grid_slam import GridSlam
    from homing.navigation.layers import dock_keepout
    from homing.navigation.navigator import Navigator, NavStatus
    from homing.robot import Pose2
    from homing.sim import SimRobot

    world = _world(name)
    robot = SimRobot(world, seed=seed, camera=False)
    legs: list[dict[str, Any]] = []
    try:
        docked_truth, docked_odom = robot.truth_pose(), robot.observe().odom.pose
        presses = _back_off(robot)
        start_truth = robot.truth_pose()
        slam = GridSlam() if grid_source == "slam" else None
        # The SLAM map frame is odom at the first scan; goals are moved into it (evaluation knows both).
        world_from_map = start_truth.compose(robot.observe().odom.pose.inverse())
        nav = Navigator(controller=controller)
        # The mission knows the dock: the robot started on it (in map = odom for SLAM, in the world otherwise).
        nav.set_keepout([dock_keepout(docked_odom if slam else docked_truth)])
        for goal in _goals(world, start_truth, n_goals, seed):
            leg_start = robot.truth_pose()
            optimum = _optimum(world, leg_start, goal)
            g_world = Pose2(goal[0], goal[1], 0.0)
            g_map = world_from_map.inverse().compose(g_world) if slam else g_world
            nav.set_goal(g_map, yaw_tolerance=math.inf)
            t0, length, last, pose = robot.clock.now(), 0.0, leg_start, leg_start
            status, pressed_before = NavStatus.RUNNING, False
            while robot.clock.now() - t0 < LEG_LIMIT:
                obs = robot.observe()
                if slam is not None:
                    slam.update(obs.odom, obs.scan)
                    grid, pose, m2o = slam.grid, slam.pose, slam.map_to_odom
                else:
                    truth = robot.truth_pose()
                    grid, pose, m2o = world.map, truth, truth.compose(obs.odom.pose.inverse())
                status, cmd, fb = nav.step(obs, grid, pose, m2o)
                if status is not NavStatus.RUNNING:
                    break
                robot.command(cmd.v, cmd.omega)
                robot.step(1.0 / RATE)
                pressed = bool(robot.observe().bumpers.any())
                presses += int(pressed and not pressed_before)
                pressed_before = pressed
                now = robot.truth_pose()
                length += now.distance_to(last)
                last = now
            if status is NavStatus.RUNNING:
                nav.cancel()
            end = robot.truth_pose()
            miss = math.hypot(end.x - goal[0], end.y - goal[1])
            loc_err = end.distance_to(world_from_map.compose(pose)) if slam else 0.0
            ok = status is NavStatus.SUCCEEDED and miss <= nav.xy_tolerance + TRUTH_SLACK
            # Navigation's own verdict, in the map it was given (differs from ``ok`` by the localisation error).
            nav_ok = status is NavStatus.SUCCEEDED and pose.distance_to(g_map) <= nav.xy_tolerance + TRUTH_SLACK
            legs.append({
                "world": name, "seed": seed, "controller": controller, "grid": grid_source,
                "success": ok, "nav_success": nav_ok, "status": status.value, "reason": nav.feedback.message, "presses": presses,
                "time": robot.clock.now() - t0, "length": length, "optimum": optimum,
                "ratio": length / optimum if optimum and math.isfinite(optimum) and optimum > 0.3 else math.nan,
                "miss": miss, "nav_miss": pose.distance_to(g_map), "loc_err": loc_err,
            })  # fmt: skip
            presses = 0
    finally:
        robot.close()
    return legs


def _summary(legs: list[dict[str, Any]]) -> list[Any]:
    ok = [leg for leg in legs if leg["success"]]
    ratios = [leg["ratio"] for leg in ok if math.isfinite(leg["ratio"])]
    return [
        len(legs), 100.0 * len(ok) / max(len(legs), 1),
        100.0 * sum(leg["nav_success"] for leg in legs) / max(len(legs), 1), sum(leg["presses"] for leg in legs),
        float(np.median([leg["time"] for leg in ok])) if ok else math.nan,
        float(np.median(ratios)) if ratios else math.nan,
        float(np.max(ratios)) if ratios else math.nan,
        float(np.median([leg["miss"] for leg in legs])) if legs else math.nan,
        float(np.max([leg["loc_err"] for leg in legs])) if legs else math.nan,
    ]


def run(args: argparse.Namespace) -> int:
    all_legs: list[dict[str, Any]] = []
    wall0 = time.perf_counter()
    if args.worlds is None:
        args.worlds = [*find_plans(why="navigating in lab only"), "lab"]
    for grid_source in args.grids:
        for controller in args.controllers:
            for name in args.worlds:
                for seed in range(1, args.seeds + 1):
                    legs = run_world(name, seed, controller, grid_source, args.goals)
                    all_legs += legs
                    for leg in legs:
                        if not leg["success"]:
                            print(f"  {name} seed {seed} {controller}/{grid_source}: {leg['status']} "
                                  f"({leg['reason']}), missed by {leg['miss']:.2f} m "
                                  f"(navigation {leg['nav_miss']:.2f} m, localisation {leg['loc_err']:.2f} m)")
    cols = ["world", "ctrl", "grid", "legs", "ok %", "map ok %", "bumps", "t med [s]", "len/opt med", "len/opt max",
            "miss med [m]", "loc err max [m]"]
    rows: list[list[Any]] = []
    data: dict[str, Any] = {}
    for grid_source in args.grids:
        for controller in args.controllers:
            for name in [*args.worlds, "all"]:
                legs = [leg for leg in all_legs if leg["controller"] == controller and leg["grid"] == grid_source
                        and (name == "all" or leg["world"] == name)]
                summary = _summary(legs)
                rows.append([name, controller, grid_source, *summary])
                data.setdefault(grid_source, {}).setdefault(controller, {})[name] = dict(
                    zip(["legs", "success_pct", "map_success_pct", "presses", "median_time", "median_ratio", "max_ratio",
                              "median_miss", "max_loc_err"], summary,
                        strict=True))
    print_table(f"navigation: {args.goals} goals × {args.seeds} seeds per world "
                f"({time.perf_counter() - wall0:.0f} s wall)", cols, rows)
    write_json(args.json, {"summary": data, "legs": all_legs})
    return 0
