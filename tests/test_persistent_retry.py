"""The persistent mission maps, on a later round, a room it had to give up in its first session (issue 36, 3)."""

from __future__ import annotations

import dataclasses
import math
from typing import Any

import numpy as np
import pytest
from homing.behaviours.explore import Explore
from homing.mapping.navigable import navigable
from homing.missions.runner import Runner
from homing.robot.turtlebot import BASE_RADIUS
from homing.sim import SimRobot, load_world
from homing.sim.events import Change, rasterise
from homing.sim.walls import solid_mask

from homing.map_server import FREE
from tests.lifecycle_helpers import live

pytestmark = pytest.mark.slow

EAST_ROOM = (6.2, 0.0, 10.0, 10.0)  # [m] x0, y0, x1, y1 in the lab's world frame: east of the partition


def test_a_room_given_up_behind_a_doorway_too_narrow_in_the_first_session_is_mapped_once_the_door_opens() -> None:
    world = load_world("lab")
    # The lab's east room has two ways in: the doorway at the partition's north end (y 7.0-8.2 m) and the strip
    # north of the kayaks. A door shut for good across the strip's west end leaves the doorway the only way in;
    # a door left ajar there during the first session leaves 0.28 m of it, which the lidar sees through and
    # the robot (0.35 m across) cannot pass. It opens when the robot is back on its dock after that session.
    shut = Change("door", 0.0, math.inf, 5.2, 9.275, 0.0, (0.08, 1.45))
    ajar = Change("door", 0.0, math.inf, 6.075, 7.46, 0.0, (0.08, 0.92))
    # The room's navigable truth once the door is open (the rule the benchmarks score on).
    standing = rasterise(world.map, [shut])
    free = ~solid_mask(standing)
    staging = world.staging_pose(1.0)
    nav = navigable(free, standing.resolution, standing.origin[:2], (staging.x, staging.y))
    rows, cols = np.nonzero(nav.mask)
    xs = standing.origin[0] + (cols + 0.5) * standing.resolution
    ys = standing.origin[1] + (rows + 0.5) * standing.resolution
    x0, y0, x1, y1 = EAST_ROOM
    inside = (xs > x0) & (xs < x1) & (ys > y0) & (ys < y1)
    room = np.column_stack([xs[inside], ys[inside]])
    assert len(room) * standing.resolution**2 > 30.0  # the room is most of the lab's east half
    map_from_world = world.dock_pose.inverse()  # map = odom at the start = the docked pose

    def mapped(runner: Runner) -> float:
        """The fraction of the room's navigable cells the robot's map knows free."""
        grid = runner.services[0].slam.grid
        pts = map_from_world.transform_points(room)
        r, c = (np.asarray(v, int) for v in grid.world_to_cell(pts[:, 0], pts[:, 1]))
        ok = (r >= 0) & (r < grid.shape[0]) & (c >= 0) & (c < grid.shape[1])
        return float((grid.data[r[ok], c[ok]] == FREE).sum() / len(room))

    first: dict[str, Any] = {}

    def after_first_session(runner: Runner, robot: SimRobot) -> None:
        if first or not runner.read("/mission/cycles"):
            return
        # Back on the dock: what the first session left, and the door opens.
        (leaf,) = [n for n in runner.mission.root.iterate() if isinstance(n, Explore)]
        assert leaf.explorer is not None and leaf.explorer.report is not None
        ex = leaf.explorer

        def world_xy(x: float, y: float) -> tuple[float, float]:
            wx, wy = world.dock_pose.transform_points(np.array([[x, y]]))[0]
            return float(wx), float(wy)

        first.update(t=runner.now, mapped=mapped(runner), report=leaf.end_report(),
                     narrow=[(*world_xy(s.x, s.y), width)
                             for s, width in zip(ex.report.narrow, ex.narrow_widths, strict=True)],
                     given_up=[(*world_xy(g.x, g.y), g.reason) for g in ex.given_up()],
                     walled=[(*world_xy(s.x, s.y), s.through_wall()) for s in ex.report.walled])
        robot.changes = tuple(dataclasses.replace(ch, end=runner.now) if ch == ajar else ch for ch in robot.changes)

    log, robot, runner = live(world, until=1800.0, seed=1, overrides={"session": "300 s", "rest": "60 s"},
                              stop_after_cycles=3, robot_kwargs={"changes": [shut, ajar]},
                              on_tick=after_first_session)
    try:
        assert first, "the robot never came back to its dock"
        # The first session gave the room up, and said why in its end report: frontiers in it behind a gap
        # narrower than the robot, the gap measured on its map as the door left it (this seed), or places in it
        # the robot stood in front of and could not see into, or could not reach (others). Not "seen through a
        # wall", though the only way in the robot fits is round the outside through unknown space: the map holds
        # the gap the lidar saw the room through, a way in a person can check.
        assert first["mapped"] < 0.3, first
        narrow = [width for x, y, width in first["narrow"] if x0 < x < x1 and y0 < y < y1]
        given_up = [why for x, y, why in first["given_up"] if x0 < x < x1 and y0 < y < y1]
        assert narrow, first["report"]
        assert not [why for x, y, why in first["walled"] if x0 < x < x1 and y0 < y < y1], first["report"]
        # Each measured narrower than the robot, through the free space its map knows there (the doorway's 0.28 m,
        # or less where the lidar saw only part of the gap: a unit test pins the width on a map that holds it all).
        assert all(0.0 < w < 2 * BASE_RADIUS for w in narrow), first["narrow"]
        assert all(why in first["report"] for why in given_up)
        assert "narrower_than_robot (way in " in first["report"], first["report"]
        # Later rounds: the patrol sees the doorway open, the next round's exploration goes in and maps the room.
        assert log.cycles == 3 and robot.charging
        assert "Exploring" in [s for t, s in log.states if t > first["t"]]
        assert mapped(runner) >= 0.9, (mapped(runner), first)
    finally:
        robot.close()
