"""Exploration efficiency, thesis table 5.1: every world × strategy × seed explored from the dock for M simulated minutes.

Each run is the real thing: the bundled mission ``missions/explore.yaml``
(back out of the dock, spin, explore with recoveries) compiled with the
strategy, ticked by :class:`homing.missions.runner.Runner` against the
pybullet TurtleBot (:class:`homing.sim.SimRobot`, camera off: the mission
uses no images) until no frontier is left or ``--minutes`` of adapter time.
Per run, the thesis's columns:

- efficiency [m²/s]: area explored / elapsed session time, both taken at the
  moment the run first reaches 95 % coverage of the reachable free area (the
  fraction of the truth's reachable free area the grid has observed,
  :func:`homing.mapping.evaluate.coverage`, sampled every ``COVERAGE_PERIOD``); a run that never
  reaches 95 % is measured at the end of the time limit: its robot may have
  stopped ("no frontier left", or given up) but the session clock keeps
  running, as in the thesis's fixed 30-minute sessions. The same rule for
  every strategy. Why not "area / time until the robot says done": that
  rewards a strategy that quits early with less coverage (explore_lite's
  known "ends early"), and the thesis's fixed-length sessions never measured
  it that way;
- farthest distance FD [m] from the start, path length PL [m] travelled and
  area explored AE [m²] (free cells of the robot's grid),

and, from the simulator's ground truth (evaluation only,
:mod:`homing.mapping.evaluate`): coverage of the free area reachable from
the dock, the time to 95 % coverage [s], the grid's cell agreement with the
true map on its observed cells (:func:`homing.mapping.evaluate.cell_agreement`:
how good a map the run built), and bumper presses. Ratios to
``nearest`` and to ``explore_lite`` are computed run by run (same world,
same seed), then the median is reported.

Worlds default to the bundled ``lab``, the six public floor plans and the
five more of their ``extra/`` folder when found (``$HOMING_WORLDS``, or ``shared/worlds`` beside the working directory or
its parent), plus ``--generated`` N plans of each generated kind
(:mod:`homing.sim.buildings`: ``office:1..N``, ``hospital:1..N``,
``slam_office:1..N``), so the median is not decided by open halls. A second
table gives the figures per plan kind (hall, loop, corridor, office,
hospital, slam_office), with how often the robot said "done" while the map
still had a frontier it could reach (``false done``) and its own coverage
estimate when it ended. Runs go to ``--workers`` processes, or to
a Ray cluster with ``--engine ray [--address ADDR]``
(:mod:`homing.benchmarks.engine`: the same JSON for the same seeds; a run
that fails is listed with its seed under ``failed``).
"""

from __future__ import annotations

import argparse
import math
import os
import statistics
import time
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

from homing.benchmarks.common import (
    find_extra_plans,
    find_plans,
    print_table,
    progress_bar,
    write_json,
)
from homing.benchmarks.engine import (
    add_engine_arguments,
    engine_from_args,
    failures_table,
    run_jobs,
)
from homing.robot import Pose2

STRATEGY_ORDER = ("nearest", "largest_closest", "largest_random", "largest_random_raw", "explore_lite", "gain_rate",
                  "frontier_travel")
MISSION = Path(__file__).resolve().parent.parent / "missions" / "explore.yaml"
COVERAGE_PERIOD = 5.0  # [s] adapter time between coverage samples (time to 95 %, and the efficiency taken then)
COVERAGE_TARGET = 0.95
FALSE_DONE_AREA = 1.0  # [m²] a place this big left unseen in the navigable area makes "done" a false done
THESIS = {  # table 5.1: efficiency [m²/s], FD [m], PL [m], AE [m²]
    "nearest": (0.0165, 1.286, 6.356, 31.748),
    "largest_closest": (0.0154, 8.237, 13.171, 53.039),
    "largest_random": (0.0223, 5.013, 23.126, 45.621),
    "largest_random_raw": (0.0224, 4.852, 15.482, 44.829),
}


