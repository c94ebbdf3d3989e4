"""The ``navigation`` service's keep-out zones: the dock marked from where the robot started on it, and ``/nav/keepout``."""

from __future__ import annotations

import math

import homing.sim as sim  # noqa: E402 - part of the package: a broken simulator must fail, not skip
import numpy as np
import py_trees
import pytest
from homing.behaviours.navigation_service import KEEPOUT_KEY, NavigationService
from homing.navigation.costmap import LETHAL
from homing.robot import Pose2
from py_trees.common import Access

from homing.errors import UserError


def _client(service: NavigationService, robot: object) -> py_trees.blackboard.Client:
    py_trees.blackboard.Blackboard.clear()
    client = py_trees.blackboard.Client(name="test")
    for key in (*service.writes, *service.reads):
        client.register_key(key=key, access=Access.WRITE)
    service.setup(robot, client)  # type: ignore[arg-type]
    return client


def test_the_dock_is_kept_out_when_the_robot_starts_on_it_and_leaves_take_zones(floor_plans) -> None:  # type: ignore[no-untyped-def]
    from homing.sim.dock import DOCK_DEPTH

    world = sim.load_world(floor_plans / "room.yaml")
    robot = sim.SimRobot(world, seed=1, camera=False)
    try:
        service = NavigationService()
        bb = _client(service, robot)
        obs = robot.observe()
        assert obs.battery.on_dock
        truth = robot.truth_pose()  # a perfect localiser, so map = world here
        bb.set("/map/grid", world.map)
        bb.set("/map/pose", truth)
        service.update(obs)
        cm = service.navigator.costmap
        # The dock's body (not in the map: it is below the lidar) is lethal, the robot's own cell is not.
        # (the front of the body, 0.1 m off the wall the scan marks; this map's cells are 0.1 m)
        middle = world.dock.station.compose(Pose2(DOCK_DEPTH - 0.005, 0.1, 0.0))
        assert cm.cost_at(np.array([[middle.x, middle.y]]))[0] == LETHAL
        assert cm.cost_at(np.array([[truth.x, truth.y]]))[0] != LETHAL
        # Without the option the same cell is free of obstacles: the keep-out zone alone marks it.
        plain = NavigationService(dock_keepout=False)
        _client(plain, robot).set("/map/grid", world.map)
        py_trees.blackboard.Blackboard.set("/map/pose", truth)
        plain.update(obs)
        assert plain.navigator.costmap.cost_at(np.array([[middle.x, middle.y]]))[0] < LETHAL
        bb = _client(service, robot)
        bb.set("/map/grid", world.map)
        bb.set("/map/pose", truth)
        # A leaf adds a zone at /nav/keepout: it is lethal at the next update, the dock stays.
        spot = world.staging_pose(1.5)
        bb.set(KEEPOUT_KEY, [[spot.x, spot.y, 0.2]])
        service.update(robot.observe())
        assert cm.cost_at(np.array([[spot.x, spot.y]]))[0] == LETHAL
        assert cm.cost_at(np.array([[middle.x, middle.y]]))[0] == LETHAL
        assert math.isfinite(float(cm.clearance.min()))
    finally:
        robot.close()


def test_no_dock_zone_when_the_robot_does_not_start_docked(floor_plans) -> None:  # type: ignore[no-untyped-def]
    world = sim.load_world(floor_plans / "room.yaml")
    robot = sim.SimRobot(world, seed=1, camera=False, start=world.staging_pose(1.0))
    try:
        service = NavigationService()
        bb = _client(service, robot)
        obs = robot.observe()
        assert not obs.battery.on_dock
        bb.set("/map/grid", world.map)
        bb.set("/map/pose", robot.truth_pose())
        service.update(obs)
        assert service.dock_zone is None and service.navigator.costmap.keepout == []
    finally:
        robot.close()


def test_a_malformed_keepout_is_the_users_mistake() -> None:
    with pytest.raises(UserError, match=r"keepout\[1\]"):
        NavigationService(keepout=[[0.0, 0.0, 1.0], [1.0, 2.0]])
