"""frontier_travel's goals: a frontier whose centroid lies deep in unknown still gets one, once no frontier has
one by explore_lite's rule (the explorer would otherwise be left to decide round it)."""

from __future__ import annotations

import numpy as np
from homing.mapping.explorer import REACH_RADIUS
from homing.mapping.strategies import GoalContext, make_strategy

from homing.map_server import FREE, OCCUPIED, UNKNOWN
from tests.mapping_helpers import travel_distance

RES = 0.05  # [m]


def _ctx(g: np.ndarray, robot: tuple[int, int], current: tuple[int, int] | None) -> GoalContext:
    """The explorer's context: cells within the reach radius of the robot are excluded as goals."""
    dist = travel_distance(g, RES, robot)
    rows, cols = np.mgrid[: g.shape[0], : g.shape[1]]
    excluded = np.hypot(rows - robot[0], cols - robot[1]) <= REACH_RADIUS / RES
    return GoalContext(g, RES, (float(robot[0]), float(robot[1])), 0.0, dist, excluded,
                       np.random.default_rng(0), current_goal=current)


def test_a_patch_of_unknown_seen_from_every_side_is_a_goal():
    """A 10 m × 10 m hall whose middle, a 3 m × 3 m patch, is still unknown, its edge seen from every side: one
    12 m frontier round it, whose centroid lies in the patch 1.5 m from any free cell. explore_lite's rule has no
    goal for it (the centroid is more than CENTROID_TOLERANCE from a reachable cell); frontier_travel goes to the
    frontier's cell nearest its centroid, once no frontier has a goal by explore_lite's rule (before the fix: no
    goal at all, and the explorer's map check was left to decide what to do round the patch)."""
    g = np.full((200, 200), FREE, np.int8)
    g[0, :] = g[-1, :] = g[:, 0] = g[:, -1] = OCCUPIED
    g[70:130, 70:130] = UNKNOWN
    robot = (20, 20)
    ctx = _ctx(g, robot, None)
    assert make_strategy("explore_lite").choose(ctx) is None
    ft = make_strategy("frontier_travel")
    choice = ft.choose(ctx)
    assert choice is not None
    r, c = choice.cell
    middles = np.array([[69, 99.5], [130, 99.5], [99.5, 69], [99.5, 130]])  # the free cells mid-way along each side
    assert g[r, c] == FREE and float(np.min(np.hypot(middles[:, 0] - r, middles[:, 1] - c))) <= 1.0