@dataclass
class RunResult:
    """One exploration run's figures (units in the field comments)."""

    world: str
    strategy: str
    seed: int
    efficiency: float  # [m²/s] area at the first ≥ 95 % coverage sample / its time, else final area / time limit
    area: float  # [m²] free cells of the final grid
    coverage: float  # fraction of the reachable free area observed (free or wall: mapping.evaluate.coverage)
    farthest: float  # [m] from the start (truth)
    path_length: float  # [m] (truth)
    explore_time: float  # [s] from the start until the robot was done, or the time limit
    t95: float  # [s] first sample with ≥ 95 % coverage (nan: never)
    area95: float  # [m²] area explored at t95 (nan: never)
    done: bool  # the mission ended with no frontier left
    bumps: int  # ticks with a bumper pressed
    nav_failures: int
    goals: int
    agreement: float  # cell agreement with the truth on observed cells
    wall: float  # [s] real time of the run
    rtf: float  # adapter seconds per real second
    free_coverage: float = math.nan  # fraction of the reachable free area mapped free (misregistration counts)
    estimate: float = math.nan  # the robot's own coverage estimate when it ended (nan: it did not end)
    frontiers_left: int = -1  # frontiers the map says the robot could still reach when it ended (-1: did not end)
    given_up: int = 0  # frontiers given up (narrower than the robot, blacklisted places)
    stopped_at_target: bool = False  # ended at its first ≥ 95 % sample (--until-target): the figures are then's
    unseen_place: float = math.nan  # [m²] the largest piece of the navigable area unseen at the end (truth)


GENERATED = ("office", "hospital", "slam_office", "floor", "atrium")  # homing.sim.buildings' kinds, run by --generated
KIND_OF_PLAN = {"room": "hall", "corner": "hall", "lab": "hall", "loop": "loop", "loop_with_corridor": "loop",
                "corridor": "corridor", "room_with_corner": "corridor",  # the public blueprints' kinds
                "explorebench_room_1": "rooms", "explorebench_room_2": "rooms", "simple_rooms": "rooms",
                "explorebench_room_3": "rings", "maze": "maze"}  # the five more (extra/)


def world_specs(names: list[str] | None, generated: int = 0) -> list[str]:
    """World specs to run: the given ones, or ``lab`` plus the public floor plans found (the six and the five
    more of ``extra/``); plus ``generated`` plans of each generated kind (seeds 1..N)."""
    public = [*find_plans(why="exploring lab only").values(), *find_extra_plans().values()]
    plans = list(names) if names else ["lab", *sorted(str(p) for p in public)]
    return plans + [f"{kind}:{seed}" for kind in GENERATED for seed in range(1, generated + 1)]


def world_label(spec: str) -> str:
    return Path(spec).stem if spec.endswith((".yaml", ".yml")) else spec


def plan_kind(label: str) -> str:
    """A world's kind for the per-kind table: hall, loop, corridor (the blueprints), office, hospital,
    slam_office (generated), else the world's own name."""
    return label.split(":")[0] if ":" in label else KIND_OF_PLAN.get(label, label)


def session_efficiency(area95: float, t95: float, final_area: float, session: float) -> float:
    """Efficiency [m²/s] of a fixed-length session: ``area95`` [m²] / ``t95`` [s] when the run reached 95 %
    coverage at ``t95``, else ``final_area`` / ``session`` [s] (the clock runs to the end of the session)."""
    if math.isfinite(t95) and t95 > 0:
        return area95 / t95
    return final_area / session


@dataclass
class _Track:
    """What one run's evaluation accumulates tick by tick from the simulator's truth."""

    last: Pose2
    path: float = 0.0  # [m] true path length
    far: float = 0.0  # [m] farthest true distance from the start
    bumps: int = 0  # ticks with a bumper pressed
    next_cov: float = COVERAGE_PERIOD  # [s] when coverage is next sampled
    t95: float = math.nan  # [s] first time coverage reached the target
    area95: float = math.nan  # [m²] area explored then


