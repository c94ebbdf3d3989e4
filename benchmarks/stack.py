"""The explore stack's speed: simulated seconds per CPU second, and where the CPU goes, on floors of every size.

Runs the exploration mission (``missions/explore.yaml``, ``--strategy``,
default frontier_travel) in the simulator on each of ``--worlds`` (default
the lab, a generated office and a generated 2000 m² floor) for
``--minutes`` of simulated time, one process, one run after another, and
measures it in **CPU time** of this process (``time.process_time``), which
other load on the machine does not change much (wall time does). Figures per
world:

- ``rtf_cpu``: simulated seconds per CPU second, the whole process
  (simulator included); ``rtf_stack_cpu``: the same without the simulator
  (observe and step): what the robot's own software costs, the part that
  would run on the robot;
- ``ms_per_sim_s``: CPU milliseconds per simulated second, by part: the
  simulator, each service (grid SLAM, the navigation service's costmap
  refresh), and in the tree the exploration decisions (frontier search,
  strategy, the travel-distance field), the navigator's step (planner,
  controller) and the rest (the tree's own walk, the other leaves);
- ``mapped_m2``: the free area the map holds at the end, to read the cost
  against the size of what is mapped; ``growth``: the stack's cost per
  simulated second over the first world's.

Issue 36's targets: the stack at ≥ 50× real time on a generated office and
≥ 20× on a 2000 m² floor, one core. Run:
``homing bench stack [--worlds lab office:1 floor:1] [--minutes 5]``.
"""

from __future__ import annotations

import argparse
import functools
import time
from collections.abc import Callable
from typing import Any

from homing.benchmarks.common import print_table, progress_bar, run_to_end, write_json

WORLDS = ("lab", "office:1", "floor:1")
PARTS = ("simulator", "grid SLAM", "costmap", "explore decisions", "navigator step", "tree, rest")


def _timed(fn: Callable[..., Any], totals: dict[str, float], part: str) -> Callable[..., Any]:
    """``fn`` adding its CPU time to ``totals[part]``."""

    @functools.wraps(fn)
    def wrapper(*args: Any, **kwargs: Any) -> Any:
        t0 = time.process_time()
        try:
            return fn(*args, **kwargs)
        finally:
            totals[part] = totals.get(part, 0.0) + time.process_time() - t0

    return wrapper


def run_one(world_spec: str, strategy: str, seed: int, minutes: float) -> dict[str, Any]:
    """One exploration session of ``minutes`` simulated minutes, timed by part (module doc)."""
    from homing.benchmarks.explore import MISSION
    from homing.missions.compiler import compile_mission
    from homing.missions.runner import Runner
    from homing.sim import SimRobot, load_world

    from homing.map_server import FREE

    world = load_world(world_spec)
    robot = SimRobot(world, seed=seed, camera=False)
    mission = compile_mission(MISSION, {"strategy": strategy, "time_limit": f"{minutes * 60.0:g} s"})
    timing: dict[str, float] = {}
    inner: dict[str, float] = {}
    explore: Any = next((n for n in mission.root.iterate() if type(n).__name__ == "Explore"), None)
    if explore is not None:
        explore._decide = _timed(explore._decide, inner, "explore decisions")

    def on_tick(runner: Runner) -> None:
        # The services exist once the runner has set up (its first tick): time the navigator's step from then.
        if not inner.get("wrapped"):
            inner["wrapped"] = 1.0
            for service in runner.services:
                navigator = getattr(service, "navigator", None)
                if navigator is not None:
                    navigator.step = _timed(navigator.step, inner, "navigator step")

    runner = Runner(mission, robot, seed=seed, until=minutes * 60.0, timing=timing,
                    timing_clock=time.process_time, on_tick=on_tick)
    cpu0 = time.process_time()
    try:
        result = run_to_end(runner)
    finally:
        robot.close()
    cpu = time.process_time() - cpu0
    grid = runner.read("/map/grid")
    sim_s = max(float(result.time), 1e-9)
    parts = {
        "simulator": timing.get("adapter: observe", 0.0) + timing.get("adapter: step (simulation)", 0.0),
        "grid SLAM": timing.get("service: grid_slam", 0.0),
        "costmap": timing.get("service: navigation", 0.0),
        "explore decisions": inner.get("explore decisions", 0.0),
        "navigator step": inner.get("navigator step", 0.0),
    }
    parts["tree, rest"] = max(timing.get("tree: leaves and runner", 0.0) - parts["explore decisions"]
                              - parts["navigator step"], 0.0)
    other = cpu - sum(parts.values())  # other services, the run loop, the timing itself
    stack_cpu = max(cpu - parts["simulator"], 1e-9)
    fields = explore.explorer.fields if explore is not None and explore.explorer is not None else 0
    return {
        "world": world_spec, "sim_s": sim_s, "cpu_s": cpu, "rtf_cpu": sim_s / max(cpu, 1e-9),
        "rtf_stack_cpu": sim_s / stack_cpu, "wall_s": float(result.wall),
        "ms_per_sim_s": {k: 1e3 * v / sim_s for k, v in {**parts, "other": other}.items()},
        "stack_ms_per_sim_s": 1e3 * stack_cpu / sim_s,
        "mapped_m2": float((grid.data == FREE).sum()) * grid.resolution**2 if grid is not None else 0.0,
        "ticks": int(result.ticks), "distance_fields": int(fields), "end": result.reason,
    }  # fmt: skip


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--worlds", nargs="+", default=list(WORLDS), metavar="WORLD",
                        help="world files or generated specs (default: lab office:1 floor:1)")
    parser.add_argument("--minutes", type=float, default=5.0, help="simulated minutes per world (default 5)")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--strategy", default="frontier_travel", help="exploration strategy (default frontier_travel)")


def run(args: argparse.Namespace) -> int:
    from homing.mapping.strategies import STRATEGIES
    from homing.sim import load_world

    from homing.errors import UserError

    if not args.minutes > 0:
        raise UserError(f"--minutes must be positive, not {args.minutes}")
    if args.strategy not in STRATEGIES:
        raise UserError(f"--strategy: unknown strategy '{args.strategy}' (known: {', '.join(sorted(STRATEGIES))})")
    for spec in args.worlds:
        load_world(spec)  # a bad world stops here, before any run
    results = []
    with progress_bar("explore stack", len(args.worlds)) as advance:
        for spec in args.worlds:
            results.append(run_one(spec, args.strategy, args.seed, args.minutes))
            advance(f"{spec}: {results[-1]['rtf_cpu']:.1f}×")
    base = results[0]["stack_ms_per_sim_s"]
    for r in results:
        r["growth"] = r["stack_ms_per_sim_s"] / base
    print_table(f"explore stack, {args.strategy}, {args.minutes:g} simulated min, CPU time",
                ["world", "mapped m²", "×real", "×real stack", "stack ms/s", "growth", "fields"],
                [[r["world"], f"{r['mapped_m2']:.0f}", f"{r['rtf_cpu']:.1f}", f"{r['rtf_stack_cpu']:.1f}",
                  f"{r['stack_ms_per_sim_s']:.1f}", f"{r['growth']:.2f}", r["distance_fields"]] for r in results])
    print_table("CPU ms per simulated second, by part",
                ["part", *[r["world"] for r in results]],
                [[part, *[f"{r['ms_per_sim_s'][part]:.1f}" for r in results]] for part in (*PARTS, "other")])
    write_json(args.json, {"strategy": args.strategy, "minutes": args.minutes, "seed": args.seed,
                           "worlds": results})
    return 0
