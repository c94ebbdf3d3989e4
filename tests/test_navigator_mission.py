"""The motion leaves in a YAML mission, through the compiler, py_trees and the runner, against the simulator.

The grid and the pose come from a test-only localiser (``nav_test_truth``,
registered here and removed after each test) that publishes the world's true
map and the simulator's true pose: it stands in for ``grid_slam`` so these
tests measure navigation, not SLAM. Checked: the robot backs off the dock,
reaches a goal across the lab (through the passage by the kayaks) with either
controller, turns, clears the costmap, and no bumper ever fires; a goal in a
table fails with the typed reason, and that reason reaches the recovery
branch of a ``recovery`` node, which picks its action by cause.
"""

from __future__ import annotations

import math
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import homing.sim as sim  # noqa: E402 - part of the package: a broken simulator must fail, not skip
import py_trees
import pytest
from homing.behaviours.registry import SERVICES, register_service
from homing.missions.compiler import compile_mission
from homing.missions.runner import Runner, RunResult, StatusChange
from homing.robot import Observation

GRID, POSE, MAP_TO_ODOM = "/map/grid", "/map/pose", "/map/map_to_odom"
GOAL = (8.0, 2.0, 0.0)  # [m, m, rad] in the lab's east room, behind the partition


class _TruthLocaliser:
    """Test-only: publishes the world's map and the simulator's true pose (a perfect localiser)."""

    name = "nav_test_truth"
    writes = (GRID, POSE, MAP_TO_ODOM)

    def setup(self, robot: Any, blackboard: Any) -> None:
        self.robot, self.bb = robot, blackboard

    def update(self, obs: Observation) -> None:
        truth = self.robot.truth_pose()
        self.bb.set(GRID, self.robot.world.map, overwrite=True)
        self.bb.set(POSE, truth, overwrite=True)
        self.bb.set(MAP_TO_ODOM, truth.compose(obs.odom.pose.inverse()), overwrite=True)

    def shutdown(self) -> None:
        pass


@pytest.fixture
def truth_service() -> Iterator[None]:
    register_service(_TruthLocaliser.name, writes=_TruthLocaliser.writes)(_TruthLocaliser)
    try:
        yield
    finally:
        SERVICES.pop(_TruthLocaliser.name, None)


def _run(tmp_path: Path, mission: str, seed: int = 1,
         until: float = 200.0) -> tuple[RunResult, list[str], list[float], Any]:
    path = tmp_path / "mission.yaml"
    path.write_text(mission)
    robot = sim.SimRobot(sim.load_world("lab"), seed=seed, camera=False)
    log: list[StatusChange] = []
    bumps: list[float] = []

    def on_tick(runner: Runner) -> None:
        if runner.observation is not None and runner.observation.bumpers.any():
            bumps.append(runner.now)

    try:
        result = Runner(compile_mission(path), robot, seed=seed, on_change=log.append, on_tick=on_tick,
                        until=until).run()
        end = robot.truth_pose()  # evaluation only
    finally:
        robot.close()
    return result, [c.line() for c in log], bumps, end


@pytest.mark.parametrize("controller", ["rpp", "dwb"])
def test_mission_backs_out_navigates_spins_and_clears_without_bumping(tmp_path: Path, truth_service: None,
                                                                      controller: str) -> None:
    x, y, theta = GOAL
    mission = f"""
services: [nav_test_truth, {{navigation: {{controller: {controller}}}}}]
tree:
  sequence:
    - BackUp: {{distance: 0.3, speed: 0.1}}
    - NavigateToPose: {{x: {x}, y: {y}, theta: {theta}, timeout: 150}}
    - Spin: {{angle: 1.5708}}
    - ClearCostmap
"""
    result, log, bumps, end = _run(tmp_path, mission)
    assert result.reason == "success", "\n".join(log)
    assert bumps == []
    order = [line.split("] ")[1] for line in log if "-> SUCCESS" in line]
    assert order == ["BackUp: RUNNING -> SUCCESS", "NavigateToPose: RUNNING -> SUCCESS", "Spin: RUNNING -> SUCCESS",
                     "ClearCostmap: INVALID -> SUCCESS", "sequence: RUNNING -> SUCCESS"]
    # Reached within the tolerance (the localiser is exact), then a quarter turn on odometry.
    assert math.hypot(end.x - x, end.y - y) <= 0.15 + 0.02
    turned = math.remainder(end.theta - theta, 2 * math.pi)
    assert turned == pytest.approx(math.pi / 2, abs=0.25 + 0.15)
    # About 12 m of travel at up to 0.5 m/s: well under the timeout, however the controller goes.
    assert result.time < 80.0


def test_typed_failure_reaches_the_recovery_branch(tmp_path: Path, truth_service: None) -> None:
    # (8.3, 3.1) is inside the east room's table: the planner says GoalOccupied.
    mission = """
services: [nav_test_truth, navigation]
tree:
  sequence:
    - SetBlackboard: {key: /test/cause, value: none}
    - BackUp: {distance: 0.3, speed: 0.1}
    - recovery:
        retries: 1
        child:
          NavigateToPose: {x: 8.3, y: 3.1}
        recovery:
          fallback:
            - sequence:
                - CheckBlackboard: {key: /nav/failure, value: no_path}
                - SetBlackboard: {key: /test/cause, value: no_path}
            - sequence:
                - CheckBlackboard: {key: /nav/failure, value: goal_occupied}
                - ClearCostmap
                - SetBlackboard: {key: /test/cause, value: goal_occupied}
"""
    result, log, bumps, _ = _run(tmp_path, mission, until=30.0)
    assert result.reason == "failure", "\n".join(log)  # the retry fails the same way: the node gives up
    assert py_trees.blackboard.Blackboard.storage.get("/test/cause") == "goal_occupied"
    assert py_trees.blackboard.Blackboard.storage.get("/nav/failure") == "goal_occupied"
    navigations = [line for line in log if line.endswith("NavigateToPose: RUNNING -> FAILURE")]
    assert len(navigations) == 2  # one attempt and one retry (Nav2's number_of_retries = 1)
    assert any(line.endswith("ClearCostmap: INVALID -> SUCCESS") for line in log)
    assert bumps == []