def run_one(world_spec: str, strategy: str, seed: int, minutes: float, save_map: str | None = None,
            until_target: bool = False) -> RunResult:
    """One run through the real mission and runner; reads the simulator's truth only to score it. With
    ``until_target`` the session ends at the first coverage sample at ``COVERAGE_TARGET`` (its t95 and area95
    are those of the full session; nothing after them is measured)."""
    import numpy as np
    from homing.benchmarks.common import run_to_end
    from homing.mapping.evaluate import coverage, unseen_places
    from homing.missions.compiler import compile_mission
    from homing.missions.runner import Runner
    from homing.sim import SimRobot, load_world
    from py_trees.common import Access

    world = load_world(world_spec)
    robot = SimRobot(world, seed=seed, camera=False)
    mission = compile_mission(MISSION, {"strategy": strategy, "time_limit": f"{minutes * 60.0:g} s"})
    start_truth = robot.truth_pose()
    odom0 = robot.observe().odom.pose
    world_from_map = start_truth.compose(odom0.inverse())  # map = odom at the first scan (grid_slam)
    track = _Track(last=start_truth)

    def on_tick(runner: Runner) -> None:
        p = robot.truth_pose()
        track.path += p.distance_to(track.last)
        track.last = p
        track.far = max(track.far, p.distance_to(start_truth))
        obs = runner.observation
        if obs is not None and obs.bumpers.any():
            track.bumps += 1
        t = runner.now - runner.start
        if t >= track.next_cov and math.isnan(track.t95):
            track.next_cov += COVERAGE_PERIOD
            grid = runner.read("/map/grid")
            if grid is None:
                return
            cov = coverage(grid, world.map, (start_truth.x, start_truth.y), world_from_map)
            if cov.coverage >= COVERAGE_TARGET:
                track.t95, track.area95 = t, cov.area
                if until_target:
                    runner.until = t  # the session ends here: the runner stops at its time limit

    runner = Runner(mission, robot, seed=seed, until=minutes * 60.0 + 1.0, on_tick=on_tick)
    if "/map/grid" not in runner.bb.remappings:
        runner.bb.register_key(key="/map/grid", access=Access.READ)
    try:
        result = run_to_end(runner)  # a run stopped half-way by a signal is no finished run for --runs-json
    finally:
        robot.close()
    grid = runner.read("/map/grid")
    explore: Any = next((n for n in mission.root.iterate() if type(n).__name__ == "Explore"), None)
    cov = coverage(grid, world.map, (start_truth.x, start_truth.y), world_from_map)
    if math.isnan(track.t95) and cov.coverage >= COVERAGE_TARGET:
        track.t95, track.area95 = result.time, cov.area
    done = result.reason == "success" and explore is not None and explore.status.value == "SUCCESS"
    explore_time = max(result.time if done else min(result.time, minutes * 60.0), 1e-9)
    efficiency = session_efficiency(track.area95, track.t95, cov.area, minutes * 60.0)
    if save_map:
        from homing.mapping.map_io import save_grid

        save_grid(save_map, grid)
    unseen = unseen_places(grid, world.map, (start_truth.x, start_truth.y), world_from_map, min_area=0.0)
    steps = explore.explorer.goals_chosen if explore is not None and explore.explorer is not None else 0
    estimate, left, given_up = math.nan, -1, 0
    explorer = explore.explorer if explore is not None else None
    if done and explorer is not None and explorer.report is not None:
        estimate, left = explorer.report.coverage_estimate, explorer.report.open
        given_up = len(explorer.report.narrow) + len(set(explorer.given_up()))
    return RunResult(
        world=world_label(world_spec), strategy=strategy, seed=seed,
        efficiency=efficiency, area=cov.area, coverage=cov.coverage, free_coverage=cov.free_coverage,
        farthest=track.far, path_length=track.path, explore_time=explore_time, t95=track.t95,
        area95=track.area95,
        done=done, bumps=int(track.bumps), nav_failures=len(explore.failures) if explore is not None else 0,
        goals=int(steps), agreement=float(np.float64(cov.agreement)), wall=result.wall, rtf=result.rtf,
        estimate=estimate, frontiers_left=left, given_up=given_up,
        stopped_at_target=until_target and result.reason == "time_limit" and result.time < minutes * 60.0,
        unseen_place=unseen[0] if unseen else 0.0,
    )  # fmt: skip


def _job(world: str, strategy: str, seed: int, minutes: float, folder: str | None,
         until_target: bool = False) -> RunResult:
    """One run of the sweep (the engine calls ``fn(*job)``)."""
    os.environ.setdefault("OMP_NUM_THREADS", "1")
    save = str(Path(folder) / f"{world_label(world)}_{strategy}_{seed}.yaml") if folder else None
    return run_one(world, strategy, seed, minutes, save_map=save, until_target=until_target)


# -- aggregation ---------------------------------------------------------------------------------
def _median(values: list[float]) -> float:
    vals = [v for v in values if not math.isnan(v)]
    return float(statistics.median(vals)) if vals else math.nan


