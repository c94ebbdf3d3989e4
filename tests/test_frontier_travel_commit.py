"""frontier_travel keeps driving to its goal as the robot comes near it: the goal's frontier drops out of
explore_lite's goals once its centroid lies within the robot's reach disc, and the strategy must not swap it for
the next frontier along (whose centroid drops out the same way when the robot gets there)."""

from __future__ import annotations

import numpy as np
from homing.mapping.explorer import REACH_RADIUS
from homing.mapping.strategies import GoalContext, make_strategy

from homing.map_server import FREE, OCCUPIED, UNKNOWN
from tests.mapping_helpers import travel_distance

RES = 0.05  # [m]


def _room_with_two_openings() -> np.ndarray:
    """A 6 m × 4 m room (rows 20-99, cols 40-159) whose north wall has two 1.4 m openings onto unknown, their
    middles 1.8 m apart (cols 95-122 and 131-158)."""
    g = np.full((140, 200), UNKNOWN, np.int8)
    g[20:100, 40:160] = FREE
    g[19, 39:161] = g[100, 39:161] = OCCUPIED
    g[19:101, 39] = g[19:101, 160] = OCCUPIED
    g[100, 95:123] = UNKNOWN
    g[100, 131:159] = UNKNOWN
    return g


def _ctx(g: np.ndarray, robot: tuple[int, int], current: tuple[int, int] | None) -> GoalContext:
    """The explorer's context: cells within the reach radius of the robot are excluded as goals."""
    dist = travel_distance(g, RES, robot)
    rows, cols = np.mgrid[: g.shape[0], : g.shape[1]]
    excluded = np.hypot(rows - robot[0], cols - robot[1]) <= REACH_RADIUS / RES
    return GoalContext(g, RES, (float(robot[0]), float(robot[1])), 0.0, dist, excluded,
                       np.random.default_rng(0), current_goal=current)


def test_the_goal_is_kept_when_its_frontiers_centroid_falls_within_the_reach_disc():
    """The robot drives to the west opening's goal (96, 100) (set when the opening's centroid stood there); it is
    0.41 m from it, not yet arrived, and the opening's centroid (100, 108.5) is within its reach disc, so
    explore_lite's rule has no goal for that opening. The east opening is 1.8 m away: before the fix the robot
    turned for it, and back again when its centroid dropped out in turn — every replan, never arriving."""
    g = _room_with_two_openings()
    robot, current = (94, 108), (96, 100)
    ctx = _ctx(g, robot, current)
    assert ctx.excluded[100, 108] and not ctx.excluded[current]
    explore_lite = make_strategy("explore_lite").choose(ctx)
    assert explore_lite is not None and explore_lite.cell[1] > 125  # explore_lite itself sees only the east one
    ft = make_strategy("frontier_travel")
    choice = ft.choose(ctx)
    assert choice is not None and choice.cell == current
    assert len(ft.tour) == 2 and ft.tour[1][1] > 125  # the east opening next


def test_without_a_current_goal_the_robot_is_not_sent_back_to_the_dropped_frontier():
    """The same room and robot with no goal (it just arrived somewhere): the opening whose centroid is in the
    reach disc is no goal (nothing to keep), and the tour goes to the east opening."""
    g = _room_with_two_openings()
    ft = make_strategy("frontier_travel")
    choice = ft.choose(_ctx(g, (94, 108), None))
    assert choice is not None and choice.cell[1] > 125 and len(ft.tour) == 1


def test_an_excluded_current_goal_is_not_kept():
    """A current goal within the reach disc (the robot is there: the explorer counts it reached) is not kept."""
    g = _room_with_two_openings()
    ft = make_strategy("frontier_travel")
    choice = ft.choose(_ctx(g, (94, 108), (96, 106)))
    assert choice is not None and choice.cell[1] > 125


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
