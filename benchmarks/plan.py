"""Global planner timings on 25 m × 25 m floor plans at 0.05 m (500 × 500 cells), per plugin.

Each map_server map given (default: the six public floor plans, found in
``$HOMING_WORLDS`` or ``../shared/worlds``, else the bundled lab's; 0.1 m
maps upsampled ×2 to 0.05 m) becomes a costmap; for
``--pairs`` seeded start/goal pairs, chosen far apart among the free cells
the robot fits in, every planner plans and is timed (wall clock, costmap
built once beforehand, as a navigator replanning on an unchanged map does).
Also timed: :func:`homing.navigation.planner.distance_map` (frontier ranking).
Path lengths are reported relative to the shortest of the three, per pair.
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np
from homing.benchmarks.common import find_plans, print_table, write_json

RES = 0.05  # [m] the costmap resolution the target is stated for


def add_arguments(parser: argparse.ArgumentParser) -> None:
    from homing.missions.commands._args import count, seed

    parser.add_argument("--maps", nargs="*", default=None,
                        help="map_server YAML files (default: the public floor plans found, else the lab's)")
    parser.add_argument("--pairs", type=count, default=10, help="start/goal pairs per map")
    parser.add_argument("--seed", type=seed, default=1)
    parser.add_argument("--planners", nargs="*", default=["dijkstra", "fmm", "astar"])


def _costmap(path: Path):  # type: ignore[no-untyped-def]
    from homing.navigation.costmap import Costmap

    from homing.map_server import load_map

    m = load_map(path)
    factor = max(1, int(round(m.resolution / RES)))
    grid = np.kron(m.grid, np.ones((factor, factor), dtype=np.int8)) if factor > 1 else m.grid
    cm = Costmap()
    cm.set_static(grid, m.resolution / factor, (m.origin[0], m.origin[1]))
    return cm


def _pairs(cm, n: int, rng: np.random.Generator) -> list[tuple[np.ndarray, np.ndarray]]:  # type: ignore[no-untyped-def]
    from homing.navigation.planner import distance_map

    free = np.argwhere(cm.cost == 0)
    out: list[tuple[np.ndarray, np.ndarray]] = []
    while len(out) < n:
        s = cm.cell_to_world(free[rng.integers(len(free))][None])[0]
        d = distance_map(cm, (float(s[0]), float(s[1])))
        reach = np.argwhere(np.isfinite(d) & (cm.cost == 0))
        if len(reach) < 100:
            continue
        # A goal in the farthest tenth of what is reachable: long plans are the ones that matter.
        far = reach[d[reach[:, 0], reach[:, 1]] >= np.quantile(d[np.isfinite(d)], 0.9)]
        g = cm.cell_to_world(far[rng.integers(len(far))][None])[0]
        out.append((s, g))
    return out


def run(args: argparse.Namespace) -> int:
    from homing.navigation.planner import distance_map, make_planner, path_length
    from homing.robot import Pose2


    maps = [Path(p) for p in args.maps] if args.maps else list(find_plans(why="timing on the lab's map").values())
    if not maps:
        from homing.sim.world import WORLDS_DIR

        maps = [WORLDS_DIR / "lab_map.yaml"]
    rng = np.random.default_rng(args.seed)
    times: dict[str, list[float]] = {name: [] for name in [*args.planners, "distance_map"]}
    ratios: dict[str, list[float]] = {name: [] for name in args.planners}
    shape = (0, 0)
    for path in maps:
        cm = _costmap(path)
        shape = cm.shape
        planners = {name: make_planner(name) for name in args.planners}
        for s, g in _pairs(cm, args.pairs, rng):
            lengths = {}
            for name, planner in planners.items():
                t0 = time.perf_counter()
                p = planner.plan(cm, Pose2(*s), Pose2(*g))
                times[name].append(time.perf_counter() - t0)
                lengths[name] = path_length(p)
            best = min(lengths.values())
            for name, length in lengths.items():
                ratios[name].append(length / best)
            t0 = time.perf_counter()
            distance_map(cm, (float(s[0]), float(s[1])))
            times["distance_map"].append(time.perf_counter() - t0)
    rows = []
    figures: dict[str, dict[str, float]] = {}
    for name, ts in times.items():
        ms = 1000.0 * np.array(ts)
        r = np.array(ratios.get(name, [np.nan]))
        figures[name] = {"median_ms": float(np.median(ms)), "p90_ms": float(np.quantile(ms, 0.9)),
                         "max_ms": float(ms.max()), "length_vs_best_median": float(np.median(r)),
                         "length_vs_best_max": float(r.max())}
        rows.append([name, figures[name]["median_ms"], figures[name]["p90_ms"], figures[name]["max_ms"],
                     figures[name]["length_vs_best_median"], figures[name]["length_vs_best_max"]])
    print_table(f"plan: {len(maps)} maps × {args.pairs} pairs, {shape[0]} × {shape[1]} cells at {RES} m",
                ["planner", "median ms", "p90 ms", "max ms", "length/best med", "length/best max"], rows)
    write_json(args.json, {"cells": list(shape), "resolution": RES, "planners": figures})
    return 0