def run_ratios(results: list[RunResult], baseline: str) -> dict[tuple[str, str], list[float]]:
    """efficiency(strategy) / efficiency(baseline) for every run, paired on the same world and seed."""
    base = {(r.world, r.seed): r.efficiency for r in results if r.strategy == baseline}
    per: dict[tuple[str, str], list[float]] = {}
    for r in results:
        b = base.get((r.world, r.seed))
        if b is not None and b > 0:
            per.setdefault((r.world, r.strategy), []).append(r.efficiency / b)
    return per


def ratios(results: list[RunResult], baseline: str) -> dict[tuple[str, str], float]:
    """Median over seeds of the run-by-run ratios of :func:`run_ratios`, per (world, strategy)."""
    return {k: _median(v) for k, v in run_ratios(results, baseline).items()}


def false_done(r: RunResult) -> bool:
    """The robot said done with a place of at least FALSE_DONE_AREA of the navigable area unseen (the truth's
    verdict: frontiers it gave up count); runs saved before that figure: with a reachable frontier left."""
    if math.isnan(r.unseen_place):
        return r.done and r.frontiers_left > 0
    return r.done and r.unseen_place >= FALSE_DONE_AREA


def summarise(results: list[RunResult], bounds: dict[str, float] | None = None) -> dict[str, dict[str, dict[str, Any]]]:
    """JSON figures per world and strategy (medians over seeds) plus an ``all`` world (medians over every run;
    its ratios are the median of every paired run's ratio); ``bounds``: explore-bound's time [s] per world, for
    each run's t95 over it."""
    bounds = bounds or {}
    vs_near, vs_lite = run_ratios(results, "nearest"), run_ratios(results, "explore_lite")
    out: dict[str, dict[str, dict[str, Any]]] = {}
    groups: dict[tuple[str, str], list[RunResult]] = {}
    for r in results:
        groups.setdefault((r.world, r.strategy), []).append(r)
        groups.setdefault(("all", r.strategy), []).append(r)
    for r in results:
        groups.setdefault((f"kind:{plan_kind(r.world)}", r.strategy), []).append(r)
    for (world, strategy), runs in groups.items():
        def med(field: str, runs: list[RunResult] = runs) -> float:
            return _median([float(getattr(r, field)) for r in runs])

        if world == "all":  # every paired run of every world
            r_near = _median([v for (w, s), vs in vs_near.items() if s == strategy for v in vs])
            r_lite = _median([v for (w, s), vs in vs_lite.items() if s == strategy for v in vs])
        elif world.startswith("kind:"):  # every paired run of the worlds of that kind
            kind = world[5:]
            r_near = _median([v for (w, s), vs in vs_near.items() if s == strategy and plan_kind(w) == kind for v in vs])
            r_lite = _median([v for (w, s), vs in vs_lite.items() if s == strategy and plan_kind(w) == kind for v in vs])
        else:
            r_near, r_lite = _median(vs_near.get((world, strategy), [])), _median(vs_lite.get((world, strategy), []))
        out.setdefault(world, {})[strategy] = {
            "false_done": sum(false_done(r) for r in runs),
            "t95_over_bound": _median([r.t95 / bounds[r.world] for r in runs if r.world in bounds]),
            "done": sum(r.done for r in runs), "given_up": sum(r.given_up for r in runs),
            "estimate": med("estimate"),
            "efficiency": med("efficiency"), "area": med("area"), "coverage": med("coverage"),
            "min_coverage": min(r.coverage for r in runs), "free_coverage": med("free_coverage"),
            "path_length": med("path_length"), "agreement": med("agreement"),
            "farthest": med("farthest"), "t95": med("t95"), "bumps": sum(r.bumps for r in runs),
            "ratio_vs_nearest": r_near, "ratio_vs_explore_lite": r_lite, "runs": len(runs),
        }  # fmt: skip
    return out


