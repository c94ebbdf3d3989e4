"""Tick cost of a compiled 200-node mission against the same tree built by hand with py_trees.

The mission is a reactive sequence of 20 branches (sequences, fallbacks,
inverters, force-success, always-succeed/fail leaves) whose last leaf keeps
running, so every tick walks all 200 nodes. The baseline builds the same
shape from py_trees' own classes (``Sequence(memory=False)``,
``Selector(memory=False)``, ``Inverter``, ``FailureIsSuccess``,
``behaviours.Success/Failure/Running``) and ticks it through the same
``BehaviourTree.tick``. Figures: ``tick_ratio`` (compiled / hand, medians
over rounds; target ≤ 1.1) and ``load_ms`` (YAML load + validate + build of
the warm process, median; target ≤ 100 ms), ``load_cold_ms`` (first load,
including importing every behaviour module).
"""

from __future__ import annotations

import argparse
import statistics
import tempfile
import time
from pathlib import Path

import py_trees
from homing.benchmarks.common import print_table, write_json

BRANCHES = 19  # [-] branches of 10 nodes before the last (running) branch of 9


def mission_yaml() -> str:
    """The 200-node mission text."""
    branch = (
        "      - reactive_sequence:\n"
        "          - Succeed\n"
        "          - inverter: {child: Fail}\n"
        "          - reactive_fallback: [Fail, Succeed]\n"
        "          - Succeed\n"
        "          - force_success: {child: Fail}\n"
    )
    last = "      - reactive_sequence: [Succeed, Succeed, Succeed, Succeed, Succeed, Succeed, Succeed, Running]\n"
    return "mission: tick200\nservices: []\ntree:\n  reactive_sequence:\n    children:\n" + branch * BRANCHES + last


def hand_built() -> py_trees.behaviour.Behaviour:
    """The same tree from py_trees' classes."""
    b = py_trees.behaviours
    branches: list[py_trees.behaviour.Behaviour] = []
    for i in range(BRANCHES):
        branches.append(
            py_trees.composites.Sequence(f"seq{i}", memory=False, children=[
                b.Success("s1"),
                py_trees.decorators.Inverter("inv", b.Failure("f1")),
                py_trees.composites.Selector("fb", memory=False, children=[b.Failure("f2"), b.Success("s2")]),
                b.Success("s3"),
                py_trees.decorators.FailureIsSuccess("fs", b.Failure("f3")),
            ])  # fmt: skip
        )
    branches.append(
        py_trees.composites.Sequence("last", memory=False, children=[*(b.Success(f"s{k}") for k in range(7)), b.Running("run")])
    )
    return py_trees.composites.Sequence("root", memory=False, children=branches)


def _time_ticks(tree: py_trees.trees.BehaviourTree, ticks: int) -> float:
    start = time.perf_counter()
    for _ in range(ticks):
        tree.tick()
    return (time.perf_counter() - start) / ticks


def add_arguments(parser: argparse.ArgumentParser) -> None:
    from homing.missions.commands._args import count

    parser.add_argument("--ticks", type=count, default=300, help="ticks per round")
    parser.add_argument("--rounds", type=count, default=7, help="alternating rounds (medians are reported)")


def run(args: argparse.Namespace) -> int:
    from homing.missions.compiler import compile_mission

    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "tick200.yaml"
        path.write_text(mission_yaml())
        t0 = time.perf_counter()
        mission = compile_mission(path)
        load_cold = (time.perf_counter() - t0) * 1e3
        loads = []
        for _ in range(args.rounds):
            t0 = time.perf_counter()
            compile_mission(path)
            loads.append((time.perf_counter() - t0) * 1e3)
    hand = hand_built()
    n_compiled = sum(1 for _ in mission.root.iterate())
    n_hand = sum(1 for _ in hand.iterate())
    assert n_compiled == n_hand == 200, (n_compiled, n_hand)
    trees = {"compiled": py_trees.trees.BehaviourTree(mission.root), "hand": py_trees.trees.BehaviourTree(hand)}
    times: dict[str, list[float]] = {k: [] for k in trees}
    for tree in trees.values():
        _time_ticks(tree, 20)  # warm up
    for _ in range(args.rounds):
        for name, tree in trees.items():
            times[name].append(_time_ticks(tree, args.ticks))
    compiled, hand_t = statistics.median(times["compiled"]), statistics.median(times["hand"])
    figures = {
        "nodes": n_compiled,
        "tick_compiled_ms": compiled * 1e3,
        "tick_hand_ms": hand_t * 1e3,
        "tick_ratio": compiled / hand_t,
        "load_ms": statistics.median(loads),
        "load_cold_ms": load_cold,
    }
    print_table(
        "tick: 200-node mission, compiled from YAML vs built by hand (py_trees)",
        ["measure", "value", "target"],
        [
            ["tick, compiled (ms)", figures["tick_compiled_ms"], ""],
            ["tick, by hand (ms)", figures["tick_hand_ms"], ""],
            ["tick_ratio", figures["tick_ratio"], "≤ 1.1"],
            ["load_ms (load + validate + build)", figures["load_ms"], "≤ 100"],
            ["load_cold_ms (first, with imports)", figures["load_cold_ms"], ""],
        ],
    )
    write_json(args.json, figures)
    return 0
