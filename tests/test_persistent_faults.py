"""Every simulated fault and every change of the world ends with the robot charging on its dock again."""

from __future__ import annotations

import math

import numpy as np
import pytest
from homing.mapping.evaluate import cell_agreement
from homing.robot import Pose2
from homing.sim import Fault, SimRobot, load_world
from homing.sim.events import Change, chair

from tests.lifecycle_helpers import live

pytestmark = pytest.mark.slow


def test_each_fault_is_survived_and_the_robot_docks_after_it() -> None:
    # Each fault is injected at the phase it hurts most, one per cycle; every cycle must end on the charger.
    # "out": exploring or patrolling, whichever the robot is doing on that trip (how many trips exploring the lab
    # takes depends on the strategy's rules, not on what this test checks).
    plan = {  # (state entered, cycles completed) → the fault, starting at that moment
        ("Exploring", 0): ("lidar_dropout", {"duration": 10.0}),
        ("MapHome", 0): ("wheel_slip", {"duration": 30.0, "amount": 0.5}),
        ("MapHome", 1): ("camera_off", {"duration": 40.0}),
        ("out", 2): ("bumper_hit", {"side": "left"}),
        ("MapHome", 2): ("dock_obstacle", {"duration": 60.0, "distance": 0.6}),
        ("out", 3): ("kidnap", {}),
    }
    injected: dict[str, float] = {}

    def inject(state: str, cycles: int, t: float, robot: SimRobot) -> None:
        fault = plan.get((state, cycles))
        if fault is None and state in ("Exploring", "Patrolling"):
            fault = plan.get(("out", cycles))
        if fault is not None and fault[0] not in injected:
            name, kw = fault
            robot.faults = (*robot.faults, Fault(name, at=t, **kw))
            injected[name] = t

    log, robot, _ = live("lab", until=2400.0, seed=3, overrides={"session": "70 s", "rest": "30 s"},
                         stop_after_cycles=5,
                         on_state=inject)
    try:
        assert set(injected) == {name for name, _ in plan.values()}, injected
        assert log.cycles == 5 and robot.charging
        for name, t in injected.items():
            assert any(d > t for d in log.docked_at), f"no dock after {name} at {t:.0f} s"
        assert log.lowest["computer"] > 20.0 and log.lowest["base"] > 30.0
    finally:
        robot.close()


def test_the_map_follows_a_changing_world_and_docking_still_succeeds() -> None:
    world = load_world("lab")
    # A parcel left in the west room's middle, and a chair moved across it, while the robot patrols.
    parcel = Change("box", 240.0, math.inf, 2.0, 4.5, 0.3, (0.4, 0.4))
    moved = chair(240.0, Pose2(3.5, 6.5, 0.0), Pose2(1.6, 7.3, 0.5))
    log, robot, runner = live(world, until=1200.0, seed=2, overrides={"session": "180 s", "rest": "30 s"},
                              stop_after_cycles=2,
                              robot_kwargs={"changes": [parcel, *moved]})
    try:
        assert log.cycles == 2 and robot.charging and log.docked_at[-1] > 240.0
        grid = runner.services[0].slam.grid
        world_from_map = world.dock_pose  # map = odom at the start = the docked pose
        data = grid.data

        def cells(xy: tuple[float, float], r: float = 0.12) -> np.ndarray:
            m = world_from_map.inverse().transform_points(np.array([xy]))[0]
            rows, cols = grid.world_to_cell(m[0], m[1])
            n = int(round(r / grid.resolution))
            return data[int(rows) - n:int(rows) + n + 1, int(cols) - n:int(cols) + n + 1]

        # A lidar sees an object's sides, not its inside (which stays free as it was mapped before): look for the
        # outline within the box's half-diagonal (0.28 m) and a cell around it.
        assert (cells((2.0, 4.5), 0.35) == 100).sum() >= 8  # the parcel is in the map (at least a side of it)
        assert (cells((1.6, 7.3), 0.35) == 100).sum() >= 4  # the chair where it stands now
        assert not (cells((3.5, 6.5), 0.1) == 100).any()  # and no longer where it stood
        assert cell_agreement(grid, robot.truth_map(), world_from_map) > 0.95  # with the world as it stands now
    finally:
        robot.close()