# -- CLI ------------------------------------------------------------------------------------------------
def add_arguments(parser: argparse.ArgumentParser) -> None:
    from homing.missions.commands._args import count, output_file, output_folder, positive

    parser.add_argument("--worlds", nargs="+", metavar="WORLD",
                        help="bundled names or YAML paths (default: lab and the public floor plans found)")
    parser.add_argument("--strategies", nargs="+", default=list(STRATEGY_ORDER), metavar="NAME",
                        help=f"frontier strategies (default: all: {', '.join(STRATEGY_ORDER)})")
    parser.add_argument("--generated", type=count, default=3,
                        help=f"also run N generated plans of each kind ({', '.join(GENERATED)}; seeds 1..N)")
    parser.add_argument("--seeds", type=count, default=5, help="seeds per world and strategy (0..N-1)")
    parser.add_argument("--minutes", type=positive, default=30.0, help="simulated minutes per run (thesis: 30)")
    add_engine_arguments(parser)
    parser.add_argument("--runs-json", metavar="PATH", type=output_file("--runs-json"),
                        help="also write every run's figures to PATH (rewritten as each run finishes)")
    parser.add_argument("--resume", action="store_true",
                        help="with --runs-json: keep the runs that file already holds and run only the others (a "
                             "sweep split over several sittings; the file must come from the same code); runs "
                             "it holds that this sweep does not ask for stay in it")
    parser.add_argument("--from-runs", nargs="+", metavar="PATH",
                        help="run nothing: tabulate the runs saved by earlier --runs-json (e.g. baselines and "
                             "the default run separately), filtered by --worlds/--strategies when given")
    parser.add_argument("--until-target", action="store_true",
                        help="end each run at its first sample at 95 %% coverage: its t95, efficiency and ratios "
                             "are the full session's, in a fraction of the time (coverage, done and the rest are "
                             "then's); to compare a change with saved runs (--from-runs)")
    parser.add_argument("--save-maps", metavar="DIR", type=output_folder("--save-maps"),
                        help="save each run's final grid as DIR/WORLD_STRATEGY_SEED.yaml (+ .pgm; see homing map show)")


def run(args: argparse.Namespace) -> int:
    from homing.mapping.strategies import STRATEGIES

    from homing.errors import UserError

    bad = [s for s in args.strategies if s not in STRATEGIES]
    if bad:
        raise UserError(f"unknown strategy {', '.join(bad)} (known: {', '.join(sorted(STRATEGIES))})")
    engine = engine_from_args(args)
    worlds = world_specs(args.worlds, args.generated if not args.worlds else 0)
    for w in worlds:
        from homing.sim.world import check_spec

        check_spec(w)  # a missing world is the user's mistake: say so before starting workers
    if args.save_maps:
        Path(args.save_maps).mkdir(parents=True, exist_ok=True)
    jobs = [(w, s, seed, args.minutes, args.save_maps, args.until_target) for w in worlds for s in args.strategies
            for seed in range(args.seeds)]
    results: list[RunResult] = []
    t0 = time.monotonic()
    if args.from_runs:
        results = load_runs(args.from_runs, args.strategies, [world_label(w) for w in worlds] if args.worlds else None)
        args.seeds = len({r.seed for r in results})
        jobs = []
    kept: list[RunResult] = []
    others: list[RunResult] = []  # runs the file holds that this sweep does not ask for: written back untouched
    if args.resume:
        if not args.runs_json:
            raise UserError("--resume needs --runs-json PATH (the runs to keep and add to)")
        if Path(args.runs_json).is_file():
            saved = load_runs([args.runs_json], list(STRATEGIES), None)
            wanted = {(world_label(w), s, seed) for w, s, seed, *_ in jobs}
            kept = [r for r in saved if (r.world, r.strategy, r.seed) in wanted]
            others = [r for r in saved if (r.world, r.strategy, r.seed) not in wanted]
            have = {(r.world, r.strategy, r.seed) for r in kept}
            jobs = [j for j in jobs if (world_label(j[0]), j[1], j[2]) not in have]
            results = list(kept)
            print(f"--resume: {len(kept)} run(s) kept from {args.runs_json}, {len(jobs)} to run")
    finished = list(results)

    def done(o: Any) -> None:
        advance(_describe(o.result) if o.ok else f"{_job_label(o.job)}: failed")
        if o.ok and args.runs_json:  # every finished run is kept, so a sweep stopped early keeps what it ran
            finished.append(o.result)
            write_json(args.runs_json, {"runs": [asdict(r) for r in [*others, *finished]]})

    with progress_bar("explore", len(jobs)) as advance:
        outcomes = run_jobs(_job, jobs, engine, done)
    results += [o.result for o in outcomes if o.ok]
    failed = failures_table(outcomes)
    results.sort(key=lambda r: (r.world, STRATEGY_ORDER.index(r.strategy) if r.strategy in STRATEGY_ORDER else 99, r.seed))
    bounds = _bounds(worlds, results)
    summary = summarise(results, bounds)
    rows = []
    for world in [*(world_label(w) for w in worlds), "all"]:
        for strategy in args.strategies:
            s = summary.get(world, {}).get(strategy)
            if s is None:
                continue
            rows.append([world, strategy, s["efficiency"], s["farthest"], s["path_length"], s["area"],
                         s["coverage"], s["min_coverage"], s["t95"], s["t95_over_bound"], s["agreement"], s["bumps"],
                         s["ratio_vs_nearest"], s["ratio_vs_explore_lite"]])
    cut = sum(r.stopped_at_target for r in results)
    print_table(
        f"Exploration, {args.minutes:g} simulated min sessions; eff = area / time at first 95 % coverage "
        f"(else final area / session length); medians over {args.seeds} seed(s) "
        f"({len(results)} runs, {time.monotonic() - t0:.0f} s wall, median rtf "
        f"{_median([r.rtf for r in results]):.1f}×)"
        + (f"; {cut} run(s) ended at 95 % (--until-target): their figures but eff and t95 are then's" if cut else ""),
        ["world", "strategy", "eff m²/s", "FD m", "PL m", "AE m²", "coverage", "min cov", "t95 s", "/bound", "agree",
         "bumps", "×nearest", "×explore_lite"],
        rows,
    )  # fmt: skip
    kinds = sorted({plan_kind(r.world) for r in results})
    print_table(
        "Per plan kind (medians over every run of the kind; coverage of the navigable area; ratios paired run by "
        f"run; /bound: t95 over explore-bound's time; false done: the robot said done with {FALSE_DONE_AREA:g} m² "
        "or more of the navigable area unseen in one place)"
        + (f"; {cut} run(s) ended at 95 %: not done, by --until-target" if cut else ""),
        ["kind", "strategy", "runs", "coverage", "min cov", "t95 s", "/bound", "×nearest", "×explore_lite", "done",
         "false done", "estimate"],
        [[kind, strategy, s["runs"], s["coverage"], s["min_coverage"], s["t95"], s["t95_over_bound"],
          s["ratio_vs_nearest"], s["ratio_vs_explore_lite"], s["done"], s["false_done"], s["estimate"]]
         for kind in [*kinds, "all"] for strategy in args.strategies
         if (s := summary.get("all" if kind == "all" else f"kind:{kind}", {}).get(strategy)) is not None],
    )  # fmt: skip
    for f in failed:
        print(f"failed: {_job_label(tuple(f['job']))}: {f['error']}")
    write_json(args.json, {**summary, "failed": failed} if failed else summary)
    if args.runs_json:
        write_json(args.runs_json, {"runs": [asdict(r) for r in [*others, *results]]})
    return 0


