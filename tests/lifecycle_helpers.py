"""Running the persistent mission in the simulator for tests: its states over time, the batteries, the truth."""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from homing.missions.compiler import compile_mission
from homing.missions.loader import resolve_mission
from homing.missions.runner import Runner
from homing.sim import SimRobot, load_world


@dataclass
class LifeLog:
    """What a lifecycle run went through: state changes (time, state), cycles, battery lows, the robot at the end."""

    states: list[tuple[float, str]] = field(default_factory=list)
    cycles: int = 0
    lowest: dict[str, float] = field(default_factory=lambda: {"base": math.inf, "computer": math.inf})
    policy_at: dict[str, tuple[float, dict[str, Any]]] = field(default_factory=dict)  # state → (t, policy) on entry
    charging: bool = False
    end: float = 0.0
    docked_at: list[float] = field(default_factory=list)  # [s] when each dock cycle ended on the charger

    def entered(self, state: str) -> list[float]:
        return [t for t, s in self.states if s == state]

    def sequence(self) -> list[str]:
        return [s for _, s in self.states]


def live(world: Any, until: float, seed: int = 1, overrides: dict[str, Any] | None = None,
         stop_after_cycles: int | None = None, faults: tuple = (), mission: str | Path = "persistent",
         robot_kwargs: dict[str, Any] | None = None,
         on_state: Callable[[str, int, float, SimRobot], None] | None = None,
         on_tick: Callable[[Runner, SimRobot], None] | None = None) -> tuple[LifeLog, SimRobot, Runner]:
    """Tick ``mission`` on ``world`` for ``until`` [s] of simulated time (or ``stop_after_cycles`` dock cycles).

    ``on_state(state, cycles, time, robot)`` is called whenever the mission enters a state: a test injects a
    fault at the moment it means to test (the simulator's faults are data; adding one is the test's business).
    ``on_tick(runner, robot)`` after every tick, for a test that looks at the robot's map or its leaves mid-run.
    """
    world = load_world(world) if isinstance(world, (str, Path)) else world
    robot = SimRobot(world, seed=seed, faults=list(faults), **(robot_kwargs or {}))
    compiled = compile_mission(resolve_mission(mission), overrides or {})
    runner = Runner(compiled, robot, seed=seed, until=until)
    log = LifeLog()
    for key in ("/mission/state", "/mission/cycles", "/energy/policy"):
        if key not in runner.bb.remappings:
            runner.bb.register_key(key=key, access=__import__("py_trees").common.Access.READ)

    def watch(r: Runner) -> None:
        state = r.read("/mission/state")
        if state is not None and (not log.states or log.states[-1][1] != state):
            log.states.append((r.now, state))
            log.policy_at.setdefault(state, (r.now, r.read("/energy/policy") or {}))
            if on_state is not None:
                on_state(state, int(r.read("/mission/cycles") or 0), r.now, robot)
        obs = r.observation
        if obs is not None:
            log.lowest["base"] = min(log.lowest["base"], obs.battery.percent)
            if obs.computer_battery is not None:
                log.lowest["computer"] = min(log.lowest["computer"], obs.computer_battery.percent)
        cycles = r.read("/mission/cycles") or 0
        if cycles != log.cycles:
            log.docked_at.append(r.now)
        log.cycles = cycles
        if stop_after_cycles is not None and log.cycles >= stop_after_cycles:
            r.request_stop()  # the runner stops the robot and halts the tree, as on Ctrl-C
        if on_tick is not None:
            on_tick(r, robot)

    runner.on_tick = watch
    runner.run()
    log.charging = robot.charging
    log.end = robot.clock.now()
    return log, robot, runner