def _bounds(worlds: list[str], results: list[RunResult]) -> dict[str, float]:
    """explore-bound's time [s] for every world that has runs (the route a robot knowing the plan drives)."""
    from homing.benchmarks.explore_bound import covering_route

    labels = {world_label(w): w for w in worlds}
    specs = {label: labels.get(label, label) for label in {r.world for r in results}
             if label in labels or label == "lab" or ":" in label}  # a saved run's plan named by its label alone
    return {label: covering_route(spec).time for label, spec in sorted(specs.items())}


def load_runs(paths: list[str], strategies: list[str], worlds: list[str] | None) -> list[RunResult]:
    """RunResults saved by ``--runs-json`` in ``paths``, kept when their strategy (and world) is asked for."""
    import json

    from homing.errors import UserError

    out = []
    for path in paths:
        try:
            runs = json.loads(Path(path).read_text())["runs"]
        except (OSError, ValueError, KeyError) as e:
            raise UserError(f"{path}:1:1: not a --runs-json file ({e})") from e
        out += [RunResult(**r) for r in runs
                if r["strategy"] in strategies and (worlds is None or r["world"] in worlds)]
    return out


def _job_label(job: tuple[Any, ...]) -> str:
    return f"{world_label(job[0])} {job[1]} seed {job[2]}"


def _describe(r: RunResult) -> str:
    unseen = f", {r.unseen_place:.1f} m² unseen" if r.unseen_place >= FALSE_DONE_AREA else ""
    return (f"{r.world} {r.strategy} seed {r.seed}: {r.coverage:.0%} in {r.explore_time:.0f} s, t95 {r.t95:.0f} s"
            f"{unseen}{' (said done)' if r.done else ''} ({r.rtf:.0f}×)")
